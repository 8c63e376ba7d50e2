"""Energy bookkeeping of the drives: where every joule of the supply goes, step by step.

Over a step h with the voltage U and the joint speed ω held, the armature
current is I(t) = I∞ + d₀ e^{−t/τ_e} (d₀ = I₀ − I∞, :mod:`exo_ctrl.plant.motor`).
Multiplying the winding's equation L İ + R I + k_b ω = U by I and
integrating over the step gives the drive's energy balance, exactly:

    U Ī h  =  R ∫I² dt  +  k_b ω Ī h  +  ½ L (I₁² − I₀²),

electrical energy in = copper loss + work converted by the back-EMF +
change of magnetic energy, with Ī h = ∫I dt and, in closed form,

    ∫I² dt = h (I∞² + 2 I∞ d₀ φ + d₀² φ (1 + ε) / 2),   ε = e^{−h/τ_e}, φ = (1 − ε) / (h/τ_e).

The motor's work is k_t Ī ω h (k_t = i_G k_m); the gearbox passes g = η^s
of it to the joint (:mod:`exo_ctrl.plant.drive`: η motoring, 1/η braking),
so the mechanical work at the joint is g k_t Ī ω h and the gear loss
(1 − g) k_t Ī ω h, never negative.  The back-EMF's and the motor's
conversions agree, k_b ω Ī = k_t Ī ω, only for an energy-consistent motor,
whose back-EMF constant [V·s/rad] equals its torque constant [N·m/A]: for
any other pair the run's books do not balance, and the residual

    electrical − copper − gear − mechanical − Δ magnetic  =  (k_b − k_t) ∫ω I dt

measures the energy the motor model creates (or destroys).  A step whose
current meets the driver's limit is booked with the current held at ±I_max
(the driver lowers the voltage to hold it): its copper loss is R I_max² h
and the driver supplies what the winding takes, R I_max² h + k_b ω Ī h +
Δ(½ L I²).  A step in the driver's current mode (:mod:`exo_ctrl.plant.current_mode`:
I(t) = I* + d₀ e^{−ω_c t}, d₀ = I₀ − I*, the voltage shaped within the step)
is booked the same way, the electrical energy being ∫U I dt, its copper
loss R ∫I² dt by the formula above with I* for I∞ and ε_c = e^{−ω_c h},
φ_c = (1 − ε_c)/(ω_c h) for ε, φ.  Energy flowing back to the supply (U Ī < 0, braking) is also
counted as ``regenerated``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._jit import kernel
from .current_mode import CURRENT_MODE

__all__ = ["book_drives", "book_step", "energy_fields", "energy_report"]


def energy_fields(n: int) -> list[tuple[Any, ...]]:
    """The bookkeeping's fields of a bank of ``n`` drives' record (module docstring).

    Parameters: ``h`` the step [s], ``res`` R [Ω], ``ind`` L [H].  Per drive
    [J], since the last reset: ``e_electrical`` (net, supply to drive),
    ``e_regenerated`` (returned to the supply), ``e_copper``, ``e_gear``,
    ``e_mechanical`` (at the joint), and ``i_start`` the current at the
    reset [A]; the last step's, until it is booked: ``i_prev`` the current at
    its start [A], ``i_asym`` its asymptote I∞ [A], ``held`` (1.0: the driver
    held the current at its limit; 2.0: it followed a current reference).
    """
    rows = (
        "e_electrical", "e_regenerated", "e_copper", "e_gear", "e_mechanical", "i_start",
        "i_prev", "i_asym", "held",
    )  # fmt: skip
    return [("h", np.float64), ("res", np.float64), ("ind", np.float64)] + [
        (name, np.float64, (n,)) for name in rows
    ]


@kernel
def book_step(
    m: Any,
    j: int,
    u: float,
    omega: float,
    i0: float,
    i1: float,
    i_inf: float,
    mean: float,
    held: float,
) -> None:
    """Book drive j's step (module docstring) into the drives' record ``m``.

    ``u`` the applied voltage [V], ``omega`` the held joint speed [rad/s],
    ``i0`` and ``i1`` the current at the step's start and end [A], ``i_inf``
    its asymptote [A] (I* in current mode), ``mean`` Ī [A]; ``held``: 1.0 the
    driver held the current at its limit during the step,
    :data:`~exo_ctrl.plant.current_mode.CURRENT_MODE` it followed I*, 0.0 a
    voltage step.
    """
    h = m.h
    if held == 1.0:
        copper = m.res * mean * mean * h
    else:
        d0 = i0 - i_inf
        phi, eps = (m.phi_c, m.eps_c) if held == CURRENT_MODE else (m.phi, m.eps)
        square = h * (i_inf * i_inf + 2.0 * i_inf * d0 * phi + d0 * d0 * phi * (1.0 + eps) * 0.5)
        copper = m.res * square
    if held == 0.0:
        electrical = u * mean * h
    else:  # the winding's take: copper, back-EMF and magnetic energy
        electrical = copper + m.kb * omega * mean * h + 0.5 * m.ind * (i1 * i1 - i0 * i0)
    m.e_electrical[j] += electrical
    m.e_copper[j] += copper
    motor = m.kt * mean * omega * h
    g = m.gear[j]
    m.e_mechanical[j] += g * motor
    m.e_gear[j] += motor - g * motor
    if electrical < 0.0:
        m.e_regenerated[j] -= electrical


@kernel
def book_drives(m: Any, omega_rad_s: np.ndarray) -> None:
    """Book the last step of every drive of the record ``m`` (held speeds ``omega_rad_s``).

    Called once a step is final: after the plant has held a drive at its
    current limit, if it had to (:mod:`exo_ctrl.plant.plant`).
    """
    for j in range(m.current.shape[0]):
        book_step(
            m, j, m.u[j], omega_rad_s[j], m.i_prev[j], m.current[j], m.i_asym[j], m.mean[j],
            m.held[j],
        )  # fmt: skip


def energy_report(m: np.ndarray, names: tuple[str, ...]) -> dict[str, Any]:
    """The books of a run: per drive and the balance's residual (module docstring).

    Args:
        m: the drives' record (one element).
        names: a name per drive (the joints).

    Returns:
        ``energy_J``: per drive ``electrical`` (net), ``copper_loss``,
        ``gear_loss``, ``mechanical``, ``regenerated``, ``magnetic`` (its
        change) and ``residual`` [J]; ``energy_balance_residual_rel``: the
        sum of the drives' |residual| over the electrical energy drawn from
        the supply (net + regenerated), 0 when none was drawn.

    """
    r = m[0]
    current = r["current"]
    magnetic = 0.5 * r["ind"] * (current * current - r["i_start"] * r["i_start"])
    out: dict[str, dict[str, float]] = {}
    total_residual = drawn = 0.0
    for j, name in enumerate(names):
        electrical, copper = float(r["e_electrical"][j]), float(r["e_copper"][j])
        mechanical, regenerated = float(r["e_mechanical"][j]), float(r["e_regenerated"][j])
        gear = float(r["e_gear"][j])
        residual = electrical - copper - gear - mechanical - float(magnetic[j])
        out[name] = {
            "electrical": electrical,
            "copper_loss": copper,
            "gear_loss": gear,
            "mechanical": mechanical,
            "regenerated": regenerated,
            "magnetic": float(magnetic[j]),
            "residual": residual,
        }
        total_residual += abs(residual)
        drawn += electrical + regenerated
    return {
        "energy_J": out,
        "energy_balance_residual_rel": total_residual / drawn if drawn > 0.0 else 0.0,
    }
