"""The summary's list of the Kalman filter's model-driven cuff-force components.

Two joint torques per leg cannot resolve the four components of a leg's two
2-D cuff forces.  The knee torque sees the shank cuff's normal force alone
(the along-shank force passes through the knee axis: no moment about it);
every other component is either unseen (the thigh's along-thigh force) or
seen by the hip torque only in a sum, split by the device's cuff and
patient models.  The summary lists those six, as
:data:`exo_ctrl.estimation.MODEL_DRIVEN` does, in :data:`COMPONENTS`' order.
"""

from __future__ import annotations

import pytest

from exo_ctrl.estimation import COMPONENTS, MODEL_DRIVEN, model_driven
from exo_ctrl.estimation.errors import OBSERVER_COMPONENTS, UNOBSERVABLE
from exo_ctrl.estimation.kalman import CUFF_SENSOR_SOURCE
from exo_ctrl.model import CUFF_NAMES
from exo_ctrl.sensing.cuff_load import CuffSensorParams
from exo_ctrl.sim import SimConfig, SimResult, simulate

#: The components a joint torque alone observes: each shank cuff's normal force.
OBSERVED = {(cuff, "normal") for cuff in CUFF_NAMES if cuff.endswith("shank")}


@pytest.fixture(scope="module")
def kalman_run() -> SimResult:
    result = simulate(SimConfig(duration_s=0.05, estimator="kalman"))
    assert result.status == "completed"
    return result


def test_summary_lists_the_model_driven_components(kalman_run) -> None:
    listed = kalman_run.summary()["cuff_force_estimate_unobservable"]
    expected = [
        f"{cuff}: {part}: {how}"
        for cuff in CUFF_NAMES
        for part, how in COMPONENTS[cuff].items()
        if (cuff, part) not in OBSERVED
    ]
    assert len(expected) == 2 * len(CUFF_NAMES) - len(OBSERVED) == 6
    assert listed == expected == MODEL_DRIVEN
    assert all("model" in line for line in listed)


def test_summary_list_is_a_copy(kalman_run) -> None:
    before = list(MODEL_DRIVEN)
    kalman_run.summary()["cuff_force_estimate_unobservable"].append("changed by the caller")
    assert before == MODEL_DRIVEN
    assert kalman_run.summary()["cuff_force_estimate_unobservable"] == before


def test_momentum_observer_lists_its_own_unobservable_components() -> None:
    summary = simulate(SimConfig(duration_s=0.05, estimator="momentum")).summary()
    listed = summary["cuff_force_estimate_unobservable"]
    assert listed == [f"{c}: {w}" for c, x in UNOBSERVABLE.items() for w in x]
    assert listed != MODEL_DRIVEN


def test_summary_names_each_components_source(kalman_run) -> None:
    """Per cuff and component, observed or from which model; consistent with the lists."""
    components = kalman_run.summary()["cuff_force_estimate_components"]
    assert components == COMPONENTS
    from_models = [
        f"{cuff}: {part}: {how}"
        for cuff, parts in components.items()
        for part, how in parts.items()
        if (cuff, part) not in OBSERVED
    ]
    assert from_models == kalman_run.summary()["cuff_force_estimate_unobservable"]
    components["left_thigh"]["normal"] = "changed by the caller"
    assert kalman_run.summary()["cuff_force_estimate_components"] == COMPONENTS


def test_momentum_observer_names_its_assumptions() -> None:
    summary = simulate(SimConfig(duration_s=0.06, estimator="momentum")).summary()
    components = summary["cuff_force_estimate_components"]
    assert components == OBSERVER_COMPONENTS
    for cuff in CUFF_NAMES:
        along = components[cuff]["along"]
        assert ("assumed 0" in along) == cuff.endswith("thigh")  # no lever arm: UNOBSERVABLE
        assert ("assumption κ" in along) == cuff.endswith("shank")
        assert (components[cuff]["normal"] == "observed: the knee torque") == cuff.endswith("shank")


@pytest.mark.parametrize(
    ("mode", "measured"), [("normal", {"normal"}), ("full", {"normal", "along"})]
)
def test_cuff_sensors_name_the_components_they_measure(mode, measured) -> None:
    """A cuff sensor set's components are observed by it; the rest keep the torques' sources."""
    config = SimConfig(duration_s=0.05, estimator="kalman", cuff_sensors=CuffSensorParams(mode))
    summary = simulate(config).summary()
    components = summary["cuff_force_estimate_components"]
    source = CUFF_SENSOR_SOURCE[mode]
    for cuff in CUFF_NAMES:
        for part in ("normal", "along"):
            expected = source if part in measured else COMPONENTS[cuff][part]
            assert components[cuff][part] == expected, (cuff, part)
    listed = summary["cuff_force_estimate_unobservable"]
    assert all("model" in line for line in listed)
    assert len(listed) == (4 if mode == "normal" else 0)  # the thighs' and shanks' along
    assert listed == model_driven(components)
