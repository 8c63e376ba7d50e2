r"""Patient load on the shank cuffs: the estimated load against the nominal patient's.

**What it is for.**  A cuff that slips off (``cuff_slip``, :mod:`exo_ctrl.sim.faults`)
carries no force, and no limit trips: its force falls to the estimate's
noise.  A shank cuff's force is observable, since the knee's external
torque is that cuff's alone (:mod:`exo_ctrl.estimation.cuff_geometry`),
but a patient who carries their own shank unloads it as much.  Telling an
unloaded cuff from a loaded one needs the load the patient should put on
it.  The device holds a model of its patient, the nominal one
(:mod:`exo_ctrl.sim.belief`: de Leva's segments from the stature and the
body mass), so this monitor compares the two.

**Predicted load.**  A passive patient's legs hang in the cuffs.  With the
patient's joints on the exoskeleton's (coaxial, as the device is fitted),
the cuffs must give the patient's legs the joint torques of their motion,
τ_p = M_p(q) q̈ + n_p(q, q̇) + b_p q̇ + f_p tanh(q̇/ε) (RNEA on the
device's patient model, its URDF damping b_p and friction f_p), and with
J_e = J_p at the cuff points the exoskeleton feels the reaction,

.. math::  \hat τ_{ext} ≈ p := -τ_p(q, \dot q, \ddot q),

q and q̇ the encoder's and speed readings, q̈ the speed reading's
difference over the sample period.  Per leg the knee's row is the shank
cuff's load: the channel ``cuff load <side>_shank``.  The hip's row is
both cuffs' together, and a thigh cuff that slips leaves it as it was: the
shank cuff takes the thigh's load, and the joint torques (so every
estimate made from them) do not change (measured: the hip's α below, 1.02
before and 1.04 after a slipped left thigh cuff).  A slipped thigh cuff
is not observable by load; it has no channel.  (The shank cuff then
carries 167–178 N, beyond ISO/TS 15066's 130 N, while the Kalman filter,
whose split between the cuffs is model-driven, reads at most 105 N on it:
seeds 0–2 of the campaign, either thigh.)

**Statistic.**  Sampled every N ticks (N Δt = :data:`SAMPLE_PERIOD_S`: the
gait's joint torques have their content below 10 Hz), over a sliding window
of W samples spanning one gait period T_s (so that the statistic does not
depend on the gait's phase), per knee:

.. math::

    α = \frac{\sum_i \hat τ_i\, p_i}{\sum_i p_i^2},\qquad
    P = \sqrt{\tfrac{1}{W} \sum_i p_i^2},

α the share of the predicted load that the estimate carries (its
least-squares gain on the prediction), P the predicted load's RMS [N·m].
A cuff is **unloaded** when α < α_th = :data:`LOAD_FRACTION` = ½ while
P ≥ P_min; the window judges nothing before it is full, nor while P < P_min.

**Threshold.**  Let E bound the RMS error of the estimated knee torque over
a window (:data:`ESTIMATE_ERROR_NM` = 1 N·m; measured against the true
cuff force's knee torque over windows of one period: at most 0.36 N·m on
the default PD run and 0.75 N·m from a shank cuff's slip on, its transient
included, with the Kalman filter; 0.83 and 0.82 N·m with the momentum
observer).  By Cauchy–Schwarz, whatever the error's spectrum,

- a slipped cuff (true load 0, τ̂ = its error): |α| ≤ E / P;
- a loaded cuff whose true load is κ p + m: α ≥ κ − (RMS(m) + E) / P.

P_min = 2 E / α_th = 4 N·m (:data:`MIN_LOAD_NM`) keeps E/P ≤ α_th/2: a
slipped cuff is then below the threshold by half of it; a loaded cuff
reads α > α_th as long as the nominal model's load is within a factor κ of
the truth with κ − RMS(m)/P > ¾.  The nominal patient's shank (de Leva: its
centre of mass 0.26 m below the knee) is lighter in load than the default
true patient's (0.315 m, the foot included): the least α over the default
runs is 1.18–1.28 (PD, CT, QP, the momentum observer, contact on; 1.03 on
the right leg with 30 % body-weight support), 2.29–2.41 with the spastic
patient, whose tone loads the cuffs more (tests/safety/test_cuff_load.py).

**Detection.**  Once a whole window lies after the slip, α ≤ E/P ≤ α_th/2:
the warning comes within one window and one sample,
T_s + N Δt (:func:`detection_bound_s`; 1.21 s with the default gait).
Measured 504–947 ms after the slip (the campaign's seeds 0–2, either
shank, tracking with PD): α falls as the window fills with the slipped
cuff's samples.

**Reaction: a warning.**  An unloaded cuff is either slipped or carried
by the patient; the load cannot tell which, so the monitor reports
``"cuff unloaded <cuff>: slipped cuff or the patient carries the segment"``,
an event of kind ``"warning"`` (the supervisor's state stays normal), once
per episode: the channel warns again only after its α came back to
α_r = 1 − α_th/2 = ¾ (:data:`RESTORED_FRACTION`), the least α of a loaded
cuff whose nominal load is right (κ = 1, m = 0 above), so that an α that
wanders about α_th (an active patient whose own gait drifts against the
plan's, measured 0.49–0.64 over 4.7–5.4 s) warns once.

**When it is off** (:func:`off_reason`).  Where the device does not carry
the patient's legs, an unloaded cuff is what it aims at or expects:
``transparent`` drives the cuff forces to zero; ``aan``, ``path`` and
``guidance`` with G < 1 leave the legs (or part of them) to the patient.
It runs in ``tracking`` and ``guidance`` with G = 1 (the device in charge,
as for the stop reaction, :func:`~exo_ctrl.safety.stop_reaction.default_stop_reaction`),
and restarts its window at each session segment's start.  An active
patient in tracking (or guidance with G = 1) carries their own legs: α is
−0.01–0.05 over the first full windows, and the monitor warns of both
shank cuffs then, naming both causes; it cannot say more.  Neither can it
with the patient's feet on the belt (``ContactParams.patient_feet``) the
belt carries part of the legs' load, and the device reads it from the shoes'
load cells (:mod:`exo_ctrl.sensing.foot_load`): the prediction then takes
the belt's share out, p := −(τ_p − J_pᵀ F_shoe), J_p the foot point's
Jacobian on the device's patient model at q.  Without that term the healthy
default run with the patient's feet read α = −1.08 and 0.05 on the shanks
(both warned); with it the least α is 0.71/0.71 (PD), 0.71/0.57 (QP) and
0.51/0.32 (CT, whose right shank still warns once: the belt's share is not
the whole story there, an open point; tests/safety/test_patient_feet_safety.py).

**Cost.**  One RNEA of the nominal patient (four joints) and two compiled
calls every N ticks, a Python comparison on the others: measured 4.5 µs
per sampling tick (the RNEA 1.5 µs of it) and 0.15 µs on the others,
0.6 µs per tick on average, about 2 % of the default tick.

Reference:
    de Leva P (1996). Adjustments to Zatsiorsky–Seluyanov's segment
    inertia parameters. J Biomech 29(9):1223–1230.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel, preload, record
from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, FRICTION_SMOOTHING_RAD_S, JOINT_NAMES, BodyModel
from ..model.leg_kernels import feet_torque, legs_record

__all__ = [
    "CUFF_LOAD_FIELDS",
    "ESTIMATE_ERROR_NM",
    "LOAD_FRACTION",
    "MIN_LOAD_NM",
    "RESTORED_FRACTION",
    "SAMPLE_PERIOD_S",
    "CuffLoadMonitor",
    "cuff_load_schedule",
    "detection_bound_s",
    "load_inputs",
    "load_update",
    "off_reason",
]

#: α_th: below this share of the predicted load a cuff is unloaded [-].
LOAD_FRACTION = 0.5

#: A cuff judged unloaded is loaded again from α ≥ 1 − α_th/2 [-]: the least α
#: of a loaded cuff whose nominal load is right (module docstring, "Reaction").
RESTORED_FRACTION = 1.0 - LOAD_FRACTION / 2.0

#: E: a bound of the estimated knee torque's RMS error over a window [N·m]
#: (measured 0.35 N·m healthy, 0.64 N·m on a slipped cuff; module docstring).
ESTIMATE_ERROR_NM = 1.0

#: P_min = 2 E / α_th: the least predicted RMS load the monitor judges [N·m].
MIN_LOAD_NM = 2.0 * ESTIMATE_ERROR_NM / LOAD_FRACTION

#: The sampling period of the loads [s] (N = round(it / Δt) ticks, at least one).
SAMPLE_PERIOD_S = 0.01

#: The knees' indices in JOINT_NAMES and their shank cuffs' in CUFF_NAMES (left, right).
_KNEES = (JOINT_NAMES.index("left_knee"), JOINT_NAMES.index("right_knee"))
_SHANKS = (CUFF_NAMES.index("left_shank"), CUFF_NAMES.index("right_shank"))

#: The monitor's record.  ``window`` W [samples], ``count`` samples in the
#: window (≤ W), ``head`` the next slot; ``inv_h`` 1/(N Δt) [1/s];
#: ``limit`` α_th, ``restore`` α_r, ``gate`` W P_min² [N²m²]; per joint (JOINT_NAMES) the
#: model's q index ``qi``, ``damping`` b_p [N·m·s/rad], ``friction`` f_p
#: [N·m], ``dq_prev`` the last sample's speeds [rad/s] (``has_prev``: set);
#: ``smoothing`` ε [rad/s]; per leg (left, right) ``alpha`` α and ``load``
#: P [N·m] of the last judged window (NaN: none), ``alpha_min`` the least α
#: judged, ``unloaded`` 1 while the cuff is judged unloaded.
CUFF_LOAD_FIELDS = [
    *((name, np.int64) for name in ("window", "count", "head")),
    *(
        (name, np.float64)
        for name in ("inv_h", "limit", "restore", "gate", "smoothing", "has_prev")
    ),
    ("qi", np.int64, (4,)),
    *((name, np.float64, (4,)) for name in ("damping", "friction", "dq_prev")),
    *((name, np.float64, (2,)) for name in ("alpha", "load", "alpha_min", "unloaded")),
]


def off_reason(mode: str, guidance: float = 1.0) -> str:
    """Why the monitor is off in ``mode`` ("" : on), module docstring's "When it is off".

    Args:
        mode: the interaction mode (:data:`~exo_ctrl.control.modes.MODES`).
        guidance: G of ``guidance`` [-] (ignored otherwise).

    """
    if mode == "tracking" or (mode == "guidance" and guidance >= 1.0):
        return ""
    if mode == "transparent":
        return "transparent drives the cuff forces to zero: an unloaded cuff is its aim"
    if mode == "guidance":
        return f"guidance with G = {guidance:g} < 1 leaves part of the legs to the patient"
    return f"{mode} leaves the legs to the patient: an unloaded cuff is expected"


def cuff_load_schedule(
    mode: str, guidance: float, session: Any = None
) -> tuple[tuple[float, str], ...]:
    """The monitor over the run: ((start time [s], off reason, "" when on), ...).

    Args:
        mode: the run's mode.
        guidance: the run's G.
        session: the session (its segments' modes and G decide; None: ``mode``).

    """
    if session is None:
        return ((0.0, off_reason(mode, guidance)),)
    out = []
    for start, seg in zip(session.starts_s, session.segments, strict=True):
        g = dict(seg.params).get("guidance", guidance)
        out.append((float(start), off_reason(seg.mode, g)))
    return tuple(out)


def detection_bound_s(period_s: float, dt: float) -> float:
    """T_s + N Δt: the latest warning of a slipped shank cuff while P ≥ P_min [s].

    Args:
        period_s: the window, one gait period T_s [s].
        dt: control period Δt [s].

    """
    every = _sample_ticks(dt)
    return _window_samples(period_s, every, dt) * every * dt + every * dt


def _sample_ticks(dt: float) -> int:
    return max(round(SAMPLE_PERIOD_S / dt), 1)


def _window_samples(period_s: float, every: int, dt: float) -> int:
    return max(round(period_s / (every * dt)), 2)


class CuffLoadMonitor:
    """The shank cuffs' estimated load against the nominal patient's (module docstring).

    Args:
        patient: the device's patient model (``Setup.device_patient``; never the plant's).
        tau_ext: the estimator's external joint torques, (4,) [N·m], updated
            in place each tick (its record's ``tau_ext``).
        dt: control period Δt [s].
        period_s: the window, one gait period T_s [s].
        schedule: ((start [s], off reason or ""), ...) (:func:`cuff_load_schedule`).
        shoes: the shoes' load cells' reading (x, z) per foot, (2, 2) [N],
            updated in place each tick, with the patient's feet on the belt
            (module docstring); None: the belt carries none of the legs.

    Attributes:
        record: the record of :data:`CUFF_LOAD_FIELDS`.
        ring: the window's samples, (2, 2, W): per leg the predicted and the
            estimated knee torque [N·m].
        every: N [ticks].
        window_s: the window, W N Δt [s].

    Raises:
        InvalidParameter: a bad Δt or T_s, or ``tau_ext`` not (4,).

    """

    def __init__(
        self,
        patient: BodyModel,
        tau_ext: np.ndarray,
        dt: float,
        period_s: float,
        schedule: Sequence[tuple[float, str]] = ((0.0, ""),),
        shoes: np.ndarray | None = None,
    ) -> None:
        dt = v.positive("dt", dt, "s")
        period_s = v.positive("period_s", period_s, "s")
        if not (isinstance(tau_ext, np.ndarray) and tau_ext.shape == (4,)):
            raise InvalidParameter("tau_ext", tau_ext, "the estimator's (4,) float array")
        self.every = _sample_ticks(dt)
        window = _window_samples(period_s, self.every, dt)
        self.window_s = window * self.every * dt
        self.record = record(CUFF_LOAD_FIELDS)
        r = self.record[0]
        r["window"], r["inv_h"] = window, 1.0 / (self.every * dt)
        r["limit"], r["restore"] = LOAD_FRACTION, RESTORED_FRACTION
        r["gate"] = window * MIN_LOAD_NM**2
        r["smoothing"] = FRICTION_SMOOTHING_RAD_S
        r["qi"], r["damping"], r["friction"] = patient.q_index, patient.damping, patient.friction
        r["alpha"] = r["load"] = math.nan
        r["alpha_min"] = math.inf
        self.ring = np.zeros((2, 2, window))
        self._model = patient.model
        self._data = patient.model.createData()
        self._q = pin.neutral(patient.model)
        self._v = np.zeros(patient.model.nv)
        self._a = np.zeros(patient.model.nv)
        self._tau_ext = tau_ext
        self._shoes = shoes
        self._legs = legs_record(patient)
        self._tau_g, self._tau = np.zeros(4), np.zeros(patient.model.nv)
        self._qi = patient.q_index
        self._schedule = tuple((float(t0), str(why)) for t0, why in schedule)
        self._segment = -1
        self.off = self._schedule[0][1]
        self._switch_s = self._schedule[0][0]
        self._next = 0

    def preload(self, q: np.ndarray, dq: np.ndarray) -> None:
        """Load (or compile) the kernels for readings of these arrays' types, before the run.

        Their first call comes some ticks into the run, inside its timed part.
        """
        preload(load_inputs, q, dq, self.record, self._q, self._v, self._a)
        preload(load_update, self._v, dq, self._tau_ext, self.record, self.ring)
        if self._shoes is not None:
            preload(feet_torque, self._legs, q, self._shoes, self._tau_g)

    def step(self, k: int, t: float, q: np.ndarray, dq: np.ndarray, events: list) -> None:
        """Tick ``k`` at t [s] with the readings q [rad], q̇ [rad/s]; a warning into ``events``.

        Samples every N ticks (the others return at once); call it while the
        supervisor is normal.
        """
        if k < self._next:
            return
        self._next = k + self.every
        if t >= self._switch_s:
            self._switch(t)
        if self.off:
            return
        if load_inputs(q, dq, self.record, self._q, self._v, self._a):
            tau = pin.rnea(self._model, self._data, self._q, self._v, self._a)
            if self._shoes is not None:  # the belt's share through the patient's feet
                feet_torque(self._legs, q, self._shoes, self._tau_g)
                tau = np.copyto(self._tau, tau) or self._tau
                tau[self._qi] -= self._tau_g
            new = load_update(tau, dq, self._tau_ext, self.record, self.ring)
            if new:
                self._warn(t, new, events)

    def _switch(self, t: float) -> None:
        """Enter the schedule's segment of time t [s]: its on/off, a fresh window."""
        while self._segment + 1 < len(self._schedule):
            start = self._schedule[self._segment + 1][0]
            if start > t + 1e-12:
                break
            self._segment += 1
            self.off = self._schedule[self._segment][1]
        nxt = self._segment + 1
        self._switch_s = self._schedule[nxt][0] if nxt < len(self._schedule) else math.inf
        r = self.record[0]
        r["count"] = r["head"] = 0
        r["has_prev"] = 0.0
        r["unloaded"] = 0.0

    def _warn(self, t: float, legs: int, events: list) -> None:
        r = self.record[0]
        for leg in (0, 1):
            if not legs & (1 << leg):
                continue
            cuff, knee = CUFF_NAMES[_SHANKS[leg]], JOINT_NAMES[_KNEES[leg]]
            alpha, load = float(r["alpha"][leg]), float(r["load"][leg])
            message = (
                f"cuff unloaded {cuff}: slipped cuff or the patient carries the segment "
                f"(its estimated load is {alpha:.2f} of the nominal patient's, limit "
                f"{LOAD_FRACTION:g}; predicted {load:.3g} N·m RMS at the {knee} over "
                f"{self.window_s:.3g} s) at t = {t:.4f} s"
            )
            events.append(
                {
                    "t": float(t),
                    "kind": "warning",
                    "quantity": f"cuff load {cuff}",
                    "value": alpha,
                    "limit": LOAD_FRACTION,
                    "message": message,
                }
            )


@kernel
def load_inputs(q, dq, state, qm, vm, am):  # pragma: no cover - compiled
    """The sample's RNEA inputs in the model's order; 1 if they are ready, else 0.

    Args:
        q: angle readings, (4,) [rad] (JOINT_NAMES).
        dq: speed readings, (4,) [rad/s].
        state: the record (``qi``, ``inv_h``, ``dq_prev``, ``has_prev``).
        qm: the model's q, written: the angles [rad].
        vm: the model's v, written: the speeds [rad/s].
        am: the model's a, written: q̈ = (q̇ − q̇_prev) / (N Δt) [rad/s²].

    A non-finite reading forgets the previous sample (0); the first sample
    after one only keeps its speeds (0).

    """
    s = state[0]
    for j in range(4):
        if not (math.isfinite(q[j]) and math.isfinite(dq[j])):
            s.has_prev = 0.0
            return 0
    ready = s.has_prev != 0.0
    for j in range(4):
        i = s.qi[j]
        qm[i] = q[j]
        vm[i] = dq[j]
        am[i] = (dq[j] - s.dq_prev[j]) * s.inv_h
        s.dq_prev[j] = dq[j]
    s.has_prev = 1.0
    return 1 if ready else 0


@kernel
def load_update(tau, dq, tau_ext, state, ring):  # pragma: no cover - compiled
    """Push the sample into the window and judge it; the legs newly unloaded (bits 0, 1).

    Args:
        tau: the nominal patient's RNEA torques, model order [N·m].
        dq: speed readings, (4,) [rad/s] (the joint losses b_p q̇ + f_p tanh(q̇/ε)).
        tau_ext: the estimated external joint torques, (4,) [N·m].
        state: the record (module docstring's α, P, threshold and gate).
        ring: the window, (2, 2, W): [leg, (predicted, estimated), sample].

    A non-finite estimate skips the sample.

    """
    s = state[0]
    for leg in range(2):
        if not math.isfinite(tau_ext[_KNEES[leg]]):
            return 0
    h = s.head
    w = s.window
    for leg in range(2):
        j = _KNEES[leg]
        loss = s.damping[j] * dq[j] + s.friction[j] * math.tanh(dq[j] / s.smoothing)
        ring[leg, 0, h] = -(tau[s.qi[j]] + loss)
        ring[leg, 1, h] = tau_ext[j]
    s.head = (h + 1) % w
    if s.count < w:
        s.count += 1
    if s.count < w:
        return 0
    new = 0
    for leg in range(2):
        spp = 0.0
        sep = 0.0
        for i in range(w):
            p = ring[leg, 0, i]
            spp += p * p
            sep += p * ring[leg, 1, i]
        if spp < s.gate:  # too little load to judge: the state is kept
            s.alpha[leg] = math.nan
            s.load[leg] = math.sqrt(spp / w)
            continue
        a = sep / spp
        s.alpha[leg] = a
        s.load[leg] = math.sqrt(spp / w)
        s.alpha_min[leg] = min(s.alpha_min[leg], a)
        if a < s.limit:
            if s.unloaded[leg] == 0.0:
                new |= 1 << leg
            s.unloaded[leg] = 1.0
        elif a >= s.restore:
            s.unloaded[leg] = 0.0
    return new
