"""Per-component honesty of the cuff-force estimate, on a fair belief (issue 31, item 3).

- the per-component figures of the summary (normal and along-link RMS error
  over the RMS true component, after the ramp-in) and the logged per-tick
  errors, against numpy from the run's own log, the link directions rebuilt
  from Pinocchio's frames (no code of exo_ctrl.estimation);
- the same figures read back from the recording;
- the goal with joint torque sensors alone on the default scenario (the
  ``paper`` preset with CT), and for the patients of seeds 1–5: normal
  components within 5 % (shanks) and 10 % (thighs) of their RMS — the user's
  numbers (with the knee 2 cm off it does not hold: docs/performance.md);
- which components the default sensor set observes
  (``cuff_force_estimate_components``);
- the device's default cuff model is the published one, and the truth's are
  the patient's scattered cuffs, not the published ones.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.cli.common import format_summary
from exo_ctrl.model import CUFF_NAMES, load_exo
from exo_ctrl.plant import CuffParams
from exo_ctrl.plant.cuff_scatter import CuffScatter
from exo_ctrl.record import RerunRecorder, read_recording
from exo_ctrl.scenario import preset
from exo_ctrl.sim import SimConfig, build, simulate

#: The user's goals (issue 31, item 3): normal component's RMS error over its RMS.
SHANK_GOAL, THIGH_GOAL = 0.05, 0.10


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    """The default scenario (preset ``paper``, CT), recorded."""
    config = dataclasses.replace(preset("paper").config, controller="ct")
    path = tmp_path_factory.mktemp("components") / "run.rrd"
    result = simulate(config, observers=[RerunRecorder(path)])
    assert result.status == "completed"
    return config, result, path


def directions(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """u (joint → cuff of the exo link) and n (u turned by +90°) per row and cuff, from frames."""
    exo = load_exo()
    model, data = exo.model, exo.model.createData()
    u = np.zeros((q.shape[0], 4, 2))
    joint_of = {"thigh": "hip", "shank": "knee"}
    for k in range(q.shape[0]):
        pin.framesForwardKinematics(model, data, q[k])
        for c, cuff in enumerate(CUFF_NAMES):
            side, link = cuff.split("_")
            at = data.oMf[model.getFrameId(f"{cuff}_cuff")].translation
            joint = data.oMi[model.getJointId(f"{side}_{joint_of[link]}")].translation
            d = (at - joint)[[0, 2]]
            u[k, c] = d / np.linalg.norm(d)
    return u, np.stack((-u[..., 1], u[..., 0]), axis=-1)


def test_per_component_errors_are_the_numpy_figures_of_the_log(default_run) -> None:
    """Estimate of row k against the true force of row k − 1, at row k's angles."""
    config, result, _ = default_run
    s = result.signals
    u, n = directions(s["q"])
    truth, est = s["cuff_force"][:-1], s["cuff_force_est"][1:]
    u, n = u[1:], n[1:]
    e_normal = s["cuff_normal_est"][1:] - np.sum(n * truth, axis=-1)
    e_along = np.sum(u * (est - truth), axis=-1)
    # The logged per-tick errors (row 0 has no truth: 0).
    np.testing.assert_allclose(s["cuff_normal_est_error"][1:], e_normal, atol=1e-9)
    np.testing.assert_allclose(s["cuff_along_est_error"][1:], e_along, atol=1e-9)
    assert np.all(s["cuff_normal_est_error"][0] == 0.0)
    # After the ramp-in (one gait period by default): rows from round(T_r / Δt) on.
    first = round(config.gait.period / config.dt)
    summary = result.summary()
    assert summary["cuff_force_estimate_components_from_s"] == pytest.approx(config.gait.period)
    rows = slice(first - 1, None)  # e_* row i is the log's row i + 1
    rms = lambda x: np.sqrt(np.mean(x[rows] ** 2, axis=0))  # noqa: E731
    normal_rel = rms(e_normal) / rms(np.sum(n * truth, axis=-1))
    along_true = rms(np.sum(u * truth, axis=-1))
    for c, cuff in enumerate(CUFF_NAMES):
        got = summary["cuff_force_estimate_normal_rms_error_over_rms"][cuff]
        assert got == pytest.approx(normal_rel[c], rel=1e-9)
        assert summary["cuff_force_estimate_along_rms_error_N"][cuff] == pytest.approx(
            rms(e_along)[c], rel=1e-9
        )
        along = summary["cuff_force_estimate_along_rms_error_over_rms"][cuff]
        if along_true[c] < 1.0:  # the thighs' along force: no lever arm, under 1 N
            assert along is None
        else:
            assert along == pytest.approx(rms(e_along)[c] / along_true[c], rel=1e-9)


