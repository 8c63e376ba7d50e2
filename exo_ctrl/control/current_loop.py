r"""The driver's current loop: joint torque commands into drive voltages.

A controller that commands torque (:class:`~exo_ctrl.control.interface.Controller`
with ``command_kind = "torque"``) is served as a servo driver in current
mode serves a motion controller: the torque becomes a current reference,
and a PI on the measured current sets the voltage.  Per drive, at tick k,

.. math::

    I^* = \mathrm{clip}\!\left(\frac{\tau^*}{i_G k_m \eta^{s}}, \pm I_{max}\right),\qquad
    e = I^* - I_m,

    U = R I^* + \frac{i_G}{k_E}\,\omega_m + K_p\,e + K_i \left(z + e\,\Delta t\right),
    \qquad U_{out} = \mathrm{clip}(U, \pm U_{max}),

with ``I_m`` the drive's current sensor (the mean current over the last
tick, :mod:`exo_ctrl.sensing.current_sensor`), ``ω_m`` the encoder's joint
speed, ``η^s`` the gearbox factor at the commanded torque and that speed
(:func:`~exo_ctrl.plant.drive.gear_factor`'s formula), and R, L, k_m, k_E, i_G, η,
U_max and I_max from the device's datasheet.  The integral ``z`` [A·s]
advances by ``e Δt`` unless the voltage is at the supply and the error
pushes it further (conditional integration, the usual anti-windup).  The
feedforward ``R I* + i_G ω / k_E`` is the steady voltage of the current
reference; the PI removes what the datasheet gets wrong.

**Gains.**  Pole-zero cancellation, the usual tuning of a current PI: with
K_p = L ω_c and K_i = R ω_c the PI's zero cancels the winding's pole R/L and
the loop closes as a first-order lag of bandwidth ω_c.  A servo driver
samples its PI current controller at 25 kHz (maxon EPOS4 50/5 Hardware
Reference, rel6852, 2017, §2.1: "Sampling rate PI current controller 25 kHz
(40 µs)") and is tuned to settle within about 1 ms with under 5 % overshoot
(Moog MSD Servo Drive Device Help, CB40859-001, 2018, §7.3); at 25 kHz a
bandwidth of 1/18 of the sampling rate (TI's default for its servo current
loop, SPRACO3) is 1.4 kHz.  :data:`CURRENT_LOOP_BANDWIDTH_HZ` takes 1 kHz.

**At the control rate.**  The simulator holds each voltage over a control
period Δt (1 ms by default, longer than L/R = 0.7 ms), so this loop runs once
per tick, not at the driver's 25 kHz: its PI part is capped at ω_c ≤ 1/(2Δt)
(500 rad/s at 1 kHz; the closed loop with the mean-current reading is then
stable with its slowest mode at 0.59 per tick, while 2π·1 kHz would
diverge), and the feedforward closes most of a step of the reference in
one tick (e^(−Δt R/L) = 25 % of it remains after one tick at 1 kHz, 6 %
after two).  The run's torque response is thus that of a driver whose
current settles within a control period or two, against the cited drivers'
1 ms.
"""

from __future__ import annotations

import math

import numpy as np

from .. import _validate as v
from .._jit import kernel
from ..plant.drive import EFFICIENCY_SMOOTHING_RAD_S, MotorParams

__all__ = ["CURRENT_LOOP_BANDWIDTH_HZ", "CurrentLoop", "current_loop_step"]

#: f_c, the current loop's bandwidth in a real servo driver [Hz] (module docstring).
CURRENT_LOOP_BANDWIDTH_HZ = 1000.0


