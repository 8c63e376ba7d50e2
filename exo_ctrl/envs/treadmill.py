"""The Gymnasium environment: the device walking a patient on the treadmill, one step at a time.

:class:`TreadmillEnv` runs a scenario's closed loop with the environment's
action as the command (:mod:`.command`): the sensors, the estimator, the
drives, the current loop and the safety supervisor are the run's own, on
the one tick path of :func:`~exo_ctrl.sim.simulate`.  One step holds the
action over ``control_rate``'s period, the scenario's ticks in it; the
observation (:mod:`.observation`) is what the device measures before the
next step's first tick; the reward (:mod:`.reward`) is minus a weighted sum
of tracking error, interaction force and electrical energy over the step.

An episode ends with ``terminated=True`` at the tick the supervisor stops
the device (``info["status"] == "stopped"``) or if the plant diverges
(``"diverged"``), and with ``truncated=True`` after the scenario's last tick
(``"ended"``).
"""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from .. import _validate as v
from .._jit import kernel
from ..control import controller_name
from ..exceptions import InvalidParameter
from ..model import load_exo
from ..record import RerunRecorder
from ..scenario import PRESETS, Scenario, load_scenario
from ..sim import CONTROLLERS, SimConfig, drive_for
from .command import ResidualController, action_controller
from .episode import Episode
from .observation import OBSERVATION_NAMES, observe
from .patients import cohort_config
from .reward import REWARD_TERMS, RewardWeights

__all__ = ["ACTIONS", "TreadmillEnv"]

#: What an action is: drive voltages [V], joint torques [N·m] (through the driver's
#: current loop), or a residual [V] added to the scenario's built-in controller's voltages.
ACTIONS = ("torque", "voltage", "residual")

#: The controllers a residual action is added to.
RESIDUAL_ON = "a built-in one (pd, ct or qp) for residual actions"

#: What ``scenario`` may be, in words (the message of a bad one).
SCENARIO_ALLOWED = (
    f"a preset name ({', '.join(PRESETS)}), a scenario file's path, a Scenario or a SimConfig"
)


def scenario_config(scenario: object) -> SimConfig:
    """The run a ``scenario`` argument describes (None: the ``paper`` preset).

    Raises:
        InvalidParameter: not one of :data:`SCENARIO_ALLOWED`.
        InvalidScenario: a file that cannot be read (:func:`~exo_ctrl.scenario.load_scenario`).

    """
    if scenario is None:
        return load_scenario(preset="paper").config
    if isinstance(scenario, SimConfig):
        return scenario
    if isinstance(scenario, Scenario):
        return scenario.config
    if isinstance(scenario, str) and scenario in PRESETS:
        return load_scenario(preset=scenario).config
    if isinstance(scenario, (str, os.PathLike)):
        if not Path(scenario).is_file():
            raise InvalidParameter("scenario", scenario, SCENARIO_ALLOWED, "no such file or preset")
        return load_scenario(scenario).config
    raise InvalidParameter("scenario", scenario, SCENARIO_ALLOWED)