def test_the_recording_carries_the_figures_and_the_per_tick_errors(default_run) -> None:
    _, result, path = default_run
    back = read_recording(path)
    for name in ("cuff_normal_est_error", "cuff_along_est_error"):
        np.testing.assert_array_equal(back.signals[name], result.signals[name])
    live, read = result.summary(), back.summary()
    for key in (
        "cuff_force_estimate_normal_rms_error_over_rms",
        "cuff_force_estimate_along_rms_error_over_rms",
        "cuff_force_estimate_components_from_s",
        "cuff_force_estimate_components",
    ):
        assert read[key] == live[key], key


def test_the_goal_with_joint_torque_sensors_alone_holds_on_the_default_scenario(
    default_run,
) -> None:
    """Measured: thighs 2.5–2.6 %, shanks 4.0–4.2 % (seed 0's patient)."""
    _, result, _ = default_run
    normal = result.summary()["cuff_force_estimate_normal_rms_error_over_rms"]
    shown = {c: round(100 * x, 2) for c, x in normal.items()}
    print("\nnormal RMS error / RMS true after the ramp-in [%]:", shown)
    for cuff, rel in normal.items():
        assert rel < (SHANK_GOAL if cuff.endswith("shank") else THIGH_GOAL), (cuff, rel)


@pytest.mark.parametrize("seed", range(1, 6))
def test_the_goal_holds_for_other_patients_cuffs(seed: int) -> None:
    """Seeds 1–5 (k_n × 0.84–1.08, k_u × 0.74–1.16): thighs 3.5–7.2 %, shanks 3.9–4.8 %."""
    config = dataclasses.replace(
        preset("paper").config, controller="ct", cuff_scatter=CuffScatter(seed=seed)
    )
    normal = simulate(config).summary()["cuff_force_estimate_normal_rms_error_over_rms"]
    for cuff, rel in normal.items():
        assert rel < (SHANK_GOAL if cuff.endswith("shank") else THIGH_GOAL), (seed, cuff, rel)


def test_the_default_sensor_set_observes_the_shanks_normal_force_only(default_run) -> None:
    _, result, _ = default_run
    summary = result.summary()
    components = summary["cuff_force_estimate_components"]
    assert set(components) == set(CUFF_NAMES)
    observed = {
        (cuff, part)
        for cuff, parts in components.items()
        for part, how in parts.items()
        if how.startswith("observed")
    }
    assert observed == {("left_shank", "normal"), ("right_shank", "normal")}
    assert components["left_shank"]["normal"] == "observed: the knee torque"
    assert "no joint torque sees it" in components["left_thigh"]["along"]
    text = format_summary(summary)
    assert (
        "observed by the joint torque sensors: left_shank normal, right_shank normal; "
        "every other component from models or assumptions"
    ) in text
    assert "cuff force estimate from t = 1.2 s, RMS error over RMS true, normal / along" in text


def test_the_device_holds_the_published_cuffs_and_the_patient_has_scattered_ones() -> None:
    config = SimConfig(duration_s=0.1)
    setup = build(config)
    assert config.belief.cuff_model_of(config.cuffs) == CuffParams()  # the published cuffs
    true = setup.plant.cuffs.params
    assert true == config.true_cuffs != CuffParams()
    f_n, f_u = config.cuff_scatter.factors()
    assert true.stiffness_N_per_m == pytest.approx(f_n * 8000.0, rel=1e-15)
    assert true.shear_stiffness_N_per_m == pytest.approx(f_u * 3700.0, rel=1e-15)
    summary = simulate(config).summary()
    assert summary["device_belief"]["cuffs"] == "published"
    assert summary["true_cuffs"]["normal_factor"] == f_n
    assert summary["true_cuffs"]["shear_stiffness_N_per_m"] == pytest.approx(f_u * 3700.0)