class CurrentLoop:
    """The four drives' current PI (module docstring), one call per control tick.

    Args:
        motor: the device's drive datasheet.
        dt_s: the control period Δt [s].
        bandwidth_hz: f_c, the wanted bandwidth [Hz]; the PI uses
            ω_c = min(2π f_c, 1/(2Δt)) [rad/s].

    Attributes:
        omega_c_rad_s: ω_c [rad/s].
        kp_V_per_A: K_p = L ω_c [V/A].
        ki_V_per_A_s: K_i = R ω_c [V/(A·s)].
        current_ref_A: I*, the last tick's current references, (4,) [A].
        voltage_V: the last tick's voltages, (4,) [V] (the array :meth:`voltages` returns).

    Raises:
        InvalidParameter: Δt or f_c not a number > 0.

    """

    def __init__(
        self, motor: MotorParams, dt_s: float, bandwidth_hz: float = CURRENT_LOOP_BANDWIDTH_HZ
    ) -> None:
        self.motor = motor
        self.dt_s = v.positive("dt", dt_s, "s")
        f_c = v.positive("current loop bandwidth", bandwidth_hz, "Hz")
        self.omega_c_rad_s = min(2.0 * math.pi * f_c, 0.5 / self.dt_s)
        self.kp_V_per_A = motor.inductance_H * self.omega_c_rad_s
        self.ki_V_per_A_s = motor.resistance_ohm * self.omega_c_rad_s
        self.current_ref_A = np.zeros(4)
        self.voltage_V = np.zeros(4)
        self._integral_A_s = np.zeros(4)
        self._params = np.array(
            [
                motor.resistance_ohm,
                motor.back_emf_V_per_rad_s,
                motor.torque_per_amp_Nm_per_A,
                motor.log_efficiency,
                1.0 / EFFICIENCY_SMOOTHING_RAD_S,
                motor.current_limit_A,
                motor.supply_voltage_V,
                self.kp_V_per_A,
                self.ki_V_per_A_s,
                self.dt_s,
            ]
        )

    def reset(self) -> None:
        """Forget the integral (a new run)."""
        self._integral_A_s[:] = 0.0

    def voltages(
        self, torque_Nm: np.ndarray, omega_rad_s: np.ndarray, current_A: np.ndarray
    ) -> np.ndarray:
        """The drive voltages for joint torque commands [V], (4,): :attr:`voltage_V`.

        One compiled call (:func:`current_loop_step`).

        Args:
            torque_Nm: τ*, the commanded joint torques, (4,) float64 [N·m].
            omega_rad_s: ω_m, the measured joint speeds, (4,) float64 [rad/s].
            current_A: I_m, the measured drive currents, (4,) float64 [A].

        """
        current_loop_step(
            self._params,
            self._integral_A_s,
            self.current_ref_A,
            self.voltage_V,
            torque_Nm,
            omega_rad_s,
            current_A,
        )
        return self.voltage_V


@kernel
def current_loop_step(
    params: np.ndarray,
    integral: np.ndarray,
    ref_out: np.ndarray,
    u_out: np.ndarray,
    torque: np.ndarray,
    omega: np.ndarray,
    current: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """One tick of the four drives' current PI (module docstring), in place.

    ``params``: R [Ω], i_G/k_E [V·s/rad], i_G k_m [N·m/A], ln η, 1/ω_η
    [s/rad], I_max [A], U_max [V], K_p [V/A], K_i [V/(A·s)], Δt [s].
    ``integral``: z per drive [A·s], advanced unless the voltage is at the
    supply and the error pushes it further; ``ref_out``: I* [A];
    ``u_out``: the voltages [V].
    """
    r, kb, kt, lneta, inv_w, i_max, u_max, kp, ki, dt = params
    for j in range(4):
        tau = torque[j]
        s = np.sign(tau) * math.tanh(omega[j] * inv_w)
        ref = min(max(tau / (kt * math.exp(s * lneta)), -i_max), i_max)
        error = ref - current[j]
        step = error * dt
        u = r * ref + kb * omega[j] + kp * error + ki * (integral[j] + step)
        if not (abs(u) > u_max and np.sign(error) == np.sign(u)):
            integral[j] += step
        ref_out[j] = ref
        u_out[j] = min(max(u, -u_max), u_max)
