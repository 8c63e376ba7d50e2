r"""When a pushed hold must yield: the cuff force a release reaches.

A hold (:mod:`.supervisor`) is a position lock: a patient who walks on
pushes their limb into the cuffs, and the cuff force rises at
ḟ = k v, v the limb's speed relative to the held link at the cuff (k the
cuff's stiffness).  Yielding (:mod:`.stop_reaction`) releases the
exoskeleton, but the force does not fall at once: the cuff is a spring
between two bodies, and it keeps loading until the exoskeleton's link has
caught up with the limb.  In their relative coordinate at the cuff point
the two bodies have the reduced inertia

.. math::

    Λ_c = \bigl(J_e M_e^{-1} J_e^T + J_p M_p^{-1} J_p^T\bigr)^{-1}\quad(2×2,\ x\text{–}z),

J the cuff point's Jacobian of each body, M_e the device's exoskeleton
model's joint-space inertia with the drives' reflected rotor inertia
i_G² J_r on its joints (a yielding drive does not hide its rotor), M_p the
nominal patient's, both at the hold posture (the patient's joint angles
taken equal to the exoskeleton's, as the hold's gravity term does; the
pseudo-inverse leaves out the directions neither body can move in, a force
along the thigh).  Released at a cuff force f with v = ḟ/k, undamped and
with the patient's muscles doing no work over the catch-up, the relative
motion's energy ½|f|²/k + ½ vᵀ Λ_c v is all in the spring at the force's
peak:

.. math::  |f_{max}|^2 = |f|^2 + ḟ^T Λ_c\, ḟ / k.

So a hold must yield, at once (:mod:`.stop_reaction`, "From a hold"), while
that peak is still within the cuff's limit: :meth:`ReleaseBound.peak_squared`
is what the supervisor compares with F_lim² every tick of the hold.  The old
trigger, the force over its limit, is the case ḟ = 0: a release at the limit
overshoots it by the catch-up, and by the estimate's lag behind the truth.

**Numbers** (default URDFs, the nominal patient, k = 8 N/mm, the hold
posture of tests/safety/test_hold_pushed.py, q ≈ (0.70, 1.00, 0.35, 1.00)
rad): Λ = 6.4 kg across the thigh cuff (13.9 kg of exoskeleton, the drives'
rotor included, against 12.0 kg of patient; along the thigh neither moves),
1.2 and 5.1 kg at the shank cuff (about across and along the shank: a force
along the shank turns the hip); √(Λ/k) = 28, 12 and 25 ms.  In that test the
left shank cuff read 70 N rising at 4.8 N/ms on a 4.2 kg axis: a catch-up of
110 N, a bound of 130 N, and the yield came there; the true forces from that
tick on peaked at 116 N (shank) and 152 N (thigh).  Yielding on the force
over the limit instead, switched at once, the shank's true force was 136 N at
the switch and peaked at 137 N.  (Measured on the patient model
before its reflex damping acted at once; on the model since, a patient
with 2.5× the default reflex stiffness keeps pushing the released limb,
past the limits: tests/safety/test_hold_pushed.py.)

**Conservative, not exact.**  The cuff's damper (damping ratio about 0.3,
:class:`~exo_ctrl.plant.cuffs.CuffParams`) takes energy out of the catch-up
(130 N predicted, 116 N true above), more than the estimate's lag behind
the truth adds (2–4 ms of the Kalman filter: 7 N at the switch above).  On
the nine variants of the test that stop (sensor seeds 0–2, the patient's
period 0.9 or 1.1 s, steps of 0.35 m, the momentum observer, the true
forces, the isotropic cuff belief) the worst true force from a switch in
the hold on was 186 N at a thigh and 127 N at a shank (on the force over
the limit and the ramp: 209 N and 149 N); from a switch in the ramp (four
of them, below), 202 N and 146 N: a cuff the stop found over its limit
stays over it for the catch-up.

**Only a loading cuff** (f·ḟ > 0) adds its term.  Unloading, the limb moves
away from the link and the hold lets it; should it turn and load the cuff
again, the bound sees it from that tick on (at the turn ḟ ≈ 0: the bound is
continuous there).  The rate of an unloading cuff can be mostly its
damper's, C v̇: an e-stop switched to the hold at once (ramp 0,
tests/safety/test_supervisor.py) stops the link under the limb, and the
shank's force fell at 8.6 N/ms from 52 N, which would read as a release
peak of 243 N; it never exceeded the 52 N it fell from.

**In the ramp** to the hold (0.2 s, :mod:`.supervisor`) the command
stiffens towards the lock, and a patient who walks on meets it as a hold:
the bound is checked there too.  The stop may have come on a cuff over its
limit, whose bound is over F_lim² from the first tick whatever the patient
does next: such a cuff yields once its bound passes (:data:`RAMP_MARGIN` ·
|f_stop|)², the force the stop found and 5 % (1730 N² at a shank's 130 N,
nearly three times the rate term's noise, below).  Unchecked, an active
patient at 1.1 s steps against the plan's 1.2 s loaded the cuffs to true
250 N (thigh) and 175 N (shank) over the ramp, the yield coming at its end;
checked, the yield comes on the next tick and they peak at 202 and 146 N
(the shank was at 139 N at the stop: the estimate's lag).  On the nine
variants above (four now yield in the ramp): at most 229 / 135 N from the
stop on (unchecked: 250 / 175 N).  A sensor fault that stops the run on the
estimate can yield there before a plausibility monitor doubts the readings
(they need 20 ms or more): an encoder frozen at the hip's current limit
(tests/safety/test_still.py) yields 1 ms after its stop, and the faulty hip
moves 0.02 rad (the hold drove it 0.24 rad on the frozen reading), the
cuffs within 113 N.  The spastic passive patient of the default run,
stopped on the estimate's over-read of a shank cuff it does not push (true
98 N), keeps the hold (0.08 rad of excursion; yielding, its spasm moved the
leg 0.74 rad).

ḟ is the readings' difference over one tick; its noise (0.3–1 N/ms RMS on
the Kalman estimate) adds up to ḟᵀ Λ ḟ / k ≈ 640 N² at a shank and 800 N²
at a thigh: it can bring a yield forward by 2–3 N of force near the limit,
never keep a hold on a cuff over its limit (ḟ = 0 is the old trigger).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .. import _validate as v
from ..model import BodyModel
from ..plant import CuffParams, MotorParams

__all__ = ["RAMP_MARGIN", "ReleaseBound"]

#: In the ramp to the hold, a cuff over its limit at the stop yields once its
#: bound passes this factor times its force at the stop (module docstring, "In the ramp").
RAMP_MARGIN = 1.05


class ReleaseBound:
    """|f_max|² per cuff for a release now (module docstring), on the device's models.

    Args:
        exo: the exoskeleton model the device holds.
        patient: the nominal patient model (None: the exoskeleton alone, the
            limb then taken as infinitely heavy: a larger bound).
        motor: the drive's datasheet (its reflected rotor inertia).
        dt: control period Δt [s] (the readings' difference).
        stiffness: the cuffs' stiffness k the device believes [N/m] (None:
            the nominal isotropic cuff's, 8 N/mm, paper Table I).

    Attributes:
        inertia: Λ_c per cuff at the hold posture [kg], (4, 2, 2), CUFF_NAMES order.

    Raises:
        InvalidParameter: a stiffness that is not a finite number > 0 (named
            ``cuff_stiffness``).

    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel | None,
        motor: MotorParams,
        dt: float,
        stiffness: float | None = None,
    ) -> None:
        k = CuffParams.isotropic().stiffness_N_per_m if stiffness is None else stiffness
        self._k, self._dt = v.positive("cuff_stiffness", k, "N/m"), dt
        self._bodies = []
        for body, armature in ((exo, motor.reflected_inertia_kgm2), (patient, 0.0)):
            if body is not None:
                model = pin.Model(body.model)
                model.armature[body.q_index] += armature  # crba then includes it
                self._bodies.append((model, model.createData(), body))
        self.inertia = np.zeros((4, 2, 2))
        self._posture = np.full(4, np.nan)
        self._last = np.full((4, 2), np.nan)
        self._found: np.ndarray | None = None

    def begin(self) -> None:
        """A ramp to the hold begins (a stop, a yield's rest): :meth:`pushed` forgets the last."""
        self._found = None

    def pushed(self, f: np.ndarray, q_hold: np.ndarray, limit: np.ndarray, ramp: bool) -> bool:
        """Whether the hold must yield now: a release would take a cuff past its limit.

        Args:
            f: this tick's cuff forces [N], (4, 2).
            q_hold: the hold posture [rad], (4,).
            limit: F_lim per cuff [N], (4,).
            ramp: the command still ramps to the hold: a cuff must pass the
                bound the stop's first tick found too (a cuff over its limit
                stops the run; module docstring, "In the ramp").

        """
        peak, limit2 = self.peak_squared(f, q_hold), limit * limit
        if self._found is None:
            self._found = np.maximum(peak * RAMP_MARGIN**2, limit2)
        return bool(np.any(peak > (self._found if ramp else limit2)))

    def start(self, q: np.ndarray) -> None:
        """Λ_c at the hold posture q [rad], (4,); the next reading has no predecessor."""
        self._posture[:] = q
        self._last.fill(np.nan)
        inverse = np.zeros((4, 2, 2))
        for model, data, body in self._bodies:
            qm = pin.neutral(model)
            qm[body.q_index] = q
            mass = pin.crba(model, data, qm)
            mass = np.triu(mass) + np.triu(mass, 1).T
            m_inv = np.linalg.inv(mass)
            pin.computeJointJacobians(model, data, qm)
            pin.updateFramePlacements(model, data)
            for c, frame in enumerate(body.cuff_frame_ids):
                jac = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[[0, 2]]
                inverse[c] += jac @ m_inv @ jac.T
        for c in range(4):
            self.inertia[c] = np.linalg.pinv(inverse[c], rcond=1e-9, hermitian=True)

    def peak_squared(self, f: np.ndarray, q_hold: np.ndarray) -> np.ndarray:
        """|f|² + ḟᵀ Λ_c ḟ / k per cuff [N²], (4,), for this tick's cuff forces f [N], (4, 2).

        ``q_hold``: the hold posture [rad], (4,); a new one recomputes Λ_c
        (:meth:`start`).  ḟ is (f − f_prev)/Δt, zero on the first reading of
        a hold and wherever a reading is not finite (then the peak is NaN:
        the supervisor's monitors refuse the reading).
        """
        if not np.array_equal(q_hold, self._posture):
            self.start(q_hold)
        rate = (f - self._last) / self._dt
        rate[~np.isfinite(rate)] = 0.0
        self._last[:] = f
        kinetic = np.einsum("ci,cij,cj->c", rate, self.inertia, rate) / self._k
        kinetic[np.einsum("ci,ci->c", f, rate) <= 0.0] = 0.0  # not loading: a hold's own sway
        return np.einsum("ci,ci->c", f, f) + kinetic
