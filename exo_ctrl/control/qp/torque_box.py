r"""The drive torques reachable at the present speed, and the voltage-torque map of a drive.

In steady state (the drive's electrical time constant, 0.7 ms, neglected) a
drive at joint speed ω with voltage U gives the joint torque

.. math::

    τ = c_2 U - c_1 ω, \qquad c_2 = \frac{i_G k_m}{R} \;[\text{N·m/V}], \quad
    c_1 = \frac{i_G k_m \, i_G / k_E}{R} \;[\text{N·m·s/rad}],

so a voltage command U_cmd is the torque command τ_cmd = c₂ U_cmd − c₁ ω,
and a torque τ the voltage U = (τ + c₁ ω)/c₂.  The torque box is the
intersection of the URDF effort limit |τ| ≤ τ_eff, the driver's current
limit |I| ≤ I_max (τ = i_G k_m I) and the supply |U| ≤ U_max:

.. math::

    τ_{hi} = \min(\mathrm{cap}, c_0 - c_1 ω), \quad
    τ_{lo} = \max(-\mathrm{cap}, -c_0 - c_1 ω), \qquad
    \mathrm{cap} = \min(τ_{eff}, i_G k_m I_{max}), \; c_0 = c_2 U_{max}.

It is empty (τ_lo > τ_hi) above ω = (U_max + R I_max) k_E / i_G.

**At the joint.**  These are the motor's torques referred to the joint, τ_m;
the gearbox passes ``τ = g τ_m`` with ``g = η^{s}``, ``s = sign(τ_m)
tanh(ω/ω_η)`` (η motoring, 1/η braking, :mod:`exo_ctrl.plant.motor`).  ``g``
depends on τ only through its sign, so the map is exact bound by bound: the
command, the box and the QP's variable are joint torques (each bound times
the ``g`` of its own sign, the effort cap applied at the joint), and a joint
torque τ is the voltage ``U = (τ/g(τ) + c₁ ω)/c₂``.

**At a bound the command exceeds.**  The box's caps are the driver's: it holds the
current within I_max, and within what gives the joint's rated effort
(:func:`~exo_ctrl.plant.motor.drive_cap`), whatever voltage it is handed.  The
steady-state voltage of a cap reaches it only through the winding's time constant
L/R (0.7 ms: the step's mean current ``I_∞ + (I_0 − I_∞)(1 − e^{−x})/x``,
:mod:`exo_ctrl.plant.motor`, stays below I_∞ from below), and with the voltage
held the back-EMF damps the joint as its speed changes, so a drive asked for more
than its cap delivers less.  Where the clipped command meets every cuff row, the
drives whose command τ_cmd is beyond the box are checked once more ``held`` at their
caps (their torque held: no back-EMF damping, :mod:`~exo_ctrl.control.qp.prediction`);
if the clip meets every row that way too, each such drive gets the command's own
voltage U_cmd, within the supply ±U_max (``c₀/c₂``), where that drives harder than its
bound's steady-state voltage: the driver then holds the cap, as under the CT+PD
command.  Otherwise (a cuff row near, or proxsuite's answer) the voltages are the
steady-state ones.  With no cuff bound near, the QP's voltage is CT+PD's, at the
drives' limits too.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..._jit import kernel
from ...plant.drive import EFFICIENCY_SMOOTHING_RAD_S, MotorParams

__all__ = ["TORQUE_BOX_FIELDS", "box_constants", "drive_at_caps", "torque_box", "voltage"]

#: Fields of a record holding the box: c₀ [N·m], c₁ [N·m·s/rad], c₂ [N·m/V],
#: the drive's cap i_G k_m I_max and the joint's effort [N·m] per joint, ln η
#: and 1/ω_η [s/rad] of the gearbox; the last τ_cmd, τ_lo and τ_hi at the
#: joint [N·m].
TORQUE_BOX_FIELDS: list[tuple[Any, ...]] = [
    ("c0", np.float64),
    ("lneta", np.float64),
    ("inv_w_eta", np.float64),
    ("effort", np.float64, (4,)),
    ("c1", np.float64, (4,)),
    ("c2", np.float64, (4,)),
    ("cap", np.float64, (4,)),
    ("torque_cmd", np.float64, (4,)),
    ("torque_lo", np.float64, (4,)),
    ("torque_hi", np.float64, (4,)),
]


def box_constants(motor: MotorParams, effort_Nm: np.ndarray) -> dict[str, Any]:
    """c₀, c₁, c₂ and cap of the module docstring for a drive and the URDF effort limits."""
    kt, kb, r = motor.torque_per_amp_Nm_per_A, motor.back_emf_V_per_rad_s, motor.resistance_ohm
    return {
        "c0": kt * motor.supply_voltage_V / r,
        "c1": np.full(4, kt * kb / r),
        "c2": np.full(4, kt / r),
        "cap": np.full(4, kt * motor.current_limit_A),
        "effort": np.asarray(effort_Nm, dtype=float),
        "lneta": motor.log_efficiency,
        "inv_w_eta": 1.0 / EFFICIENCY_SMOOTHING_RAD_S,
    }


@kernel
def gear(lneta: float, inv_w: float, torque: float, omega: float) -> float:  # pragma: no cover
    """The gear factor g = η^s of a torque's sign at speed ω (module docstring)."""
    if lneta == 0.0 or torque == 0.0:
        return 1.0
    th = math.tanh(omega * inv_w)
    return math.exp((th if torque > 0.0 else -th) * lneta)


