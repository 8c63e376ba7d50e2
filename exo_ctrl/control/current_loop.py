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
(:func:`~exo_ctrl.plant.drive.gear_factor`), and R, L, k_m, k_E, i_G, η,
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
diverge), and the feedforward brings the current to its reference within
about one tick.  The run's torque response is thus that of a driver whose
current settles within a control period, as the cited ones do.
"""

from __future__ import annotations

import math

import numpy as np

from .. import _validate as v
from ..plant.drive import MotorParams, gear_factor

__all__ = ["CURRENT_LOOP_BANDWIDTH_HZ", "CurrentLoop"]

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

    def reset(self) -> None:
        """Forget the integral (a new run)."""
        self._integral_A_s[:] = 0.0

    def voltages(
        self, torque_Nm: np.ndarray, omega_rad_s: np.ndarray, current_A: np.ndarray
    ) -> np.ndarray:
        """The drive voltages for joint torque commands [V], (4,): :attr:`voltage_V`.

        Args:
            torque_Nm: τ*, the commanded joint torques, (4,) [N·m].
            omega_rad_s: ω_m, the measured joint speeds, (4,) [rad/s].
            current_A: I_m, the measured drive currents, (4,) [A].

        """
        m = self.motor
        gear = gear_factor(m.gear_efficiency, torque_Nm, omega_rad_s)
        limit = m.current_limit_A
        ref = np.clip(torque_Nm / (m.torque_per_amp_Nm_per_A * gear), -limit, limit)
        self.current_ref_A[:] = ref
        error = ref - current_A
        step = error * self.dt_s
        u = (
            m.resistance_ohm * ref
            + m.back_emf_V_per_rad_s * omega_rad_s
            + self.kp_V_per_A * error
            + self.ki_V_per_A_s * (self._integral_A_s + step)
        )
        supply = m.supply_voltage_V
        winding_up = (np.abs(u) > supply) & (np.sign(error) == np.sign(u))
        self._integral_A_s += np.where(winding_up, 0.0, step)
        np.clip(u, -supply, supply, out=self.voltage_V)
        return self.voltage_V
