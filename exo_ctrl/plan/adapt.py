r"""How the gait adapts to the belt speed: step length and period for a speed v.

The paper's gait vector (s, h_s, H_s, k_v, T_s) ties the belt speed to the
step: v = s / (β T_s) (:mod:`exo_ctrl.plan.gait`).  When the belt speed
changes, the lift h_s, the hip height H_s, the shape coefficient k_v and the
duty factor β stay; step length and period follow the law

.. math::

    s(v) = \min\!\big(s_0 (v / v_0)^{a},\; s_{max}\big), \qquad
    T(v) = \frac{s(v)}{β v},

through the configured gait's own point (s_0, v_0 = s_0 / (β T_0)), with
a = 1/2: a speed-invariant **walk ratio** (step length over cadence).
Healthy adults keep their walk ratio nearly constant over slow to fast
walking (Sekiya & Nagasaki 1998, Gait & Posture 7: 225–227, 0.0064 m·min
per step in young adults; Grieve 1968's stride length ∝ √speed relation
is the same law), so with the cadence n = 2 / T (steps per second; two steps
a cycle)

.. math::

    \frac{s}{n} = \frac{s^2}{2 β v} = \frac{s_0^2}{2 β v_0}
    \quad\Longrightarrow\quad s ∝ \sqrt{v}.

The configured gait fixes the patient's own ratio (the default 0.35 m at
1.2 s: 0.0035 m·min per step, a patient's shorter step).  The cap s_max is
the longest step whose path (same h_s, H_s, k_v, β) stays within the leg's
reach and the joints' ranges of motion (:func:`max_step_length`); above the
speed where the law meets it the step stays at s_max and the cadence alone
rises.  The paths' shape in phase depends on k_v and β only, so the foot's
x scales with s and its z does not (nor does the hip's rise and fall, a
function of the phase, ``pelvis_excursion``: it is in the path checked):
reach and ranges are monotone in s and the cap is found by bisection.
What the drives can follow (the joint speeds grow as 1/T) is checked by
the run for each speed of a profile (:func:`exo_ctrl.sim.sync.check_profile`).

The phase rate is r(v) = 1 / T(v) = β v / s(v); its derivative in v (for
the planned accelerations) is (1 - a) r / v below the cap and r / v on it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v_
from ..exceptions import ExoCtrlError, InvalidParameter
from ..model import BodyModel
from .gait import GaitParams, GaitPlan
from .kinematics import plan_joints

__all__ = ["WALK_RATIO_EXPONENT", "SpeedAdaptation", "max_step_length"]

#: a of the law: s ∝ v^a at a constant walk ratio (module docstring).
WALK_RATIO_EXPONENT = 0.5

#: Samples per period of the reach and range check of :func:`max_step_length`.
_SAMPLES = 512


@dataclass(frozen=True)
class SpeedAdaptation:
    """The law s(v), T(v) of the module docstring.

    Attributes:
        reference: the configured gait: (s_0, T_0) and the h_s, H_s, k_v, β kept.
        max_step_m: s_max [m] (inf: no cap).
        exponent: a [-], in [0, 1].

    """

    reference: GaitParams
    max_step_m: float = math.inf
    exponent: float = WALK_RATIO_EXPONENT

    def __post_init__(self) -> None:
        a = v_.finite("exponent", self.exponent)
        if not 0.0 <= a <= 1.0:
            raise InvalidParameter("exponent", self.exponent, "in [0, 1]")
        if not self.max_step_m > 0.0:
            raise InvalidParameter("max_step", self.max_step_m, "> 0 m")

    def step_length(self, speed_mps: float) -> float:
        """s(v) [m]."""
        ref = self.reference
        s = ref.step_length * (speed_mps / ref.belt_speed) ** self.exponent
        return min(s, self.max_step_m)

    def capped(self, speed_mps: float) -> bool:
        """Whether the step is at its cap s_max at speed v."""
        ref = self.reference
        return ref.step_length * (speed_mps / ref.belt_speed) ** self.exponent >= self.max_step_m

    def period(self, speed_mps: float) -> float:
        """T(v) = s(v) / (β v) [s]."""
        return self.step_length(speed_mps) / (self.reference.duty_factor * speed_mps)

    def gait(self, speed_mps: float) -> GaitParams:
        """The configured gait with the step length and period of speed v [m/s].

        At the reference speed v_0 the configured gait itself (s(v_0) = s_0 and
        T(v_0) = T_0 exactly, not as rounded through the law).
        """
        if speed_mps == self.reference.belt_speed:
            return self.reference
        return dataclasses.replace(
            self.reference,
            step_length=self.step_length(speed_mps),
            period=self.period(speed_mps),
        )

    def kernel_params(self) -> np.ndarray:
        """(s_0 [m], v_0 [m/s], a, s_max [m], β) for the compiled generator."""
        ref = self.reference
        cap = self.max_step_m if math.isfinite(self.max_step_m) else 1e300
        return np.array(
            [ref.step_length, ref.belt_speed, self.exponent, cap, ref.duty_factor], dtype=float
        )


def max_step_length(gait: GaitParams, body: BodyModel, tol_m: float = 1e-5) -> float:
    """s_max: the longest step of ``gait``'s shape that ``body`` reaches within its ranges [m].

    Bisection on s between 0 and twice the leg's length, each trial the
    path of one period checked by :func:`~exo_ctrl.plan.kinematics.plan_joints`
    (reach, knee not straighter than its singular margin, URDF ranges of
    motion).

    Raises:
        ExoCtrlError: no step at all is reachable (the error of the shortest
            step tried: the belt or the lift out of the leg's reach).

    """

    def fits(step: float) -> ExoCtrlError | None:
        params = dataclasses.replace(gait, step_length=step)
        t = np.linspace(0.0, params.period, _SAMPLES, endpoint=False)
        try:
            plan_joints(GaitPlan(params), body, t)
        except ExoCtrlError as exc:
            return exc
        return None

    lo = tol_m
    error = fits(lo)
    if error is not None:
        raise error
    hi = 2.0 * min(leg.thigh_length + leg.shank_length for leg in body.legs.values())
    if fits(hi) is None:
        return hi
    while hi - lo > tol_m:
        mid = 0.5 * (lo + hi)
        if fits(mid) is None:
            lo = mid
        else:
            hi = mid
    return lo
