r"""DC motor and gearbox of the exoskeleton drives (paper §V).

Each drive is a DC motor behind a gearbox of ratio ``i_G`` and efficiency
``η``.  With the joint speed ``ω`` [rad/s] (motor speed ``i_G ω``) the
armature obeys

.. math::

    L \frac{dI}{dt} + R I + e = U, \qquad e = \frac{i_G\,\omega}{k_E},

the motor puts ``τ_m = i_G k_m I`` (referred to the joint) into the gearbox
and the joint receives ``τ = η^{s}\,τ_m`` (below).

**Exact step.**  The electrical time constant ``τ_e = L/R`` is about 0.7 ms.
Explicit Euler on the current multiplies the error by ``1 − h R/L`` per step:
−0.43 at h = 1 ms (each step overshoots and the current rings), and it
diverges for ``h > 2 L/R ≈ 1.4 ms``.  So the current is integrated exactly:
with ``U`` and ``ω`` held over a step ``h`` the ODE is linear, and with
``x = h/τ_e``

.. math::

    I_\infty = \frac{U - e}{R}, \qquad
    I(h) = I_\infty + (I_0 - I_\infty)\,e^{-x}, \qquad
    \bar I = I_\infty + (I_0 - I_\infty)\,\varphi, \quad
    \varphi = \frac{1 - e^{-x}}{x},

where ``Ī`` is the mean current over the step; the joint torque applied over
the step is ``τ = η^{s} i_G k_m Ī``.

**Limits.**  The applied voltage is the command clipped to the supply,
``clip(U_cmd, −U_max, U_max)``.  The driver's current loop keeps
``|I| ≤ I_max``; it is modelled by clipping both ``I(h)`` and ``Ī`` to
``±I_max`` (the voltage the driver then actually applies is not modelled;
``applied_voltage_V`` is the clipped command).

**Current mode.**  A drive handed a current reference instead of a voltage
(:attr:`MotorBank.current_command`) follows it through the driver's current
loop, stepped exactly too (:mod:`exo_ctrl.plant.current_mode`).

The parameters, the gear factor ``η^{s}`` and the presets are in
:mod:`exo_ctrl.plant.drive`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._jit import kernel, record
from .._validate import array, positive
from ..exceptions import InvalidParameter
from .current_mode import CURRENT_LOOP_BANDWIDTH_HZ, follow_reference
from .drive import EFFICIENCY_SMOOTHING_RAD_S, OPEN_PHASE, MotorParams, gear_factor
from .energy import book_drives, energy_fields, energy_report

__all__ = [
    "MotorBank",
    "drive_cap",
    "drive_model",
    "hold_drive",
    "motor_fields",
    "motor_step",
    "steady_voltage",
    "step_drives",
]


def _read_only(a: NDArray) -> NDArray:
    view = a.view()
    view.flags.writeable = False
    return view


class MotorBank:
    """``n`` drives sharing one :class:`MotorParams`, stepped exactly.

    All arrays are allocated once, in the constructor; :meth:`step` works in
    place and allocates nothing.  The state and outputs are exposed as
    read-only views of the bank's buffers: they are overwritten by the next
    :meth:`step` or :meth:`reset` (copy them to keep a value).

    Example::

        bank = MotorBank(4)
        tau = bank.step(u_cmd, qdot, 1e-3)  # joint torques over the step [N·m]
        D = bank.damping_Nm_s_per_rad  # the step's damping [N·m·s/rad]

    Args:
        n_drives: number of drives n (>= 1).
        params: motor and gearbox parameters (defaults: paper Table I plus
            the choices documented on :class:`MotorParams`).
        into: a record of :func:`motor_fields` to hold the bank's state (a
            field of its owner's record); default a record of its own.

    Raises:
        InvalidParameter: ``n_drives`` is not an integer >= 1.

    """

    def __init__(
        self, n_drives: int, params: MotorParams | None = None, into: np.ndarray | None = None
    ) -> None:
        if isinstance(n_drives, bool) or not isinstance(n_drives, (int, np.integer)):
            raise InvalidParameter("n_drives", n_drives, "an integer >= 1")
        if n_drives < 1:
            raise InvalidParameter("n_drives", n_drives, "an integer >= 1")
        self.params = params if params is not None else MotorParams()
        p = self.params
        n = int(n_drives)
        self._n = n
        self._shape = (n,)
        self._kt = p.torque_per_amp_Nm_per_A
        self._kb = p.back_emf_V_per_rad_s
        self._tau_e = p.electrical_time_constant_s
        self._d_coef = self._kt * self._kb / p.resistance_ohm  # i_G k_m (i_G/k_E) / R
        #: The drives' parameters and state, one record (:data:`motor_fields`),
        #: the argument of :func:`motor_step`.  The constants ``eps``, ``phi``
        #: and ``d_unsat`` depend on the step length h and are set by :meth:`_set_dt`.
        self.record = record(motor_fields(n)) if into is None else into
        m = self.record[0]
        m["u_max"], m["kb"], m["inv_r"] = p.supply_voltage_V, self._kb, 1.0 / p.resistance_ohm
        m["i_max"], m["kt"] = p.current_limit_A, self._kt
        m["res"], m["ind"] = p.resistance_ohm, p.inductance_H
        m["lneta"], m["inv_w_eta"] = p.log_efficiency, 1.0 / EFFICIENCY_SMOOTHING_RAD_S
        m["gear"] = 1.0
        m["eps"] = m["phi"] = m["d_unsat"] = m["eps_c"] = m["phi_c"] = math.nan
        self._omega_c = 2.0 * math.pi * CURRENT_LOOP_BANDWIDTH_HZ
        m["wcl"] = p.inductance_H * self._omega_c
        m["u_ff"] = math.nan
        r = self.record
        self._current, self._mean, self._u = r["current"][0], r["mean"][0], r["u"][0]
        self._torque, self._sat, self._damping = r["torque"][0], r["saturated"][0], r["damping"][0]
        self._dt = math.nan
        self._ro_current = _read_only(self._current)
        self._ro_mean = _read_only(self._mean)
        self._ro_u = _read_only(self._u)
        self._ro_torque = _read_only(self._torque)
        self._ro_damping = _read_only(self._damping)

    # -- state and outputs ---------------------------------------------------
    @property
    def n_drives(self) -> int:
        """Number of drives n."""
        return self._n

    @property
    def current_A(self) -> NDArray[np.float64]:
        """Armature current at the end of the last step, shape (n,) [A] (read-only view)."""
        return self._ro_current

    @property
    def mean_current_A(self) -> NDArray[np.float64]:
        """Mean armature current ``Ī`` over the last step, shape (n,) [A] (read-only view)."""
        return self._ro_mean

    @property
    def applied_voltage_V(self) -> NDArray[np.float64]:
        """Voltage applied over the last step, shape (n,) [V] (read-only view).

        ``clip(U_cmd, ±U_max)``; in current mode the driver's mean voltage.
        """
        return self._ro_u

    @property
    def torque_Nm(self) -> NDArray[np.float64]:
        """Mean joint torque ``i_G k_m Ī`` over the last step, shape (n,) [N·m]."""
        return self._ro_torque

    @property
    def saturated(self) -> NDArray[np.bool_]:
        """Drives whose mean current over the last step was held at ``±I_max``, shape (n,)."""
        return _read_only(self._sat > 0.0)

    # -- stepping --------------------------------------------------------------
    def set_step(self, dt_s: float) -> None:
        """Prepare the constants of a step length h [s] (cached; done by :meth:`step` too).

        A new h (NaN never equals the cache) is validated in :meth:`_set_dt`; a
        repeated valid h costs one float comparison.
        """
        if dt_s != self._dt:
            self._set_dt(dt_s)

    def _set_dt(self, dt_s: float) -> None:
        dt = positive("dt_s", dt_s, "s")
        x = dt / self._tau_e
        em1 = math.expm1(-x)  # e^{-x} - 1, accurate for small x
        m = self.record[0]
        m["h"] = dt
        m["eps"] = em1 + 1.0  # e^{-x}
        m["phi"] = -em1 / x  # φ
        m["d_unsat"] = self._d_coef * (x + em1) / x  # D unsaturated; (x + em1)/x = 1 − φ
        y = dt * self._omega_c
        em1 = math.expm1(-y)
        m["eps_c"] = em1 + 1.0  # e^{-ω_c h}
        m["phi_c"] = -em1 / y  # φ_c
        self._dt = dt

    def step(self, voltage_cmd_V: ArrayLike, omega_rad_s: ArrayLike, dt_s: float) -> NDArray:
        """Advance every drive by one step with voltage and joint speed held.

        Updates :attr:`current_A` in place by the exact solution (module
        docstring), clips voltage and current to their limits, and returns the
        mean joint torque over the step, ``τ = η^{s} i_G k_m Ī``.

        Nothing is allocated; inputs are not checked for shape or finiteness
        (numpy raises on a shape mismatch; a NaN command propagates to the
        torque, for the plant's divergence check to catch).

        Args:
            voltage_cmd_V: commanded voltages, shape (n,) or scalar [V].
            omega_rad_s: joint speeds, shape (n,) or scalar [rad/s].
            dt_s: step length h [s], finite and > 0.

        Returns:
            Mean joint torques over the step, shape (n,) [N·m]: a read-only
            view of the bank's buffer, overwritten by the next step.

        Raises:
            InvalidParameter: ``dt_s`` is not a finite number > 0.

        """
        self.set_step(dt_s)
        voltage_cmd_V = array("voltage_cmd_V", voltage_cmd_V, self._shape)
        omega_rad_s = array("omega_rad_s", omega_rad_s, self._shape)
        motor_step(self.record, voltage_cmd_V, omega_rad_s)
        return self._ro_torque

    @property
    def current_command(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The current mode's inputs ``(i_ref, u_ff)``, (n,) each, writable views [A], [V].

        Write the current references I* into the first and, into the second,
        the voltage handed to :meth:`step` with them: a drive whose voltage
        command equals its ``u_ff`` follows I* (:mod:`exo_ctrl.plant.current_mode`);
        NaN (after :meth:`reset`) never does.
        """
        r = self.record
        return r["i_ref"][0], r["u_ff"][0]

    @property
    def damping_Nm_s_per_rad(self) -> NDArray[np.float64]:
        r"""The last step's damping ``D = −∂τ/∂ω`` of the mean joint torque [N·m·s/rad].

        With ``g = η^{s}`` the gear factor and ``θ = tanh(ω/ω_η)``,

        .. math::

            D = g\, i_G k_m \,(1 - \varphi)\, \frac{i_G / k_E}{R}
              + |τ|\,|\ln η|\,\frac{1 - θ^2}{ω_η},

        the back-EMF part zero for a drive whose mean current was held at
        the limit (:attr:`saturated`).  For implicit integration: the torque
        over the step is ``τ(ω) ≈ τ(ω_0) − D (ω − ω_0)``.  A read-only view,
        overwritten by the next :meth:`step`.
        """
        return self._ro_damping

    def reset(self, current_A: ArrayLike = 0.0) -> None:
        """Set the armature currents and clear the last step's outputs.

        Args:
            current_A: new currents, scalar or shape (n,) [A], finite and
                within ``±I_max``.

        Raises:
            InvalidParameter: a current is not finite or beyond the limit.

        """
        i = np.broadcast_to(np.asarray(current_A, dtype=float), (self._n,))
        i_max = self.params.current_limit_A
        if not np.all(np.isfinite(i)) or np.any(np.abs(i) > i_max):
            raise InvalidParameter("current_A", current_A, f"finite and within ±{i_max:g} A")
        self._current[:] = i
        self._mean[:] = i
        r = self.record
        r["i_start"][0] = i
        for name in ("e_electrical", "e_regenerated", "e_copper", "e_gear", "e_mechanical"):
            r[name][0] = 0.0
        self._u.fill(0.0)
        r["u_ff"][0] = math.nan
        self._sat.fill(0.0)
        self._damping.fill(0.0)  # set by the next step
        np.multiply(self._mean, self._kt, out=self._torque)

    def energy(self, names: tuple[str, ...]) -> dict:
        """The drives' energy books since the last reset, a drive per name.

        See :func:`exo_ctrl.plant.energy.energy_report`.
        """
        return energy_report(self.record, names)

    # -- steady state and feedforward -----------------------------------------
    def steady_state_current(self, voltage_V: ArrayLike, omega_rad_s: ArrayLike) -> NDArray:
        """Return the current the drives settle to, holding a voltage and joint speed [A].

        ``clip((clip(U, ±U_max) − i_G ω/k_E)/R, ±I_max)``: the limit of
        :meth:`step` with both held.  Allocates its result (not for the tick).

        Args:
            voltage_V: commanded voltages, broadcastable [V].
            omega_rad_s: joint speeds, broadcastable [rad/s].

        Returns:
            Steady-state currents, broadcast shape [A].

        """
        p = self.params
        u = np.clip(np.asarray(voltage_V, dtype=float), -p.supply_voltage_V, p.supply_voltage_V)
        i = (u - self._kb * np.asarray(omega_rad_s, dtype=float)) / p.resistance_ohm
        return np.clip(i, -p.current_limit_A, p.current_limit_A)

    def voltage_for(self, torque_Nm: ArrayLike, omega_rad_s: ArrayLike) -> NDArray[np.float64]:
        """Return the steady-state voltage giving a joint torque at a joint speed [V].

        ``U = R τ_m/(i_G k_m) + i_G ω/k_E`` with the motor torque
        ``τ_m = τ / η^{s}`` the gearbox needs for ``τ`` at the joint
        (``s = sign(τ) tanh(ω/ω_η)``, module docstring): inductance is
        neglected (the current settles within a few ``τ_e`` ≈ 0.7 ms).  Not
        clipped: a torque beyond what the current limit gives or a voltage
        beyond the supply is limited when applied by :meth:`step`.  Allocates
        its result (for tables made before a run, not for the tick).

        Args:
            torque_Nm: wanted joint torques, broadcastable [N·m].
            omega_rad_s: joint speeds, broadcastable [rad/s].

        Returns:
            Voltages [V], the broadcast shape.

        """
        p = self.params
        tau = np.asarray(torque_Nm, dtype=float)
        omega = np.asarray(omega_rad_s, dtype=float)
        tau_m = tau / gear_factor(p.gear_efficiency, tau, omega)
        return p.resistance_ohm / self._kt * tau_m + self._kb * omega


def motor_fields(n: int) -> list[tuple]:
    """Fields of a bank of ``n`` drives' record.

    Parameters: ``u_max`` U_max [V], ``kb`` i_G/k_E [V·s/rad], ``inv_r`` 1/R
    [1/Ω], ``i_max`` I_max [A], ``kt`` i_G k_m [N·m/A], ``lneta`` ln η,
    ``inv_w_eta`` 1/ω_η [s/rad], ``wcl`` L ω_c [V/A], and of the step
    length h: ``eps`` e^{-h/τ_e}, ``phi`` φ, ``d_unsat`` the unsaturated
    back-EMF damping D [N·m·s/rad], ``eps_c`` e^{-ω_c h}, ``phi_c`` φ_c
    (:mod:`exo_ctrl.plant.current_mode`).  Current mode per drive: ``i_ref``
    I* [A], ``u_ff`` the voltage command that selects it [V].  State per drive: ``current`` I(h) [A]
    at the end of the last step, ``mean`` Ī [A], ``u`` the applied voltage
    [V], ``torque`` η^s i_G k_m Ī at the joint [N·m], ``gear`` the gear
    factor η^s, ``saturated`` (1.0/0.0), ``damping`` D = −∂τ/∂ω of the
    step's mean torque [N·m·s/rad] (back-EMF part zero where Ī is at the limit),
    ``fault`` (:data:`~exo_ctrl.plant.drive.DRIVE_FAULTS`: 0.0 healthy, set only by fault
    injection).
    And the energy books (:func:`exo_ctrl.plant.energy.energy_fields`).
    """
    scalars = (
        "u_max", "kb", "inv_r", "i_max", "kt", "lneta", "inv_w_eta", "eps", "phi", "d_unsat",
        "wcl", "eps_c", "phi_c",
    )  # fmt: skip
    rows = ("current", "mean", "u", "torque", "gear", "saturated", "damping", "fault", "i_ref")
    rows += ("u_ff",)
    return (
        [(name, np.float64) for name in scalars]
        + [(name, np.float64, (n,)) for name in rows]
        + energy_fields(n)
    )


@kernel
def motor_step(motors: NDArray, voltage_cmd_V: NDArray, omega_rad_s: NDArray) -> None:
    """One exact step of every drive, in place (the module docstring's maths).

    ``motors``: the bank's record array (:func:`motor_fields`).  The step is
    booked (:func:`~exo_ctrl.plant.energy.book_drives`).
    """
    step_drives(motors[0], voltage_cmd_V, omega_rad_s)
    book_drives(motors[0], omega_rad_s)


@kernel
def step_drives(m: Any, voltage_cmd_V: NDArray, omega_rad_s: NDArray) -> None:
    """:func:`motor_step` on the record ``m`` itself (also a field of another record).

    The step is not booked: its owner books it once it is final.
    """
    u_max, kb, inv_r, i_max, kt = m.u_max, m.kb, m.inv_r, m.i_max, m.kt
    lneta, inv_w = m.lneta, m.inv_w_eta
    eps, phi, d_unsat = m.eps, m.phi, m.d_unsat
    current, mean_out, u_out, torque, saturated, damping = (
        m.current,
        m.mean,
        m.u,
        m.torque,
        m.saturated,
        m.damping,
    )
    for j in range(current.shape[0]):
        u = min(max(voltage_cmd_V[j], -u_max), u_max)
        fault = m.fault[j]
        if fault != 0.0:
            if fault == OPEN_PHASE:  # no current flows: no torque, no back-EMF damping
                current[j] = mean_out[j] = torque[j] = damping[j] = u_out[j] = 0.0
                m.i_prev[j] = m.i_asym[j] = m.held[j] = saturated[j] = 0.0
                m.gear[j] = 1.0
                continue
            u = 0.0  # SHORTED: the winding is shorted, U = 0 whatever the command
        lag = False
        if fault == 0.0 and voltage_cmd_V[j] == m.u_ff[j]:  # current mode
            lag, u_lag = follow_reference(m, j, omega_rad_s[j])
            u = min(max(u_lag, -u_max), u_max)
        if lag:  # the driver followed I*: no back-EMF damping
            mean = mean_out[j]
            emf_damped = False
        else:
            i_inf = (u - kb * omega_rad_s[j]) * inv_r
            i0 = current[j]
            d0 = i0 - i_inf
            mean = d0 * phi + i_inf
            sat = abs(mean) > i_max
            end = d0 * eps + i_inf
            current[j] = min(max(end, -i_max), i_max)
            mean = min(max(mean, -i_max), i_max)
            m.i_prev[j] = i0
            m.i_asym[j] = i_inf
            m.held[j] = 1.0 if sat or abs(end) > i_max else 0.0
            mean_out[j] = mean
            u_out[j] = u
            saturated[j] = 1.0 if sat else 0.0
            emf_damped = not sat
        if lneta == 0.0:
            torque[j] = mean * kt
            damping[j] = d_unsat if emf_damped else 0.0
            continue
        # η^s, s = sign(τ_m) tanh(ω/ω_η); D = −∂τ/∂ω = η^s D_emf + |τ| |ln η| sech²(ω/ω_η)/ω_η.
        th = math.tanh(omega_rad_s[j] * inv_w)
        s = th if mean > 0.0 else (-th if mean < 0.0 else 0.0)
        g = math.exp(s * lneta)
        m.gear[j] = g
        tau = mean * kt * g
        torque[j] = tau
        emf = d_unsat * g if emf_damped else 0.0
        damping[j] = emf - abs(tau) * lneta * (1.0 - th * th) * inv_w


@kernel
def drive_cap(m: Any, effort: float, j: int) -> tuple[float, float]:
    """Drive j's torque cap at the joint and the current that holds it [N·m], [A].

    The smaller of the drive's own, η^s i_G k_m I_max, and the joint's rated
    ``effort``; the current is I_max, or what gives the effort through the
    gear factor where the rating binds first (braking, or a big drive).
    """
    cap = m.kt * m.i_max * m.gear[j]
    if cap > effort:
        return effort, effort / (m.kt * m.gear[j])
    return cap, m.i_max


@kernel
def hold_drive(m: Any, j: int, torque: float, current: float) -> None:
    """Record drive j held at its cap: ``torque`` [N·m] from ``current`` [A], signed; no damping."""
    m.mean[j] = current
    m.current[j] = current
    m.torque[j] = torque
    m.saturated[j] = 1.0
    m.damping[j] = 0.0
    m.held[j] = 1.0


def drive_model(motor: MotorParams) -> np.ndarray:
    """The drive model :func:`steady_voltage` takes, (4,).

    (R / (i_G k_m) [Ω·A/(N·m)], i_G / k_E [V·s/rad], ln η, ω_η [rad/s]).
    """
    return np.array(
        [
            motor.resistance_ohm / motor.torque_per_amp_Nm_per_A,
            motor.back_emf_V_per_rad_s,
            math.log(motor.gear_efficiency),
            EFFICIENCY_SMOOTHING_RAD_S,
        ]
    )


@kernel
def steady_voltage(torque: float, omega: float, drive: np.ndarray) -> float:
    """The steady-state voltage for a joint torque at a joint speed [V], compiled.

    U = R τ / (i_G k_m η^s) + (i_G / k_E) ω, s = sign(τ) tanh(ω/ω_η): the
    formula of :meth:`MotorBank.voltage_for` for one joint, ``drive`` from
    :func:`drive_model`.
    """
    s = np.sign(torque) * np.tanh(omega / drive[3])
    return drive[0] * torque / np.exp(s * drive[2]) + drive[1] * omega
