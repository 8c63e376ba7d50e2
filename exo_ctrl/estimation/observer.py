r"""Cuff (interaction) forces from the joint torque sensors: the live momentum observer.

**Link dynamics seen by the sensors.**  The joint torque sensors sit between
gearbox and link, so the rotor's reflected inertia is on the far side of
them: the observer uses the exoskeleton's *link* model only (no armature),

    M(q) q̈ + C(q, q̇) q̇ + g(q) = τ_s − b q̇ − f_c tanh(q̇/ε) + τ_ext,
    τ_ext = Σ_c J_cᵀ f_c,

with τ_s the sensor torque, b and f_c the URDF joint damping and dry
friction (link side, not seen by the sensor; ε =
:data:`~exo_ctrl.model.FRICTION_SMOOTHING_RAD_S`), f_c the (x, z) force of
cuff c on the exoskeleton and J_c the x, z rows of its frame Jacobian.

**Generalised-momentum observer** (De Luca & Mattone 2005; Haddadin, De
Luca & Albu-Schäffer, "Robot collisions: a survey on detection, isolation,
and identification", IEEE T-RO 33(6), 2017).  With p = M(q) q̇ and
Ṁ = C + Cᵀ, ṗ = τ_s − b q̇ − f_c tanh(q̇/ε) + Cᵀ q̇ − g + τ_ext, so

    r(t) = K_O [p(t) − p(0) − ∫₀ᵗ (τ_s − b q̇ − f_c tanh(q̇/ε) + Cᵀ q̇ − g + r) ds]

obeys ṙ = K_O (τ_ext − r): r is τ_ext through a first-order low-pass of
bandwidth K_O [1/s] (K_O / 2π Hz).  Neither q̈ nor a derivative of the
measured speed is needed.  The update makes two Pinocchio calls, ``crba``
(M) and ``nonLinearEffects`` (n = C q̇ + g): with Ṁ = C + Cᵀ (Pinocchio's C
is the Christoffel-consistent one), Cᵀ q̇ − g = Ṁ q̇ − n, and the Ṁ q̇ part
is integrated along the path from the encoder readings alone, ∫ Ṁ q̇ ds
over a step ≈ (M_k − M_{k-1}) (q_k − q_{k-1}) / h, so C itself is never
formed (pairing M(q_k) with the filtered speed instead would pair it with
a lagged signal: a mean error of up to 0.05 N·m on the default gait).

*Discrete form* (step h, readings q_k, q̇_k, τ_k, where τ_k is the sensor
reading over [t_{k-1}, t_k]; the plant's reading at tick k is the one of the
step just taken):  with m = −n(q, q̇) − b q̇ − f_c tanh(q̇/ε) and M_k = M(q_k),

    s_k = s_{k-1} + h (τ_k + ½ (m_{k-1} + m_k) + r_{k-1})
                  + (M_k − M_{k-1}) (q_k − q_{k-1}) / h,   s_0 = p_0,
    r_k = K_d (p_k − s_k),   K_d = (1 − e^{−K_O h}) / h,

which gives r_k = r_{k-1} + (1 − e^{−K_O h}) (e_k − r_{k-1}) with e_k the
external torque over the step.  As M_k q̇_k − M_{k-1} q̇_{k-1} =
½ (M_k + M_{k-1}) (q̇_k − q̇_{k-1}) + ½ (M_k − M_{k-1}) (q̇_k + q̇_{k-1}),
and (q_k − q_{k-1}) / h ≈ ½ (q̇_{k-1} + q̇_k),

    e_k ≈ ½ (M_{k-1} + M_k) (q̇_k − q̇_{k-1}) / h − ½ (m_{k-1} + m_k) − τ_k,

inverse dynamics with the mean mass matrix times the finite-difference
acceleration.  Given e_k, the r recursion is the exact zero-order-hold
discretisation of the continuous filter, stable for every K_O > 0 (K_d → K_O
as h → 0).  When h changes (a log with uneven time stamps) s is re-anchored
to s = p − r/K_d, which keeps that identity.  r is then mapped to cuff
forces by the assumption of :mod:`exo_ctrl.estimation.cuff_geometry`.

**Default gain** K_O = 100 1/s (bandwidth 16 Hz, time constant 10 ms).
The observer passes encoder-speed noise to r with a gain of about K_O M
(p = M q̇ enters r multiplied by K_O), and lags the cuff forces by 1/K_O.
On the default gait (cycle 1.2 s) with the default sensors
(:mod:`exo_ctrl.sensing.sensors`) the worst cuff's RMS error of the normal
component is 7.3 % of its peak at K_O = 50 1/s (lag), 4.4 % at 100 and 200,
and 7.0 % at 400 (speed noise) (tests/estimation/test_observer.py prints
this); 100 1/s is the less noisy end of the flat optimum.  With ideal
sensors the error is the lag alone: 4.6 % at 100 1/s, 0.45 % at 1000 1/s.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import Status, check, kernel, record
from ..exceptions import InvalidParameter
from ..model import FRICTION_SMOOTHING_RAD_S, BodyModel
from ..sensing.readings import SensorReadings
from .cuff_geometry import GEOMETRY_FIELDS, CuffGeometry, _cuff_directions

__all__ = ["DEFAULT_GAIN_PER_S", "CuffForceEstimator", "observer_step"]

#: Default observer gain K_O [1/s] (bandwidth K_O / 2π ≈ 16 Hz).
DEFAULT_GAIN_PER_S = 100.0

#: The observer's record: parameters, then state and outputs.  tau_ext,
#: cuff_normal and cuff_force are adjacent float64 fields, so that
#: :attr:`CuffForceEstimator.outputs_flat` is one contiguous view of them.
_FIELDS = [
    # Link model: damping b [N·m·s/rad], dry friction f_c [N·m], smoothing ε [rad/s].
    ("damping", np.float64, (4,)),
    ("friction", np.float64, (4,)),
    ("friction_smoothing", np.float64),
    ("has_friction", np.bool_),
    # Torque-sensor bias β subtracted from the readings [N·m].
    ("torque_bias", np.float64, (4,)),
    ("has_bias", np.bool_),
    # κ of the assumption [-] and the cuff geometry (CuffGeometry, per leg).
    ("stiffness_ratio", np.float64),
    *GEOMETRY_FIELDS,
    # State: s = p_0 + ∫ (τ + m + r) dt, p = M q̇, m and m_{k-1} [N·m·s, N·m].
    ("s", np.float64, (4,)),
    ("p", np.float64, (4,)),
    ("m", np.float64, (4,)),
    ("m_prev", np.float64, (4,)),
    # Outputs: r [N·m], f⊥ [N] (CUFF_NAMES order), forces (x, z) per cuff [N].
    ("tau_ext", np.float64, (4,)),
    ("cuff_normal", np.float64, (4,)),
    ("cuff_force", np.float64, (4, 2)),
    # K_d [1/s], whether the observer has started, M_{k-1} [kg·m²], q_{k-1} [rad].
    ("kd", np.float64),
    ("started", np.bool_),
    ("mass_prev", np.float64, (4, 4)),
    ("q_prev", np.float64, (4,)),
]


class CuffForceEstimator:
    """Live cuff-force estimate from the sensor readings, one update per tick.

    An update is two Pinocchio calls (``crba`` and ``nonLinearEffects`` of
    the link model) and one call of the compiled kernel
    :func:`observer_step`, which does the rest (momentum, model terms, the
    observer step, the cuff forces).

    Args:
        exo: the exoskeleton model (its link model is used; see the module
            docstring).
        dt: control period h [s].
        gain_per_s: observer gain K_O [1/s] (bandwidth K_O / 2π Hz).
        torque_bias_Nm: a known (calibrated) torque-sensor bias to subtract,
            (4,) or scalar [N·m] (see :func:`~exo_ctrl.estimation.bias.estimate_bias`).
        stiffness_ratio: κ of the assumption
            (:mod:`~exo_ctrl.estimation.cuff_geometry`): shank-cuff over
            thigh-cuff stiffness with coaxial joints; 0: straps carry only
            normal forces [-].

    Attributes:
        record: the observer's parameters, state and outputs, a one-element
            structured array (fields ``tau_ext`` (4,) [N·m], ``cuff_normal``
            (4,) [N], ``cuff_force`` (4, 2) [N], and the state); the same
            array for the whole run.
        tau_ext: external joint torques r of the last update [N·m], (4,).
        normal: estimated normal components f⊥ [N], (4,), CUFF_NAMES order.
        force: estimated cuff forces on the exoskeleton [N], (4, 2): f_t⊥ n_t
            (thighs), f_s⊥ n_s + f_s∥ u_s (shanks).
        outputs_flat: (tau_ext, normal, force) as one contiguous (16,) view.
        torque_bias_Nm: the subtracted bias β [N·m], (4,).
        geometry: the cuff lever arms and directions.

        ``tau_ext``, ``normal``, ``force``, ``outputs_flat`` and
        ``torque_bias_Nm`` are views of :attr:`record`, overwritten in place.

    """

    def __init__(
        self,
        exo: BodyModel,
        dt: float,
        gain_per_s: float = DEFAULT_GAIN_PER_S,
        torque_bias_Nm: np.ndarray | float = 0.0,
        stiffness_ratio: float = 1.0,
    ) -> None:
        exo.require_legs_only("the estimator")
        self.dt = v.positive("dt", dt, "s")
        self.gain_per_s = v.positive("gain", gain_per_s, "1/s")
        bias = np.broadcast_to(np.asarray(torque_bias_Nm, dtype=float), (4,))
        for b in bias:
            v.finite("torque_bias", b, "N·m")
        self.record = rec = record(_FIELDS)
        self.torque_bias_Nm = rec["torque_bias"][0]
        self.torque_bias_Nm[:] = bias
        rec["has_bias"] = bool(np.any(bias != 0))
        self.stiffness_ratio = stiffness_ratio
        self.exo = exo
        self.geometry = CuffGeometry.from_body(exo)
        self.geometry.fill(rec)
        self._model = pin.Model(exo.model)
        self._model.armature = np.zeros(self._model.nv)  # link side: no rotor inertia
        self._data = self._model.createData()
        rec["damping"][0] = exo.damping
        rec["friction"][0] = exo.friction
        rec["friction_smoothing"] = FRICTION_SMOOTHING_RAD_S
        rec["has_friction"] = bool(np.any(exo.friction > 0))
        self._s = rec["s"][0]  # p_0 + ∫ (τ + m + r) dt
        self._p = rec["p"][0]
        self._tmp = np.zeros(4)
        self._zeros = np.zeros(4)
        self._h_cached = math.nan
        self._started = False
        self.tau_ext = rec["tau_ext"][0]
        self.normal = rec["cuff_normal"][0]
        self.force = rec["cuff_force"][0]
        start = rec.dtype.fields["tau_ext"][1] // 8
        self.outputs_flat = rec.view(np.float64)[start : start + 16]

    @property
    def stiffness_ratio(self) -> float:
        """κ of the assumption [-] (:mod:`~exo_ctrl.estimation.cuff_geometry`)."""
        return self._stiffness_ratio

    @stiffness_ratio.setter
    def stiffness_ratio(self, value: float) -> None:
        self._stiffness_ratio = v.non_negative("stiffness_ratio", value, "")
        self.record["stiffness_ratio"] = self._stiffness_ratio

    # ------------------------------------------------------------------ public

    def reset(self, q: np.ndarray | None = None, dq: np.ndarray | None = None) -> None:
        """Restart the observer (estimate zero).

        Args:
            q: joint angles [rad] at the tick *before* the next :meth:`update`
                (which then integrates over one period dt from this state);
                None: the next update starts the observer at its own readings.
            dq: joint speeds [rad/s] with ``q``.

        """
        self.tau_ext[:] = 0.0
        self.normal[:] = 0.0
        self.force[:] = 0.0
        self._started = False
        self.record["started"] = False
        if q is None or dq is None:
            return
        self.step(np.asarray(q, dtype=float), np.asarray(dq, dtype=float), self._zeros, self.dt)

    def update(self, sensors: SensorReadings) -> np.ndarray:
        """Advance by one control period with this tick's readings.

        Args:
            sensors: encoder angles q [rad], speeds dq [rad/s] and sensor
                torques tau [N·m] of this tick.

        Returns:
            The estimated cuff forces on the exoskeleton, (4, 2) [N]
            (:attr:`force`, overwritten by the next update).

        """
        return self.step(sensors.q, sensors.dq, sensors.tau, self.dt)

    def step(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray, h: float) -> np.ndarray:
        """Advance by a step h [s] with readings (q, dq, tau); as :meth:`update`.

        The first step after construction or :meth:`reset` starts the observer
        at these readings (estimate zero; ``tau`` and ``h`` unused).

        Raises:
            InvalidParameter: q, dq or tau is not of shape (4,) (nothing changed).

        """
        if not (type(q) is type(dq) is type(tau) is np.ndarray):
            q, dq, tau = v.arrays((4,), q=q, dq=dq, tau=tau)
        if q.shape != (4,) or dq.shape != (4,):  # before Pinocchio sees them
            v.refuse_shapes((4,), q=q, dq=dq)
        if not self._started:
            self._started = True  # the kernel starts the observer at these readings
        elif h != self._h_cached:
            self._set_step(h)
        model, data = self._model, self._data
        status = observer_step(
            self.record,
            pin.crba(model, data, q),
            pin.nonLinearEffects(model, data, q, dq),
            q,
            dq,
            tau,
            h,
        )
        if status:
            self.answer(status, q, tau)
        return self.force

    def bind(self, sensors: SensorReadings) -> Callable[[], np.ndarray]:
        """:meth:`update` with ``sensors``, as a call without arguments, for the control tick.

        The readings' arrays are checked once, here; the call then makes
        :meth:`step`'s Pinocchio calls and kernel on them with nothing
        around, and reads the arrays as they are at each call.

        Raises:
            InvalidParameter: q, dq or tau is not a float (4,) array.

        """
        q, dq, tau = sensors.q, sensors.dq, sensors.tau
        v.held_arrays((4,), q=q, dq=dq, tau=tau)
        rec, model, data, force, h = self.record, self._model, self._data, self.force, self.dt
        crba, nle = pin.crba, pin.nonLinearEffects

        def update() -> np.ndarray:
            if not (self._started and self._h_cached == h):
                return self.step(q, dq, tau, h)
            mass, bias = crba(model, data, q), nle(model, data, q, dq)
            status = observer_step(rec, mass, bias, q, dq, tau, h)
            if status:
                self.answer(status, q, tau)
            return force

        return update

    @property
    def started(self) -> bool:
        """Whether the observer has started at its period dt (its next update steps it)."""
        return self.running_at(self.dt)

    def step_arguments(self) -> tuple[tuple, tuple, tuple]:
        """What a fused tick (:mod:`exo_ctrl.sim.fused`) calls of :meth:`step`, once started.

        The model and data of the CRBA and nonLinearEffects calls on this
        tick's readings, then the kernel's record and its step dt (in the
        fused tick's layout: no cuff model, split, cuff sensors or filter).
        """
        return (self._model, self._data), (self.record, None), (None, None, None, self.dt)

    def answer(self, status: int, q: np.ndarray, tau: np.ndarray) -> None:
        """A step's status other than OK raises, naming the reading."""
        check(status, "CuffForceEstimator.step", tau=tau)

    def running_at(self, h: float) -> bool:
        """Whether the observer has started and steps by h (its next update takes no set-up)."""
        return self._started and h == self._h_cached

    # ------------------------------------------------------------------ internals

    def _set_step(self, h: float) -> None:
        """A new step h: K_d = (1 − e^{−K_O h}) / h, and s re-anchored to p − r / K_d."""
        if not h > 0:
            raise InvalidParameter("step", h, "> 0 s")
        self._h_cached = h
        kd = -math.expm1(-self.gain_per_s * h) / h
        self.record["kd"] = kd
        # A new step length changes K_d: re-anchor s so that r_{k-1} = K_d (p_{k-1} - s_{k-1}).
        np.divide(self.tau_ext, kd, out=self._tmp)
        np.subtract(self._p, self._tmp, out=self._s)


_OUTPUT_FIELDS = ("tau_ext", "cuff_normal", "cuff_force")
_offsets = [record(_FIELDS).dtype.fields[f][1] for f in _OUTPUT_FIELDS]
if _offsets != [_offsets[0], _offsets[0] + 32, _offsets[0] + 64] or _offsets[0] % 8:
    raise TypeError(f"the observer's outputs {_OUTPUT_FIELDS} must be adjacent float64 fields")
del _offsets


@kernel
def observer_step(state, mass, nle, q, dq, tau, h):
    """One observer step in place (module docstring, discrete form), then the cuff forces.

    ``mass``, ``nle``: M(q) and n(q, q̇) of the link model (Pinocchio's
    ``crba`` and ``nonLinearEffects`` at this tick's readings).
    p = M q̇, m = −n − b q̇ − f_c tanh(q̇/ε);
    s += h (τ − β + ½ (m_{k-1} + m) + r) + (M − M_{k-1}) (q − q_{k-1}) / h,
    r = K_d (p − s).
    Not started: s = p, m_{k-1} = m, M_{k-1} = M, q_{k-1} = q, r = f = 0,
    then started.

    Returns:
        The value of a :class:`~exo_ctrl._jit.Status` (a plain integer:
        returning the enum member itself costs about 0.5 µs per call to box):
        OK, or WRONG_LENGTH (and nothing done) when ``tau`` is not of length 4.

    """
    if tau.shape[0] != 4:
        return Status.WRONG_LENGTH.value
    st = state[0]
    has_friction = st.has_friction
    eps = st.friction_smoothing
    for i in range(4):
        p = 0.0
        for j in range(4):
            p += mass[i, j] * dq[j]
        m = -nle[i] - st.damping[i] * dq[i]
        if has_friction:
            m = m - math.tanh(dq[i] / eps) * st.friction[i]
        st.p[i] = p
        st.m[i] = m
    if not st.started:
        for i in range(4):
            st.s[i] = st.p[i]
            st.m_prev[i] = st.m[i]
            st.tau_ext[i] = 0.0
            st.cuff_normal[i] = 0.0
            st.cuff_force[i, 0] = 0.0
            st.cuff_force[i, 1] = 0.0
            st.q_prev[i] = q[i]
            for j in range(4):
                st.mass_prev[i, j] = mass[i, j]
        st.started = True
        return Status.OK.value
    has_bias = st.has_bias
    kd = st.kd
    for i in range(4):
        x = (st.m_prev[i] + st.m[i]) * 0.5 + tau[i]
        if has_bias:
            x = x - st.torque_bias[i]
        dp = 0.0  # (M_k − M_{k-1}) (q_k − q_{k-1}), row i; then M_{k-1} = M_k
        for j in range(4):
            dp += (mass[i, j] - st.mass_prev[i, j]) * (q[j] - st.q_prev[j])
            st.mass_prev[i, j] = mass[i, j]
        s = st.s[i] + (x + st.tau_ext[i]) * h + dp / h
        st.s[i] = s
        st.tau_ext[i] = (st.p[i] - s) * kd
        st.m_prev[i] = st.m[i]
    for i in range(4):
        st.q_prev[i] = q[i]
    _cuffs_kernel(state, q)
    return Status.OK.value


@kernel
def _cuffs_kernel(state, q):
    """Normal components and forces from r: solve A(q) (f_t⊥, f_s⊥) = (τ_hip, τ_knee) per leg.

    The compiled form of :func:`~exo_ctrl.estimation.cuff_geometry.cuff_forces_from_torque`
    for one posture q [rad]: reads ``tau_ext``, ``stiffness_ratio`` and the
    geometry of the record, writes ``cuff_normal`` and ``cuff_force``.
    """
    st = state[0]
    kappa = st.stiffness_ratio
    for s in range(2):
        sh, sk, a, dt0 = st.sign_hip[s], st.sign_knee[s], st.thigh_arm[s], st.thigh_dir0[s]
        l1, dk0, c, ds0 = st.knee_arm[s], st.knee_dir0[s], st.shank_arm[s], st.shank_dir0[s]
        qh, qk = q[2 * s], q[2 * s + 1]
        psi_t, psi_s = _cuff_directions(sh, sk, dt0, ds0, qh, qk)
        psi_k = dk0 + sh * qh
        f_s = st.tau_ext[2 * s + 1] / (sk * c)
        w_arm = l1 * math.cos(psi_s - psi_k) + c  # w of the cuff_geometry docstring
        sn = math.sin(psi_s - psi_k)
        kappa_sn = kappa * sn
        f_t = (st.tau_ext[2 * s] / sh - w_arm * f_s) / (a + kappa_sn * sn * l1 * l1 / a)
        st.cuff_normal[2 * s] = f_t
        st.cuff_normal[2 * s + 1] = f_s
        t, k = 2 * s, 2 * s + 1  # rows of the thigh and shank cuffs of leg s
        st.cuff_force[t, 0] = -f_t * math.sin(psi_t)
        st.cuff_force[t, 1] = f_t * math.cos(psi_t)
        f_sa = kappa_sn * l1 / a * f_t  # f_s∥, along knee → shank cuff
        st.cuff_force[k, 0] = -f_s * math.sin(psi_s) + f_sa * math.cos(psi_s)
        st.cuff_force[k, 1] = f_s * math.cos(psi_s) + f_sa * math.sin(psi_s)
