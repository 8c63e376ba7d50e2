r"""The yield's command U_y, and its force feedback after a departure stop.

The yield itself (gravity compensation of the device's models, the injected
damping d_y, the back-EMF compensated, the ramp, the speed filter, the brake
of a joint out of its range) is described in :mod:`.stop_reaction`; this
module computes it.

**Force feedback after the QP's departure stop** (:meth:`YieldCommand.start`
with ``force_limit_N``).  Without feedback the patient who keeps walking
moves the exoskeleton's links and the drives' reflected rotors through the
cuffs: an active patient on the precomputed plan (``tools/load_held.py
--cuff-sensors full --sync off``, point 65: 60 kg, bound 136 N, the walk
stopped at 1.306 s) swung the right leg with 75 N·m at the hip and dragged
the exoskeleton's thigh to 165.9 N, 0.2 s into the yield.  The departure
stop is not a sensor fault (the QP, reading the same sensors, left its plan
to hold its bound), so the yield may use the device's estimate of the cuff
forces f̂_c (the supervisor's, fused with the cuff sensors when fitted) and
add the interaction torque they put on the joints, τ̂_int = Σ_c J_cᵀ f̂_c
(:meth:`~exo_ctrl.estimation.cuff_geometry.CuffGeometry.joint_torques`),
with a gain K_j per joint:

.. math::  τ_y = g(q) - d_y\,\hat\omega + K\,\hat τ_{int}.

The link then obeys I q̈ = (1 + K) τ_int + …: the patient feels the
exoskeleton's inertia divided by 1 + K (as ``transparent``'s K_f,
:mod:`exo_ctrl.control.modes.controller`).  **The gain** is the least that
keeps the inertia's cuff force within the share of the bound the damping
leaves, 1 − σ (:data:`YIELD_FORCE_SHARE`), at the patient's largest
acceleration q̈_p (:data:`PATIENT_ACCELERATION_RAD_S2`):

.. math::  K_j = \min\Bigl(K_{max},\ \max\bigl(0,\ \frac{I_j\,q̈_p}{r_j\,(1-σ)\,F_j} - 1\bigr)\Bigr),

I_j the diagonal of the device's exoskeleton mass matrix at the stop
posture plus the reflected rotor inertia i_G² J_r, r_j the lever of the cuff
the joint's torque loads (hip: thigh cuff, knee: shank cuff, as d_y's), F_j
that cuff's bound (the QP's), K_max = :data:`MAX_FORCE_GAIN`.  Point 65: K =
3.8 at the right hip, 0.12 at the knee; its thigh cuff peaked at 75.5 N
(−44.4 %; 107.4 N with K = 1 on every joint).  Over the campaign's 200 points
(seed 0, each cuff-sensor set and both plans) every run stays within 5 % of
its bound; the supported active points' worst without cuff sensors went
from −16.2 % to −21.5 %.  The feedback ends for the rest of the stop once a
plausibility monitor doubts the readings (the supervisor's
:meth:`~exo_ctrl.safety.SafetySupervisor.step`), skips a tick whose estimate
is not finite, and ends on a leg once one of its joints leaves its range of motion
(:meth:`YieldCommand.brake_outside`): the estimate reads the end stop's torque
as a cuff force, and fed back it drove the knee on into its stop (``--preset
clinic-bws --controller qp --cuff-force-limit 200,120 --sync off`` with the
spastic patient at 50 % support: the estimated thigh force past 220 N, the
true one below 30 N).  Other stops (limits, faults, the e-stop) yield
without it, since a fault in a torque sensor would be fed back to the drives.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..estimation.cuff_geometry import CuffGeometry
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES, BodyModel
from ..plant import MotorParams
from ..plant.motor import drive_model, steady_voltage

__all__ = [
    "MAX_FORCE_GAIN",
    "PATIENT_ACCELERATION_RAD_S2",
    "SPEED_FILTER_HZ",
    "YIELD_FORCE_SHARE",
    "YieldCommand",
]

#: Share σ of a cuff's force limit the yield's damping may take at the
#: joint's speed limit (module docstring).
YIELD_FORCE_SHARE = 0.5

#: Cut-off of the yield's speed filter on the encoder difference [Hz].
SPEED_FILTER_HZ = 150.0

#: q̈_p, the largest joint acceleration of a patient in charge [rad/s²]: the
#: healthy active patient in ``transparent`` reached 32 rad/s² at the hips and
#: 46 rad/s² at the knees (true, 5 ms means; rounded up); sets the yield's ramp
#: and its force feedback's gain.
PATIENT_ACCELERATION_RAD_S2 = 50.0

#: K_max, the force feedback's largest gain [-]: the force-feedback gain the
#: interaction modes run on the live estimate (``guidance`` with either
#: estimator, ``transparent`` with the momentum observer;
#: :data:`~exo_ctrl.control.modes.params.FORCE_GAINS`).
MAX_FORCE_GAIN = 10.0


class YieldCommand:
    """The yield's command U_y (module docstring), on the device's models.

    Args:
        exo: the exoskeleton model the device holds.
        patient: the nominal patient model (None: the exoskeleton alone).
        motor: the drive's datasheet.
        damping: d_y per joint [N·m·s/rad], (4,).
        speed_limit: ω_max per joint [rad/s], (4,) (the speed estimate's clip).
        dt: control period Δt [s].

    Attributes:
        speed: the filtered speed ω̂ [rad/s], (4,).
        torque: the last τ_y [N·m], (4,).
        force_gain: K per joint in this stop [-], (4,) (zero: no force feedback).

    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel | None,
        motor: MotorParams,
        damping: np.ndarray,
        speed_limit: np.ndarray,
        dt: float,
    ) -> None:
        self.damping = np.array(damping, dtype=float)
        if self.damping.shape != (4,) or not np.all(np.isfinite(self.damping)):
            raise InvalidParameter("yield_damping", damping, "4 finite numbers >= 0 [N·m·s/rad]")
        if np.any(self.damping < 0.0):
            raise InvalidParameter("yield_damping", damping, "4 finite numbers >= 0 [N·m·s/rad]")
        self._bodies = []
        for body in (exo, patient):
            if body is not None:
                model = pin.Model(body.model)
                self._bodies.append((model, model.createData(), body, np.zeros(model.nq)))
        # The patient model's inertias, and per joint its subtree (the segments it carries).
        ids = () if patient is None else patient.joint_ids
        self._patient = self._bodies[1] if patient is not None else None
        self._inertias = [] if patient is None else [i.copy() for i in patient.model.inertias]
        self._carried = [[] if patient is None else _subtree(patient.model, i) for i in ids]
        self._drive = drive_model(motor)
        #: D_b, the short-circuit brake's damping i_G k_m (i_G/k_E)/R [N·m·s/rad]
        #: (:meth:`brake_outside`).
        self.brake_damping = (
            motor.torque_per_amp_Nm_per_A * motor.back_emf_V_per_rad_s / motor.resistance_ohm
        )
        self._limit = np.array(speed_limit, dtype=float)
        #: T_y, the ramp to the yield [s]: min over the joints of
        #: 4 d_y ω_max / (D q̈_p) (module docstring, "The ramp").
        self.ramp_s = float(
            np.min(4.0 * self.damping * self._limit)
            / (self.brake_damping * PATIENT_ACCELERATION_RAD_S2)
        )
        self._dt = dt
        self._alpha = 1.0 - math.exp(-2.0 * math.pi * SPEED_FILTER_HZ * dt)
        self.speed = np.zeros(4)
        self.torque = np.zeros(4)
        self._q_prev = np.zeros(4)
        #: The joints that left their range of motion in this yield (:meth:`brake_outside`).
        self.braked = np.zeros(4, dtype=bool)
        self._geometry = CuffGeometry.from_body(exo)  # the device's cuff levers
        self._arms = self._geometry.joint_arms()
        self._rotor = motor.reflected_inertia_kgm2
        self.force_gain = np.zeros(4)

    def stand(self) -> None:
        """The patient stands on the belt at a stop: U_y carries the exoskeleton alone.

        Module docstring, "The patient's feet on the belt".
        """
        del self._bodies[1:]

    def start(self, q: np.ndarray, dq: np.ndarray, force_limit_N: np.ndarray | None = None) -> None:
        """Start the speed filter at the stop: ω̂ from the speed reading, q_{k−1} = q.

        ``force_limit_N``: the bound F_c per cuff [N], (4,) CUFF_NAMES order, that the
        force feedback's gain K is set from (module docstring); None: no feedback.
        """
        self.force_gain[:] = 0.0 if force_limit_N is None else self.gains(q, force_limit_N)
        self.speed[:] = np.where(np.isfinite(dq), dq, 0.0)
        np.clip(self.speed, -self._limit, self._limit, out=self.speed)
        self._q_prev[:] = q
        self.braked[:] = False
        if self._patient is not None:  # the patient's segments all carried again
            for i, inertia in enumerate(self._inertias):
                self._patient[0].inertias[i] = inertia

    def gains(self, q: np.ndarray, force_limit_N: np.ndarray) -> np.ndarray:
        """K per joint at posture q [rad] for the cuff bounds F [N], (4,) (module docstring).

        The joint j's cuff is cuff j in CUFF_NAMES order (hip: thigh, knee: shank).
        """
        model, data, body, qm = self._bodies[0]  # the exoskeleton
        qm[body.q_index] = np.where(np.isfinite(q), q, 0.0)
        inertia = pin.crba(model, data, qm).diagonal()[body.q_index] + self._rotor
        share = (1.0 - YIELD_FORCE_SHARE) * np.asarray(force_limit_N, dtype=float)
        gain = inertia * PATIENT_ACCELERATION_RAD_S2 / (self._arms * share) - 1.0
        return np.clip(gain, 0.0, MAX_FORCE_GAIN)

    @property
    def posture(self) -> np.ndarray:
        """The last finite angle reading per joint [rad], (4,) (a view, do not modify)."""
        return self._q_prev

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """g_exo(q) + g_patient(q), the device's models [N·m], (4,) JOINT_NAMES order."""
        tau = np.zeros(4)
        for model, data, body, qm in self._bodies:
            qm[body.q_index] = q
            tau += pin.computeGeneralizedGravity(model, data, qm)[body.q_index]
        return tau

    def command(
        self, q: np.ndarray, out: np.ndarray, cuff_force: np.ndarray | None = None
    ) -> np.ndarray:
        """Advance ω̂ by this tick's reading q [rad] and write U_y into ``out`` [V].

        A joint whose reading is not finite keeps its last speed and posture.
        ``cuff_force``: the estimated cuff forces on the exoskeleton (x, z) [N], (4, 2),
        fed back with :attr:`force_gain` (None, or one not finite: this tick without).
        """
        ok = np.isfinite(q)
        diff = np.where(ok, (q - self._q_prev) / self._dt, self.speed)
        self.speed += self._alpha * (diff - self.speed)
        np.clip(self.speed, -self._limit, self._limit, out=self.speed)
        self._q_prev[ok] = q[ok]
        tau = self.gravity(self._q_prev)
        tau -= self.damping * self.speed
        if cuff_force is not None and self.force_gain.any() and np.all(np.isfinite(cuff_force)):
            tau += self.force_gain * self._geometry.joint_torques(self._q_prev, cuff_force)
        self.torque[:] = tau
        for j in range(4):
            out[j] = steady_voltage(tau[j], self.speed[j], self._drive)
        return out

    def brake_outside(
        self, q: np.ndarray, q_lower: np.ndarray, q_upper: np.ndarray, out: np.ndarray
    ) -> list[tuple[str, float, float, str]]:
        """Brake the joints outside [q_lower, q_upper] [rad] against moving further out.

        On such a joint τ_y gains −D_b ω̂_out, ω̂_out the outward part of its
        speed (max(ω̂, 0) above the range, min(ω̂, 0) below), D_b = i_G k_m
        (i_G/k_E)/R the short-circuit brake's damping (the power cut's, on
        that joint and in that direction alone), and its voltage in ``out``
        is rewritten: it is driven further out no faster than τ/D_b, comes
        back freely, and the other joints keep yielding (module docstring).
        Its leg's force feedback ends for this stop: the device's estimate
        reads the mechanical end stop's torque as a cuff force.

        Returns:
            The breaches of the joints out of their range for the first time
            in this yield: (quantity, value [rad], limit [rad], message) each.

        """
        new = []
        for j in range(4):
            lim = q_upper[j] if q[j] > q_upper[j] else (q_lower[j] if q[j] < q_lower[j] else None)
            if lim is None:
                continue
            w = self.speed[j]
            outward = max(w, 0.0) if q[j] > q_upper[j] else min(w, 0.0)
            out[j] = steady_voltage(self.torque[j] - self.brake_damping * outward, w, self._drive)
            if not self.braked[j]:
                self.braked[j] = True
                self._drop(j)
                self.force_gain[j - j % 2 : j - j % 2 + 2] = 0.0  # its leg: no feedback
                v, name = float(q[j]), JOINT_NAMES[j]
                message = (
                    f"yield: {name} at {v:.4g} rad, outside [{q_lower[j]:.4g}, "
                    f"{q_upper[j]:.4g}]: braked outward, its patient segments no longer "
                    "carried, the other joints still yield"
                )
                new.append((f"yield angle {name}", v, float(lim), message))
        return new

    def _drop(self, j: int) -> None:
        """Stop carrying the patient segments joint j carries (their mass to zero in the model)."""
        if self._patient is not None:
            for i in self._carried[j]:
                self._patient[0].inertias[i] = pin.Inertia.Zero()


def _subtree(model: pin.Model, joint_id: int) -> list[int]:
    """The joints of ``model`` at or below ``joint_id``: the bodies that joint carries."""
    out = []
    for i in range(1, model.njoints):
        k = i
        while k not in (0, joint_id):
            k = model.parents[k]
        if k == joint_id:
            out.append(i)
    return out
