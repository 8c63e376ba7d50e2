"""A run's synchronised plan: the online gait generator and the checks of its speeds.

With ``SimConfig.synced`` the plan is generated each tick from the belt
encoder's reading (:class:`~exo_ctrl.plan.online.OnlineGait`), the gait's
step and period following the belt speed by the law of
:mod:`exo_ctrl.plan.adapt`.  Before the run, every speed the session's
profile reaches is checked as the precomputed plan is
(:func:`check_profile`): the leg's reach and ranges of motion at the
adapted step, and the joint speeds against the URDF and drive limits
(:func:`~exo_ctrl.sim.setup.check_followable`).  A profile is piecewise
linear and step, period and joint speeds are monotone in the speed, so its
points are the extremes to check.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from ..exceptions import ExoCtrlError, InvalidParameter
from ..model import BodyModel
from ..plan import (
    GaitPlan,
    OnlineGait,
    Ramp,
    RampedGait,
    SpeedAdaptation,
    SpeedProfile,
    StanceSink,
    max_step_length,
    plan_joints,
)
from ..plant import MotorParams
from .config import SimConfig

__all__ = ["check_profile", "online_gait", "profile_runs", "set_speeds"]

#: Samples per gait period of each speed's check.
SAMPLES_PER_PERIOD = 1000


def online_gait(
    config: SimConfig,
    exo: BodyModel,
    patient: BodyModel,
    motor: MotorParams,
    device_exo: BodyModel,
    check: Callable[..., None],
    sink: StanceSink | None = None,
    start: bool = True,
) -> OnlineGait:
    """The run's online generator, its profile checked first.

    Args:
        config: the run (``synced``).
        exo: the true exoskeleton (reach, ranges and speed limits checked on it).
        patient: the true patient (its speed limits).
        motor: the drive as configured.
        device_exo: the device's exoskeleton model: the generator's kinematics.
        check: the check of a plan's joint speeds
            (:func:`~exo_ctrl.sim.setup.check_followable`).
        sink: the stance feet's loading sink (:mod:`exo_ctrl.plan.loading`), or None.
        start: False: neither checked nor started (the compile helper's build, which
            only needs the plan's record: :mod:`exo_ctrl.sim.warmup`).

    Raises:
        InvalidParameter: a profile speed the leg cannot reach or the drives
            cannot follow (:func:`check_profile`).

    """
    law = SpeedAdaptation(config.gait, max_step_length(config.gait, exo))
    if start:
        check_profile(config, law, exo, patient, motor, check, sink)
    dt, ramp_in = config.dt, config.ramp_in
    return OnlineGait(law, config.speed_profile, device_exo, dt, ramp_in, sink, start=start)


def check_profile(
    config: SimConfig,
    law: SpeedAdaptation,
    exo: BodyModel,
    patient: BodyModel,
    motor: MotorParams,
    check: Callable[..., None],
    sink: StanceSink | None = None,
) -> None:
    """Refuse a profile point whose adapted gait the leg or the drives cannot follow.

    Each point's speed v gets the law's gait (s(v), T(v)); its path over one
    period (and the ramp-in, for the speed at the start) is planned and
    checked as a precomputed plan is (``check``:
    :func:`~exo_ctrl.sim.setup.check_followable`, given by the caller).

    Raises:
        InvalidParameter: ``speed_profile``, naming the point's time and
            speed, the step and period it needs and the limit it breaks.

    """
    profile = config.speed_profile or SpeedProfile.constant(config.gait.belt_speed)
    for (t, speed), cfg in zip(_points(profile), profile_runs(config, law), strict=True):
        gait, ramp_in = cfg.gait, cfg.ramp_in_s
        span = ramp_in + gait.period
        n = max(math.ceil(SAMPLES_PER_PERIOD * span / gait.period), 2) + 1
        try:
            ramped = RampedGait(GaitPlan(gait, sink), Ramp(ramp_in))
            plan = plan_joints(ramped, exo, np.linspace(0.0, span, n))
            check(cfg, plan, exo, patient, motor)
        except ExoCtrlError as exc:
            cap = " (the longest the leg reaches)" if law.capped(speed) else ""
            raise InvalidParameter(
                "speed_profile",
                profile.text(),
                "speeds the leg reaches and the drives follow",
                f"at t = {t:g} s the belt speed {speed:g} m/s needs step_length "
                f"{gait.step_length:.4g} m{cap} and period {gait.period:.4g} s: {exc}",
            ) from None


def profile_runs(config: SimConfig, law: SpeedAdaptation) -> list[SimConfig]:
    """Each point of the session's profile (its start first) as a run on a precomputed plan.

    The point's speed v gets the law's gait (s(v), T(v)); the start keeps the
    run's ramp-in, the others none; each lasts the run's duration or one ramp
    and period, whichever is longer.  Planned as such a run is
    (:func:`~exo_ctrl.sim.setup.precomputed_plan`), a point's plan is the
    synchronised one at a steady speed v: what :func:`check_profile` checks and
    the QP's bound margin is computed along (:mod:`exo_ctrl.control.qp.margin`).
    """
    profile = config.speed_profile or SpeedProfile.constant(config.gait.belt_speed)
    runs = []
    for i, (_, speed) in enumerate(_points(profile)):
        gait = law.gait(speed)
        ramp_in = config.ramp_in if i == 0 else 0.0
        runs.append(
            dataclasses.replace(
                config,
                gait=gait,
                speed_profile=None,
                sync=False,
                ramp_in_s=ramp_in,
                duration_s=max(config.duration_s, ramp_in + gait.period),
                session=None,  # a profile point, not the session's run
            )
        )
    return runs


def _points(profile: SpeedProfile) -> list[tuple[float, float]]:
    """The profile's points (time [s], speed [m/s]), its start at t = 0 first."""
    start_speed = float(profile.at(0.0)[0][0])
    return [(0.0, start_speed), *zip(profile.times, profile.speeds, strict=True)]


def set_speeds(config: SimConfig, sigma: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The belt's set speed σ v(t) [m/s] and its rate σ̇ v + σ v̇ [m/s²] per tick, (n, 2).

    ``sigma``: σ(t_k) and σ̇(t_k) of the run's ramp; v(t) the profile's.
    """
    t = np.arange(config.n_ticks) * config.dt
    speed, rate = config.speed_profile.at(t)
    return np.stack((sigma[0] * speed, sigma[1] * speed + sigma[0] * rate), axis=1)
