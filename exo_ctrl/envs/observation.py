"""What the environment observes: the device's measurements and the plan, one flat vector.

At each step the observation is what the device has before it commands the
step's first tick k (:meth:`~exo_ctrl.sim.tick.Runner.measure`): its
sensors' readings, the estimator's cuff forces, and the plan's row and phase.
Never the plant's truth.  In :data:`OBSERVATION_NAMES` order (joints in
:data:`~exo_ctrl.model.JOINT_NAMES` order, cuffs in
:data:`~exo_ctrl.model.CUFF_NAMES` order):

=================  ====  ========  ==================================================
block              size  unit      what
=================  ====  ========  ==================================================
``q``              4     rad       encoders
``dq``             4     rad/s     the encoders' speed
``tau``            4     N·m       joint torque sensors
``current``        4     A         the drives' current sensors
``belt_speed``     1     m/s       the belt's speed sensor (0 without the belt)
``foot_force``     4     N         the foot plates' load cells, (x, z) per foot (0 without the belt)
``cuff_force_est`` 8     N         the estimator's cuff forces, (x, z) per cuff
``q_plan``         4     rad       the plan's q* of tick k
``dq_plan``        4     rad/s     the plan's q̇* of tick k
``phase``          2     -         (sin 2πτ, cos 2πτ) of the left leg's gait phase τ
=================  ====  ========  ==================================================

The gait phase τ ∈ [0, 1) is the synchronised plan's own
(:mod:`exo_ctrl.plan.online`, which follows the belt) or, for a
precomputed plan, (t_k / T_s) mod 1.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from ..model import CUFF_NAMES, JOINT_NAMES
from .episode import Episode

__all__ = ["OBSERVATION_NAMES", "observe"]


def _names() -> tuple[str, ...]:
    """The observation's components, named with their units."""
    joints = JOINT_NAMES
    out = [f"{j}_q_rad" for j in joints]
    out += [f"{j}_dq_rad_s" for j in joints]
    out += [f"{j}_tau_Nm" for j in joints]
    out += [f"{j}_current_A" for j in joints]
    out += ["belt_speed_mps"]
    out += [f"{foot}_foot_force_{axis}_N" for foot in ("left", "right") for axis in "xz"]
    out += [f"{c}_cuff_force_est_{axis}_N" for c in CUFF_NAMES for axis in "xz"]
    out += [f"{j}_q_plan_rad" for j in joints]
    out += [f"{j}_dq_plan_rad_s" for j in joints]
    out += ["phase_sin", "phase_cos"]
    return tuple(out)


#: The observation's components in order, each named with its unit (module docstring).
OBSERVATION_NAMES = _names()


def observe(episode: Episode, out: np.ndarray) -> np.ndarray:
    """Fill ``out`` (float32, (len(OBSERVATION_NAMES),)) with tick ``episode.k``'s observation."""
    runner, s = episode.runner, episode.readings
    setup = runner.setup
    plan, k = setup.plan, episode.k
    online = setup.online
    if online is None:
        row = plan.row(k)
        tau = (k * episode.config.dt / episode.config.gait.period) % 1.0
    else:
        row = 0
        tau = float(online.record["phase"][0][0])
    belt = 0.0 if s.belt_speed is None else float(s.belt_speed[0])
    fill_observation(
        out,
        s.q,
        s.dq,
        s.tau,
        runner.current_sensor.current,
        belt,
        runner.foot_load.force,
        runner.estimator.force,
        plan.q[row],
        plan.dq[row],
        tau,
    )
    return out


@kernel
def fill_observation(out, q, dq, tau, current, belt, foot, est, q_plan, dq_plan, phase):
    """The observation's blocks (module docstring) into ``out``."""  # pragma: no cover
    for j in range(4):
        out[j] = q[j]
        out[4 + j] = dq[j]
        out[8 + j] = tau[j]
        out[12 + j] = current[j]
        out[29 + j] = q_plan[j]
        out[33 + j] = dq_plan[j]
    out[16] = belt
    for f in range(2):
        out[17 + 2 * f] = foot[f, 0]
        out[18 + 2 * f] = foot[f, 1]
    for c in range(4):
        out[21 + 2 * c] = est[c, 0]
        out[22 + 2 * c] = est[c, 1]
    out[37] = math.sin(2.0 * math.pi * phase)
    out[38] = math.cos(2.0 * math.pi * phase)
