"""The Gymnasium environment: its contract, its physics on the run's own tick, its errors."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from exo_ctrl import SimConfig, read_recording, simulate
from exo_ctrl.control import Controller
from exo_ctrl.envs import ENV_ID, OBSERVATION_NAMES, RewardWeights, TreadmillEnv
from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter

#: check_env's advice this environment declines, on purpose (docs/gym.md): actions in
#: physical units (volts, N·m), which the drives clip, and unbounded observations.
DECLINED = ("symmetric and normalized space", "minimum value is -infinity", "maximum value is")


def run_episode(env: TreadmillEnv, seed: int, policy_seed: int) -> tuple[float, dict, int]:
    """The return of one episode of uniform random actions; the last info; the steps."""
    env.reset(seed=seed)
    env.action_space.seed(policy_seed)
    total, steps = 0.0, 0
    while True:
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        total += reward
        steps += 1
        if terminated or truncated:
            return total, info, steps


def test_check_env_passes_and_the_id_is_registered() -> None:
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        env = gymnasium.make(ENV_ID, action="torque", duration_s=0.1)
        check_env(env.unwrapped)
        env.close()
    other = [str(w.message) for w in seen if not any(d in str(w.message) for d in DECLINED)]
    assert other == []
    assert env.unwrapped.observation_space.shape == (len(OBSERVATION_NAMES),) == (39,)


def test_a_seeded_episode_returns_the_same_and_another_seed_not() -> None:
    env = TreadmillEnv(action="residual", duration_s=0.3, control_rate=100.0)
    first = run_episode(env, seed=7, policy_seed=1)
    again = run_episode(env, seed=7, policy_seed=1)
    other = run_episode(env, seed=8, policy_seed=1)  # other sensor noise, same actions
    env.close()
    assert first[0] == again[0]
    assert first[2] == 30 and first[1]["status"] == "ended"  # truncated at the scenario's end
    assert other[0] != first[0]
    assert abs(other[0] - first[0]) < 0.05 * abs(first[0])  # the noise, not another run


def test_a_random_policy_ends_in_a_safety_stop_not_a_crash() -> None:
    env = TreadmillEnv(action="voltage", duration_s=3.0, control_rate=20.0)
    total, info, _ = run_episode(env, seed=0, policy_seed=0)
    events = env.episode.result.events
    env.close()
    assert info["status"] == "stopped" and info["safety_state"] != "normal"
    assert info["tick"] < 3000 and np.isfinite(total)
    # it stopped at the tick a limit was crossed: that tick is the episode's last
    violation = next(e for e in events if e["kind"] == "violation")
    assert abs(violation["value"]) > violation["limit"]
    assert violation["t"] == pytest.approx((info["tick"] - 1) * 1e-3)
    assert events[-1]["kind"] == "episode_end"


def test_zero_residual_is_the_built_in_run_tick_for_tick(tmp_path: Path) -> None:
    # the environment drives the run's own tick: with nothing added it is simulate()
    env = TreadmillEnv(action="residual", duration_s=0.2, record_dir=tmp_path)
    env.reset(seed=3)
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(4))
        done = terminated or truncated
    config = env.config
    env.close()
    recorded = read_recording(tmp_path / "episode_0000.rrd")
    reference = simulate(config)
    assert len(recorded.t) == info["tick"] == 200
    for name in ("q", "q_meas", "voltage_cmd", "current", "cuff_force_est"):
        np.testing.assert_array_equal(recorded.signals[name], reference.signals[name], name)


def residual_episode(folder: Path, amplitude_V: float) -> tuple[list, np.ndarray, dict, SimConfig]:
    """A recorded 0.25 s residual episode of uniform random residuals, ten ticks a step.

    Returns the rewards, the reward's terms per step, the plant's energy books and the run.
    """
    weights = RewardWeights(tracking=2e3, interaction=3e-4, energy=5e-2)
    env = TreadmillEnv(
        action="residual",
        duration_s=0.25,
        control_rate=100.0,
        record_dir=folder,
        reward_weights=weights,
    )
    env.reset(seed=4)
    rng = np.random.default_rng(0)
    rewards, terms = [], []
    done = False
    while not done:
        _, reward, terminated, truncated, info = env.step(rng.uniform(-1.0, 1.0, 4) * amplitude_V)
        rewards.append(reward)
        terms.append(list(info["reward_terms"].values()))
        done = terminated or truncated
    books = env.episode.runner.setup.plant.motors.energy(("a", "b", "c", "d"))["energy_J"]
    config = env.config
    env.close()
    return rewards, np.array(terms), books, config


def per_step(x: np.ndarray) -> np.ndarray:
    """Per-tick values summed over each step of ten ticks."""
    return x.reshape(-1, 10).sum(axis=1)


def test_the_reward_is_its_terms_from_the_logged_signals(tmp_path: Path) -> None:
    rewards, terms, books, config = residual_episode(tmp_path, 0.3)
    s = read_recording(tmp_path / "episode_0000.rrd").signals
    dt = 1e-3
    assert s["q"].shape[0] == 250 and terms.shape == (25, 3)
    track = per_step(((s["q_des"] - s["q"]) ** 2).sum(axis=1) * dt)
    force = per_step((s["cuff_force"] ** 2).sum(axis=(1, 2)) * dt)
    energy = per_step(np.clip(s["voltage"] * s["current"], 0.0, None).sum(axis=1) * dt)
    # the currents stay far from the driver's limit: the drives draw U Ī Δt per tick
    assert np.abs(s["current"]).max() < 0.8 * config.motor.current_limit_A
    np.testing.assert_allclose(terms, np.stack([track, force, energy], axis=1), rtol=1e-9)
    w = np.array([2e3, 3e-4, 5e-2])
    np.testing.assert_allclose(rewards, -(terms @ w), rtol=1e-12)
    drawn = sum(b["electrical"] + b["regenerated"] for b in books.values())
    assert terms[:, 2].sum() == pytest.approx(drawn, rel=1e-12)
    # the residual reached the drives: at tick 0 (the same state) the built-in PD's plus it
    builtin = simulate(dataclasses.replace(config, duration_s=0.001)).signals["voltage_cmd"][0]
    first = np.random.default_rng(0).uniform(-1.0, 1.0, 4) * 0.3
    np.testing.assert_allclose(s["voltage_cmd"][0], builtin + first, rtol=0, atol=1e-12)


def test_the_energy_term_is_what_the_drives_drew_at_their_current_limit(tmp_path: Path) -> None:
    # where the driver's current limit holds the current within a tick it lowers the
    # voltage: the drives draw less than the log's U Ī Δt; the plant's books say how much
    _, terms, books, config = residual_episode(tmp_path, 3.0)
    s = read_recording(tmp_path / "episode_0000.rrd").signals
    energy = per_step(np.clip(s["voltage"] * s["current"], 0.0, None).sum(axis=1) * 1e-3)
    limited = per_step(np.abs(s["current"]).max(axis=1) >= 0.999 * config.motor.current_limit_A)
    assert limited.any()
    assert np.all(terms[limited > 0, 2] < energy[limited > 0])
    assert np.all(terms[:, 2] <= energy * (1 + 1e-12))
    drawn = sum(b["electrical"] + b["regenerated"] for b in books.values())
    assert terms[:, 2].sum() == pytest.approx(drawn, rel=1e-12)


def test_a_voltage_action_is_the_drives_command_clipped_and_held(tmp_path: Path) -> None:
    env = TreadmillEnv(action="voltage", duration_s=0.02, control_rate=500.0, record_dir=tmp_path)
    env.reset(seed=0)
    actions = np.array([[1.5, -2.0, 0.25, 1e3], [-1e3, 0.0, 3.0, -4.0]] * 5)
    for a in actions:
        env.step(a)
    env.close()
    s = read_recording(tmp_path / "episode_0000.rrd").signals
    supply = env.config.motor.supply_voltage_V
    held = np.repeat(np.clip(actions, -supply, supply), 2, axis=0)  # two ticks a step
    np.testing.assert_array_equal(s["voltage_cmd"], held)
    np.testing.assert_array_equal(s["voltage"], held)  # the supply passes them all


def test_a_torque_action_never_draws_more_than_the_drivers_current_limit(tmp_path: Path) -> None:
    env = TreadmillEnv(action="torque", duration_s=1.0, control_rate=50.0, record_dir=tmp_path)
    run_episode(env, seed=2, policy_seed=2)
    limit = env.episode.runner.setup.plant.motor_params.current_limit_A
    env.close()
    cut = tmp_path / "episode_0000.partial.rrd"  # the random torques end it in a safety stop
    current = read_recording(cut).signals["current"]
    peak = float(np.abs(current).max())
    assert 0.5 * limit < peak <= limit * (1 + 1e-9)  # pushed to it, never beyond


def test_two_environments_step_in_an_async_vector_env() -> None:
    def make() -> TreadmillEnv:
        return TreadmillEnv(action="torque", duration_s=0.1)

    vec = gymnasium.vector.AsyncVectorEnv([make, make])
    try:
        obs, _ = vec.reset(seed=11)
        assert obs.shape == (2, 39) and obs.dtype == np.float32
        for _ in range(5):
            obs, reward, terminated, truncated, _ = vec.step(np.zeros((2, 4)))
        assert np.all(np.isfinite(obs)) and reward.shape == (2,)
        assert not terminated.any() and not truncated.any()
    finally:
        vec.close()
    single = make()  # env i of the vector was reset with seed 11 + i
    single.reset(seed=12)
    for _ in range(5):
        alone, r, *_ = single.step(np.zeros(4))
    single.close()
    np.testing.assert_array_equal(obs[1], alone)
    assert reward[1] == r
    assert not np.array_equal(obs[0], obs[1])  # their sensors' noise differs


def test_a_drawn_patient_follows_the_seed() -> None:
    env = TreadmillEnv(action="torque", duration_s=0.05, cohort=True)
    _, info = env.reset(seed=5)
    first = env.config
    env.reset(seed=5)
    same = env.config
    env.reset(seed=6, options={"cohort": True})
    other = env.config
    env.reset(seed=6, options={"cohort": False})
    plain = env.config
    env.step(np.zeros(4))
    env.close()
    assert Path(info["patient"]).name == "patient_00000.urdf"
    assert first.belief.patient_mass_kg == same.belief.patient_mass_kg
    assert first.misalignment == same.misalignment
    assert other.belief.patient_mass_kg != first.belief.patient_mass_kg
    assert 1.55 <= first.belief.patient_height_m <= 1.95
    assert plain.patient is None and plain.belief.patient_mass_kg is None


class _Mine(Controller):
    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.zeros(4)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"action": "force"}, "action must be one of torque, voltage, residual; got 'force'"),
        (
            {"control_rate": 300.0},
            "control_rate must be the scenario's control rate 1000 Hz divided by a whole "
            "number >= 1; got 300.0",
        ),
        ({"control_rate": 0.0}, "control_rate must be > 0 Hz; got 0.0"),
        (
            {"scenario": 42},
            "scenario must be a preset name (paper, paper-free-air, clinic-bws, clinic-spastic, "
            "spastic-qp, active-transparent, calibration), a scenario file's path, a Scenario or a "
            "SimConfig; got 42",
        ),
        (
            {"scenario": SimConfig(controller=_Mine()), "action": "residual"},
            "the scenario's controller must be a built-in one (pd, ct or qp) for residual "
            "actions; got 'test_treadmill_env:_Mine'",
        ),
        ({"duration_s": -1.0}, "duration_s must be > 0 s; got -1.0"),
        (
            {"reward_weights": (1, 2, 3)},
            "reward_weights must be a RewardWeights or None; got (1, 2, 3)",
        ),
        (
            {"record_dir": "/no/such"},
            "record_dir must be an existing directory or None; got '/no/such'",
        ),
        ({"cohort": "yes"}, "cohort must be True or False; got 'yes'"),
    ],
)
def test_bad_arguments_are_refused_by_name(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as caught:
        TreadmillEnv(**kwargs)
    assert str(caught.value).replace("tests.envs.", "") == message
    assert isinstance(caught.value, ExoCtrlError)


def test_bad_steps_and_weights_are_refused_by_name() -> None:
    message = r"^reward weight energy \[1/J\] must be >= 0; got -1.0$"
    with pytest.raises(InvalidParameter, match=message):
        RewardWeights(energy=-1.0)
    env = TreadmillEnv(scenario="paper-free-air", duration_s=0.002)
    messages = []
    for call in (
        lambda: env.step(np.zeros(4)),
        lambda: (env.reset(seed=0), env.step([0.0, 0.0, float("nan"), 0.0])),
        lambda: env.step(np.zeros(3)),
        lambda: env.reset(options={"patient": 1}),
        lambda: (env.reset(), env.step(np.zeros(4)), env.step(np.zeros(4)), env.step(np.zeros(4))),
    ):
        with pytest.raises(InvalidParameter) as caught:
            call()
        messages.append(str(caught.value))
    env.close()
    assert messages == [
        "step() must be called between reset() and the episode's end; got 'before reset()'",
        "action must be 4 finite numbers; got [0.0, 0.0, nan, 0.0]",
        "action must be 4 finite numbers; got array([0., 0., 0.]) (shape (3,))",
        "options must be a dict with at most the key 'cohort'; got {'patient': 1}",
        "step() must be called between reset() and the episode's end; "
        "got 'after the episode ended'",
    ]


def test_the_observation_is_what_the_device_measured(tmp_path: Path) -> None:
    env = TreadmillEnv(action="residual", duration_s=0.03, record_dir=tmp_path)
    obs, _ = env.reset(seed=9)
    seen = [obs]
    for _ in range(19):
        obs, *_ = env.step(np.zeros(4))
        seen.append(obs)
    env.close()  # 19 of 30 ticks: an episode cut short
    s = read_recording(tmp_path / "episode_0000.partial.rrd").signals
    seen = np.array(seen)[:19]  # the 20th observation's tick was never acted on, nor logged
    names = list(OBSERVATION_NAMES)
    q = names.index("left_hip_q_rad")
    est = names.index("left_thigh_cuff_force_est_x_N")
    plan = names.index("left_hip_q_plan_rad")
    belt = names.index("belt_speed_mps")
    as32 = lambda name: s[name].reshape(19, -1).astype(np.float32)  # noqa: E731
    np.testing.assert_array_equal(seen[:, q : q + 4], as32("q_meas"))
    np.testing.assert_array_equal(seen[:, est : est + 8], as32("cuff_force_est"))
    np.testing.assert_array_equal(seen[:, plan : plan + 4], as32("q_des"))
    np.testing.assert_array_equal(seen[:, belt], as32("belt_speed_meas")[:, 0])
    tau = names.index("left_hip_tau_Nm")
    np.testing.assert_array_equal(seen[:, tau : tau + 4], as32("tau_sensor"))
    assert dataclasses.asdict(env.config.sensors)["seed"] != 0  # drawn from the env's seed


def test_without_gymnasium_the_import_names_the_extra() -> None:
    code = (
        "import sys; sys.modules['gymnasium'] = None\n"
        "try:\n    import exo_ctrl.envs\n"
        "except Exception as e:\n    print(type(e).__name__, '|', e)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == (
        'MissingDependency | the Gymnasium environment needs gymnasium: pip install "exo-ctrl[gym]"'
    )


def test_an_episode_cut_short_is_recorded_as_interrupted_and_a_whole_one_completed(
    tmp_path: Path,
) -> None:
    env = TreadmillEnv(action="residual", duration_s=0.05, control_rate=200.0, record_dir=tmp_path)
    env.reset(seed=1)
    env.step(np.zeros(4))  # 1 of 10 steps (5 ticks of 1 ms), then the next episode starts
    env.reset(seed=1)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(4))
        done = terminated or truncated
    env.close()
    # a cut episode keeps the name of a run cut short (the recorder's rule)
    assert not (tmp_path / "episode_0000.rrd").exists()
    cut = read_recording(tmp_path / "episode_0000.partial.rrd")
    whole = read_recording(tmp_path / "episode_0001.rrd")
    assert cut.status == "interrupted" and len(cut.t) == 5
    assert cut.error == "ended after 5 of 50 ticks (t = 0.0050 s): the next episode started"
    assert whole.status == "completed" and not whole.error and len(whole.t) == 50
