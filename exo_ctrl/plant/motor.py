r"""DC motor and gearbox of the exoskeleton drives (paper §V).

Each drive is a DC motor behind a gearbox of ratio ``i_G``.  With the joint
speed ``ω`` [rad/s] (motor speed ``i_G ω``) the armature obeys

.. math::

    L \frac{dI}{dt} + R I + e = U, \qquad e = \frac{i_G\,\omega}{k_E},

and the drive puts the joint torque ``τ = i_G k_m I`` on its joint.  The gear
efficiency is taken as 1 and gearbox friction is left to the joint model
(URDF ``<dynamics>``).

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
the step is ``τ = i_G k_m Ī``.

**Limits.**  The applied voltage is the command clipped to the supply,
``clip(U_cmd, −U_max, U_max)``.  The driver's current loop keeps
``|I| ≤ I_max``; it is modelled by clipping both ``I(h)`` and ``Ī`` to
``±I_max`` (the voltage the driver then actually applies is not modelled;
``applied_voltage_V`` is the clipped command).

**Units of the paper's constants.**  Table I gives ``k_m = 0.35 N·m/A`` and
``k_E = 25.9 rad/(V·s)``.  For an ideal DC motor ``k_m = 1/k_E`` in SI, but
here ``1/k_E = 0.0386 V·s/rad``, nine times smaller than ``k_m``: with the
values as printed the model delivers more mechanical power
(``i_G k_m I ω``) than the back-EMF absorbs (``e I``).  (Read as
25.9 rpm/V, ``1/k_E`` would be 0.369 V·s/rad, within 5 % of ``k_m``.)  The
defaults keep the paper's numbers as printed; both are configurable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._jit import kernel, record
from .._validate import array, positive
from ..exceptions import InvalidParameter
from .energy import book_drives, energy_fields, energy_report

__all__ = ["MotorBank", "MotorParams", "motor_step"]


@dataclass(frozen=True)
class MotorParams:
    """Parameters of one drive (motor + gearbox), shared by a :class:`MotorBank`.

    The first four are the paper's Table I.  The others are not in the paper
    and were chosen here (override them for a real device):

    - ``gear_ratio = 50``: gives a peak joint torque ``i_G k_m I_max`` of
      175 N·m, margin over the ~100 N·m the paper reports for a 0.35 m step,
      while the back-EMF at the joint (1.93 V per rad/s) leaves the drive
      about 12 rad/s of no-load joint speed at 24 V.
    - ``supply_voltage_V = 24``: a common battery/bus voltage for
      exoskeleton drives.
    - ``current_limit_A = 10``: the driver's current limit (175 N·m peak).
    - ``rotor_inertia_kgm2 = 6e-5``: typical of a 150–250 W DC motor;
      reflected to the joint it is ``i_G² J_rotor = 0.15 kg·m²``, which the
      caller adds to the exoskeleton model's joint armature.

    Attributes:
        inductance_H: armature inductance L [H].
        resistance_ohm: armature resistance R [Ω].
        torque_constant_Nm_per_A: motor torque coefficient k_m [N·m/A].
        speed_constant_rad_per_Vs: speed coefficient k_E [rad/(V·s)]; the
            back-EMF is ``i_G ω / k_E``.
        gear_ratio: total gear ratio i_G (motor speed / joint speed) [-].
        supply_voltage_V: supply voltage limit U_max [V].
        current_limit_A: driver current limit I_max [A].
        rotor_inertia_kgm2: rotor inertia J_rotor, at the motor shaft [kg·m²].

    Raises:
        InvalidParameter: a field is not a finite number > 0 (text and
            bools are refused, not converted).

    """

    inductance_H: float = field(default=0.072e-3, metadata={"unit": "H"})
    resistance_ohm: float = field(default=0.103, metadata={"unit": "Ω"})
    torque_constant_Nm_per_A: float = field(default=0.35, metadata={"unit": "N·m/A"})
    speed_constant_rad_per_Vs: float = field(default=25.9, metadata={"unit": "rad/(V·s)"})
    gear_ratio: float = field(default=50.0, metadata={"unit": ""})
    supply_voltage_V: float = field(default=24.0, metadata={"unit": "V"})
    current_limit_A: float = field(default=10.0, metadata={"unit": "A"})
    rotor_inertia_kgm2: float = field(default=6e-5, metadata={"unit": "kg·m²"})

    def __post_init__(self) -> None:
        for f in fields(self):
            unit = f.metadata["unit"]
            value = positive(f.name, getattr(self, f.name), unit)
            object.__setattr__(self, f.name, value)

    @property
    def electrical_time_constant_s(self) -> float:
        """Electrical time constant ``τ_e = L/R`` [s]."""
        return self.inductance_H / self.resistance_ohm

    @property
    def torque_per_amp_Nm_per_A(self) -> float:
        """Joint torque per armature ampere ``i_G k_m`` [N·m/A]."""
        return self.gear_ratio * self.torque_constant_Nm_per_A

    @property
    def back_emf_V_per_rad_s(self) -> float:
        """Back-EMF per unit joint speed ``i_G / k_E`` [V·s/rad]."""
        return self.gear_ratio / self.speed_constant_rad_per_Vs

    @property
    def reflected_inertia_kgm2(self) -> float:
        """Rotor inertia seen at the joint ``i_G² J_rotor`` [kg·m²]."""
        return self.gear_ratio**2 * self.rotor_inertia_kgm2

    @property
    def peak_torque_Nm(self) -> float:
        """Joint torque at the current limit ``i_G k_m I_max`` [N·m]."""
        return self.torque_per_amp_Nm_per_A * self.current_limit_A


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
        D = bank.damping_Nm_s_per_rad(1e-3)  # back-EMF damping [N·m·s/rad]

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
        m["eps"] = m["phi"] = m["d_unsat"] = math.nan
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
        """Voltage applied over the last step, ``clip(U_cmd, ±U_max)``, shape (n,) [V]."""
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
        self._dt = dt

    def step(self, voltage_cmd_V: ArrayLike, omega_rad_s: ArrayLike, dt_s: float) -> NDArray:
        """Advance every drive by one step with voltage and joint speed held.

        Updates :attr:`current_A` in place by the exact solution (module
        docstring), clips voltage and current to their limits, and returns the
        mean joint torque over the step, ``τ = i_G k_m Ī``.

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

    def damping_Nm_s_per_rad(self, dt_s: float) -> NDArray[np.float64]:
        r"""Return the back-EMF damping ``D = −∂τ/∂ω`` of the step's mean torque [N·m·s/rad].

        For a drive whose mean current is not at the limit

        .. math::

            D = i_G k_m \,(1 - \varphi)\, \frac{i_G / k_E}{R},

        and ``D = 0`` for a drive that is (the saturation state is the last
        step's, :attr:`saturated`).  For implicit integration: the torque over
        the next step is ``τ(ω) ≈ τ(ω_0) − D (ω − ω_0)``.

        Args:
            dt_s: step length h [s], finite and > 0.

        Returns:
            D per drive, shape (n,) [N·m·s/rad]: a read-only view of the
            bank's buffer, overwritten by the next call.

        Raises:
            InvalidParameter: ``dt_s`` is not a finite number > 0.

        """
        self.set_step(dt_s)
        np.multiply(self._sat == 0.0, self.record[0]["d_unsat"], out=self._damping)
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
        for name in ("e_electrical", "e_regenerated", "e_copper", "e_mechanical"):
            r[name][0] = 0.0
        self._u.fill(0.0)
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

    def voltage_for(
        self,
        torque_Nm: ArrayLike,
        omega_rad_s: ArrayLike,
        out: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """Return the steady-state voltage giving a joint torque at a joint speed [V].

        ``U = R τ/(i_G k_m) + i_G ω/k_E``: inductance is neglected (the
        current settles within a few ``τ_e`` ≈ 0.7 ms).  Not clipped: a
        torque beyond :attr:`MotorParams.peak_torque_Nm` or a voltage beyond
        the supply is limited when applied by :meth:`step`.

        Args:
            torque_Nm: wanted joint torques, broadcastable [N·m].
            omega_rad_s: joint speeds, broadcastable [rad/s].
            out: optional array to write the result into (no allocation).

        Returns:
            Voltages [V] (``out`` when given).

        """
        p = self.params
        if out is None:
            return p.resistance_ohm / self._kt * np.asarray(torque_Nm, dtype=float) + (
                self._kb * np.asarray(omega_rad_s, dtype=float)
            )
        # U = (i_G/k_E) (ω + R τ / (i_G k_m i_G/k_E)), in place.
        np.multiply(torque_Nm, p.resistance_ohm / (self._kt * self._kb), out=out)
        np.add(out, omega_rad_s, out=out)
        np.multiply(out, self._kb, out=out)
        return out


def motor_fields(n: int) -> list[tuple]:
    """Fields of a bank of ``n`` drives' record.

    Parameters: ``u_max`` U_max [V], ``kb`` i_G/k_E [V·s/rad], ``inv_r`` 1/R
    [1/Ω], ``i_max`` I_max [A], ``kt`` i_G k_m [N·m/A], and of the step
    length h: ``eps`` e^{-h/τ_e}, ``phi`` φ, ``d_unsat`` the unsaturated
    back-EMF damping D [N·m·s/rad].  State per drive: ``current`` I(h) [A]
    at the end of the last step, ``mean`` Ī [A], ``u`` the applied voltage
    [V], ``torque`` i_G k_m Ī [N·m], ``saturated`` (1.0/0.0), ``damping``
    D of the step's mean torque [N·m·s/rad] (zero where Ī is at the limit).
    And the energy books (:func:`exo_ctrl.plant.energy.energy_fields`).
    """
    scalars = ("u_max", "kb", "inv_r", "i_max", "kt", "eps", "phi", "d_unsat")
    rows = ("current", "mean", "u", "torque", "saturated", "damping")
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
        torque[j] = mean * kt
        saturated[j] = 1.0 if sat else 0.0
        damping[j] = 0.0 if sat else d_unsat