class TreadmillEnv(gym.Env):
    """The exoskeleton on the treadmill as a Gymnasium environment (module docstring).

    Args:
        scenario: the run (:func:`scenario_config`; default the ``paper`` preset).
        action: one of :data:`ACTIONS`.  ``"residual"`` needs the scenario's
            controller to be a built-in one (pd, ct, qp).
        control_rate: the steps' rate [Hz], the scenario's control rate
            divided by a whole number of ticks per step (None: one tick a step).
        duration_s: the episode's longest span [s] (None: the scenario's).
        reward_weights: the reward's weights (:class:`~.reward.RewardWeights`).
        cohort: draw a patient at each reset (:mod:`.patients`).
        record_dir: write each episode to ``<record_dir>/episode_<n>.rrd``
            (a rerun recording, :func:`~exo_ctrl.read_recording` reads it); None: none.
        render_mode: None (the recording is the way to see an episode).

    Attributes:
        config: the scenario's run (the drawn patient's, after a reset with ``cohort``).
        ticks_per_step: the scenario's control ticks per step.
        episode: the running episode (None before the first reset).
        observation_names: the observation's components (:data:`~.observation.OBSERVATION_NAMES`).

    Raises:
        InvalidParameter: a bad argument, naming it, its value and what is allowed.

    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(
        self,
        scenario: str | os.PathLike[str] | Scenario | SimConfig | None = None,
        action: str = "torque",
        control_rate: float | None = None,
        duration_s: float | None = None,
        reward_weights: RewardWeights | None = None,
        cohort: bool = False,
        record_dir: str | os.PathLike[str] | None = None,
        render_mode: str | None = None,
    ) -> None:
        super().__init__()
        v.one_of("action", action, ACTIONS)
        config = scenario_config(scenario)
        if duration_s is not None:
            duration_s = v.positive("duration_s", duration_s, "s")
            config = dataclasses.replace(config, duration_s=duration_s)
        name = controller_name(config.controller)  # a PD or CT object: "pd", "ct"
        if action == "residual" and name not in CONTROLLERS:
            raise InvalidParameter("the scenario's controller", name, RESIDUAL_ON)
        self.ticks_per_step = _ticks_per_step(control_rate, config.control_rate_hz)
        if reward_weights is None:
            reward_weights = RewardWeights()
        elif not isinstance(reward_weights, RewardWeights):
            raise InvalidParameter("reward_weights", reward_weights, "a RewardWeights or None")
        if render_mode is not None:
            raise InvalidParameter("render_mode", render_mode, "None (record_dir records episodes)")
        self.render_mode = render_mode
        self.action_kind = action
        self.weights = reward_weights
        self.cohort = v.flag("cohort", cohort)
        self.record_dir = None if record_dir is None else Path(record_dir)
        if self.record_dir is not None and not self.record_dir.is_dir():
            raise InvalidParameter("record_dir", record_dir, "an existing directory or None")
        self.scenario_config = config
        self.config = config
        if action != "residual":  # the env's own plug-in controller, set up by each run
            self._controller = action_controller(action)
            self.scenario_config = dataclasses.replace(config, controller=self._controller)
        self.action_space = _action_space(action, config)
        self._bounds = np.stack([self.action_space.low, self.action_space.high])
        self._weights = reward_weights.vector
        n = len(OBSERVATION_NAMES)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (n,), np.float32)
        self.observation_names = OBSERVATION_NAMES
        self.episode: Episode | None = None
        self.episodes = 0
        self._obs = np.zeros(n, dtype=np.float32)
        self._pending: np.ndarray = np.zeros(4)
        self._folder: Path | None = None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode: the scenario's run (on a drawn patient with ``cohort``).

        Args:
            seed: seeds the environment's generator (the sensors' noise and
                the drawn patient follow it); None: go on with it.
            options: ``{"cohort": bool}`` overrides the constructor's choice
                for this episode.

        Returns:
            The first observation and the info (``"t_s"``, ``"tick"``, ``"patient"``).

        """
        super().reset(seed=seed)
        self._end("the next episode started")
        options = options or {}
        unknown = set(options) - {"cohort"}
        if unknown:
            raise InvalidParameter("options", options, "a dict with at most the key 'cohort'")
        cohort = v.flag("options['cohort']", options.get("cohort", self.cohort))
        rng = self.np_random
        seeds = [int(s) for s in rng.integers(0, 2**31 - 1, size=3)]
        base = self.scenario_config
        config = dataclasses.replace(
            base,
            sensors=dataclasses.replace(base.sensors, seed=seeds[0]),
            current_sensor=dataclasses.replace(base.current_sensor, seed=seeds[1]),
            foot_load=dataclasses.replace(base.foot_load, seed=seeds[2]),
        )
        if cohort:
            config = cohort_config(config, rng, self._patients_folder(), f"{self.episodes:05d}")
        self.config = config
        observers = []
        if self.record_dir is not None:
            path = self.record_dir / f"episode_{self.episodes:04d}.rrd"
            observers.append(RerunRecorder(path, write_behind=False))
        wrap = None
        if self.action_kind == "residual":
            wrap = self._wrap
        else:
            self._pending = self._controller.pending
            self._pending[:] = 0.0
        self.episode = Episode(config, observers, wrap)
        self.episodes += 1
        info = self._info(np.zeros(3))
        info["patient"] = config.patient
        return observe(self.episode, self._obs).copy(), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Hold ``action`` over the step's ticks (clipped to the action space, then by the drives).

        Returns:
            observation, reward, terminated (a safety stop or a divergence),
            truncated (the scenario's last tick done), info (``"t_s"``,
            ``"tick"``, ``"status"``, ``"safety_state"``, ``"reward_terms"``
            by :data:`~.reward.REWARD_TERMS`).

        Raises:
            InvalidParameter: an action that is not four finite numbers, or
                a step before :meth:`reset` or after the episode ended.

        """
        episode = self.episode
        if episode is None or episode.status != "running":
            when = "before reset()" if episode is None else f"after the episode {episode.status}"
            raise InvalidParameter("step()", when, "called between reset() and the episode's end")
        a = action
        if not (type(a) is np.ndarray and a.dtype == np.float64):
            try:
                a = np.asarray(action, dtype=np.float64)
            except (TypeError, ValueError):
                a = np.full(1, np.nan)
        if a.shape != (4,) or not clip_action(a, self._bounds, self._pending):
            shown = a.tolist() if a.shape == (4,) else action
            detail = f"shape {a.shape}" if a.shape != (4,) else ""
            raise InvalidParameter("action", shown, "4 finite numbers", detail)
        terms = episode.advance(self.ticks_per_step)
        reward = -float(self._weights @ terms)
        status = episode.status
        terminated = status == "stopped" or status == "diverged"
        truncated = status == "ended"
        if terminated or truncated:
            self._end(f"the episode {status} at tick {episode.k}")
        if status != "diverged":
            observe(episode, self._obs)
        return self._obs.copy(), reward, terminated, truncated, self._info(terms)

    def close(self) -> None:
        """End the running episode (its recording written) and remove the drawn patients' files."""
        self._end("the environment was closed")
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None
        super().close()

    def _end(self, reason: str) -> None:
        """Close the running episode once (its observers finish)."""
        if self.episode is not None:
            self.episode.close(reason)

    def _wrap(self, controller: Any) -> ResidualController:
        """The residual wrapper of an episode's built-in controller; its residual is the action."""
        wrapped = ResidualController(controller)
        self._pending = wrapped.pending
        return wrapped

    def _patients_folder(self) -> Path:
        """A temporary folder for the drawn patients' URDFs (removed by :meth:`close`)."""
        if self._folder is None:
            self._folder = Path(tempfile.mkdtemp(prefix="exo_ctrl_env_"))
        return self._folder

    def _info(self, terms: np.ndarray) -> dict[str, Any]:
        """The step's info (:meth:`step`)."""
        episode = self.episode
        sup = episode.runner.supervisor
        return {
            "t_s": episode.k * self.config.dt,
            "tick": episode.k,
            "status": episode.status,
            "safety_state": sup.state if sup is not None else "normal",
            "reward_terms": dict(zip(REWARD_TERMS, terms.tolist(), strict=True)),
        }


