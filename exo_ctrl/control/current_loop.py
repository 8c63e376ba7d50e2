r"""Joint torque commands into the driver's current references.

A controller that commands torque (:class:`~exo_ctrl.control.interface.Controller`
with ``command_kind = "torque"``) is served as a servo driver in current
mode serves a motion controller: the torque becomes a current reference,
which the driver's PI current loop follows at its own rate, inside the
plant's step (:mod:`exo_ctrl.plant.current_mode`: a first-order lag of
bandwidth :data:`~exo_ctrl.plant.current_mode.CURRENT_LOOP_BANDWIDTH_HZ`,
the cited drivers').  Per drive, at tick k,

.. math::

    I^* = \mathrm{clip}\!\left(\frac{\tau^*}{i_G k_m \eta^{s}}, \pm I_{max}\right),
    \qquad
    U_{ff} = \mathrm{clip}\!\left(R I^* + \frac{i_G}{k_E}\,\omega_m, \pm U_{max}\right),

with ``ω_m`` the encoder's joint speed, ``η^s`` the gearbox factor at the
commanded torque and that speed (:func:`~exo_ctrl.plant.drive.gear_factor`'s
formula), and R, k_m, k_E, i_G, η, U_max and I_max from the device's
datasheet (what the driver is configured with).  ``U_ff``, the steady voltage
of the reference, is the command the tick passes on (the supervisor checks
it and the log's ``voltage_cmd`` shows it); the drives apply the voltage
their current loop sets (the log's ``voltage``), unless the supervisor
replaces the command by its own voltages.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from ..plant.drive import EFFICIENCY_SMOOTHING_RAD_S, MotorParams

__all__ = ["current_reference", "reference_params"]


def reference_params(motor: MotorParams) -> np.ndarray:
    """The datasheet :func:`current_reference` takes, (7,).

    R [Ω], i_G/k_E [V·s/rad], i_G k_m [N·m/A], ln η, 1/ω_η [s/rad], I_max [A], U_max [V].
    """
    return np.array(
        [
            motor.resistance_ohm,
            motor.back_emf_V_per_rad_s,
            motor.torque_per_amp_Nm_per_A,
            motor.log_efficiency,
            1.0 / EFFICIENCY_SMOOTHING_RAD_S,
            motor.current_limit_A,
            motor.supply_voltage_V,
        ]
    )


@kernel
def current_reference(
    params: np.ndarray,
    torque: np.ndarray,
    omega: np.ndarray,
    ref_out: np.ndarray,
    u_out: np.ndarray,
    u_ff_out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """I* and U_ff of the four drives (module docstring), in place.

    ``params``: :func:`reference_params`; ``torque`` τ* [N·m], ``omega`` ω_m
    [rad/s]; ``ref_out`` I* [A]; ``u_out`` and ``u_ff_out`` both U_ff [V]
    (the command and the driver's copy that selects its current mode).
    """
    r, kb, kt, lneta, inv_w, i_max, u_max = params
    for j in range(4):
        tau = torque[j]
        s = np.sign(tau) * math.tanh(omega[j] * inv_w)
        ref = min(max(tau / (kt * math.exp(s * lneta)), -i_max), i_max)
        u = min(max(r * ref + kb * omega[j], -u_max), u_max)
        ref_out[j] = ref
        u_out[j] = u
        u_ff_out[j] = u