@kernel
def torque_box(
    s: np.void, u_cmd: np.ndarray, omega: np.ndarray
) -> None:  # pragma: no cover - compiled
    """τ_cmd = c₂ U_cmd − c₁ ω and the box at ω into record ``s`` (module docstring).

    A NaN speed gives a NaN box.  ``u_cmd`` and ``omega``: (4,) (checked by
    the caller).
    """
    c1, c2, cap, c0, effort = s.c1, s.c2, s.cap, s.c0, s.effort
    lneta, inv_w = s.lneta, s.inv_w_eta
    target, lo, hi = s.torque_cmd, s.torque_lo, s.torque_hi
    for j in range(4):
        w = omega[j]
        t = c1[j] * w
        m = c2[j] * u_cmd[j] - t
        target[j] = m * gear(lneta, inv_w, m, w)
        if t != t:
            hi[j] = lo[j] = t
        else:
            m_hi = min(c0 - t, cap[j])
            m_lo = max(-c0 - t, -cap[j])
            hi[j] = min(m_hi * gear(lneta, inv_w, m_hi, w), effort[j])
            lo[j] = max(m_lo * gear(lneta, inv_w, m_lo, w), -effort[j])


@kernel
def voltage(
    s: np.void, torque: np.ndarray, omega: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Write U = (τ/g(τ) + c₁ ω) / c₂ to ``out``: the voltage giving joint ``torque`` at ω [V]."""
    c1, c2, lneta, inv_w = s.c1, s.c2, s.lneta, s.inv_w_eta
    for j in range(4):
        w = omega[j]
        out[j] = (torque[j] / gear(lneta, inv_w, torque[j], w) + c1[j] * w) / c2[j]


@kernel
def drive_at_caps(
    s: np.void, held: np.ndarray, u_cmd: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """The drives ``held`` at their caps (> 0) get clip(U_cmd, ±U_max) in ``out`` [V].

    For a clipped command only, whose held drives sit at the bound their command
    τ_cmd exceeds (module docstring): the command's voltage ``u_cmd`` [V] where it
    drives harder than the bound's steady-state one already in ``out``.
    """
    for j in range(4):
        if held[j] > 0.0:
            u_max = s.c0 / s.c2[j]
            u_drive = min(max(u_cmd[j], -u_max), u_max)
            if s.torque_cmd[j] > s.torque_hi[j]:
                out[j] = max(out[j], u_drive)
            else:
                out[j] = min(out[j], u_drive)
