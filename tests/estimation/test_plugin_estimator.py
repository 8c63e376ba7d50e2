"""A user's estimator on the public interface: used by the supervisor and the QP, logged,
its external torques consistent with its forces, its errors clear."""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl import SimConfig, simulate
from exo_ctrl.estimation import Estimator, EstimatorDevice, PluginEstimator
from exo_ctrl.exceptions import InvalidParameter, PluginError
from exo_ctrl.sensing import SensorReadings
from exo_ctrl.sim.setup import build


class Fixed(Estimator):
    """A constant estimate: ``force_N`` (4, 2) [N], from ``from_s`` [s] on (zero before)."""

    def __init__(self, force_N=None, from_s: float = 0.0) -> None:
        self.force_N = np.zeros((4, 2)) if force_N is None else np.asarray(force_N, float)
        self.from_s = from_s
        self.setups = 0

    def setup(self, device: EstimatorDevice) -> None:
        self.setups += 1
        self.dt_s = device.dt_s

    def estimate(self, t_s, sensors):
        return self.force_N if t_s >= self.from_s - 1e-12 else np.zeros((4, 2))


class Echo(Estimator):
    """Whatever it is given to return."""

    out: object = None

    def estimate(self, t_s, sensors):
        return self.out


def shank_push(newtons: float) -> np.ndarray:
    """``newtons`` [N] along +x on the left shank cuff (the others zero), (4, 2)."""
    force = np.zeros((4, 2))
    force[1, 0] = newtons
    return force


def test_the_supervisor_stops_on_a_user_estimate_at_its_tick() -> None:
    mine = Fixed(shank_push(400.0), from_s=0.3)
    result = simulate(SimConfig(estimator=mine, duration_s=0.6))
    assert mine.setups == 1 and mine.dt_s == SimConfig().dt
    first = result.events[0]
    assert first["quantity"] == "estimated cuff force left_shank"
    assert first["t"] == pytest.approx(0.3)
    k = int(np.flatnonzero(result.signals["safety_state"])[0])
    assert k == 300  # the first tick the estimate is over the limit
    np.testing.assert_array_equal(result.signals["cuff_force_est"][k], shank_push(400.0))


def test_the_qp_takes_its_cuff_state_from_a_user_estimate() -> None:
    base = dict(controller="qp", duration_s=0.6, safety=False)
    quiet = simulate(SimConfig(estimator=Fixed(), **base))
    pushed = simulate(SimConfig(estimator=Fixed(shank_push(150.0), from_s=0.3), **base))
    before = slice(0, 300)
    np.testing.assert_array_equal(
        quiet.signals["voltage_cmd"][before], pushed.signals["voltage_cmd"][before]
    )
    after = np.abs(quiet.signals["voltage_cmd"][300:] - pushed.signals["voltage_cmd"][300:])
    assert after.max() > 0.5  # [V]: the estimate moved the QP's command


def test_the_log_and_the_summary_show_the_user_estimate() -> None:
    result = simulate(SimConfig(estimator=Fixed(shank_push(10.0)), duration_s=0.2))
    name = f"{__name__}:Fixed"
    summary = result.summary()
    assert summary["device_belief"]["estimator"] == name
    assert result.config.to_dict()["estimator"] == name
    said = f"the user's estimator {name}"
    assert summary["cuff_force_estimate_components"]["left_shank"] == {
        "normal": said,
        "along": said,
    }
    assert np.all(result.signals["cuff_force_est"] == shank_push(10.0))


def test_external_torques_are_the_forces_through_the_cuff_jacobians() -> None:
    """τ_ext = Σ J_cᵀ f_c: the momentum observer's forces explain its torques exactly."""
    run = simulate(SimConfig(estimator="momentum", duration_s=0.4))
    setup = build(SimConfig(duration_s=0.4))
    echo = Echo()
    adapter = PluginEstimator(echo, EstimatorDevice(setup.device_exo, setup.device_patient, 1e-3))
    for k in (100, 250, 399):
        echo.out = run.signals["cuff_force_est"][k]
        readings = SensorReadings(run.signals["q_meas"][k], np.zeros(4), np.zeros(4))
        adapter.step(k, readings)
        np.testing.assert_allclose(adapter.tau_ext, run.signals["tau_ext_est"][k], atol=1e-9)
        np.testing.assert_allclose(adapter.normal, run.signals["cuff_normal_est"][k], atol=1e-9)


@pytest.mark.parametrize(
    ("out", "message"),
    [
        (np.zeros(4), "estimate must return (4, 2) cuff forces [N]; got shape (4,)"),
        (
            np.array([[0.0, np.inf]] * 4),
            "estimate must return finite numbers; got [[0.0, inf], [0.0, inf], [0.0, inf], "
            "[0.0, inf]]",
        ),
    ],
)
def test_a_bad_estimate_stops_the_run_naming_the_tick(out, message) -> None:
    echo = Echo()
    echo.out = out
    with pytest.raises(PluginError) as info:
        simulate(SimConfig(estimator=echo, duration_s=0.05))
    assert str(info.value) == f"estimator {__name__}:Echo at tick 0 (t = 0 s): {message}"


def test_bad_estimators_are_refused_by_name() -> None:
    with pytest.raises(InvalidParameter) as info:
        SimConfig(estimator="ekf")
    assert str(info.value) == "estimator must be one of momentum, kalman; got 'ekf'"
    with pytest.raises(InvalidParameter) as info:
        SimConfig(estimator=Fixed)
    assert str(info.value).endswith("(Fixed is a class: give an object, Fixed())")
    with pytest.raises(InvalidParameter) as info:
        build(SimConfig(estimator="no_such_pkg.est:Mine", duration_s=0.01))
    assert str(info.value).endswith(
        "got 'no_such_pkg.est:Mine' (cannot import no_such_pkg.est: No module named 'no_such_pkg')"
    )
    with pytest.raises(InvalidParameter) as info:
        SimConfig(estimator=Fixed(), mode="transparent")
    assert str(info.value) == (
        "mode must be tracking with a user's estimator; got 'transparent' "
        "(a user's estimator runs in tracking mode)"
    )