@kernel
def clip_action(action, bounds, out):  # pragma: no cover - compiled
    """``action`` clipped to [bounds[0], bounds[1]] into ``out`` if all 4 are finite; whether."""
    for j in range(4):
        if not math.isfinite(action[j]):
            return False
    for j in range(4):
        out[j] = min(max(action[j], bounds[0, j]), bounds[1, j])
    return True


def _ticks_per_step(control_rate: float | None, tick_rate_hz: float) -> int:
    """The scenario's ticks per step at ``control_rate`` [Hz] (None: one).

    Raises:
        InvalidParameter: not the tick rate over a whole number >= 1.

    """
    if control_rate is None:
        return 1
    allowed = f"the scenario's control rate {tick_rate_hz:g} Hz divided by a whole number >= 1"
    rate = v.positive("control_rate", control_rate, "Hz")
    n = tick_rate_hz / rate
    whole = round(n)
    if whole < 1 or not math.isclose(n, whole, rel_tol=1e-9):
        raise InvalidParameter("control_rate", control_rate, allowed)
    return whole


def _action_space(action: str, config: SimConfig) -> gym.spaces.Box:
    """The action's box: ± the supply voltage [V], or ± the drives' peak torque [N·m]."""
    if action == "torque":
        limit = drive_for(config.motor, load_exo(config.exo)).peak_torque_Nm
    else:
        limit = config.motor.supply_voltage_V
    return gym.spaces.Box(-limit, limit, (4,), np.float64)
