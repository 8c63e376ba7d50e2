"""The QP controller in the closed loop: tracking, the user's bound within 5 %, fallbacks.

The default 2.4 s scenario through :func:`exo_ctrl.sim.loop.simulate`,
default sensors (so the estimated cuff forces feed the QP), safety
supervisor off; the real cuff forces are the plant's elastic cuffs',
scattered around the published ones (the default
:class:`~exo_ctrl.plant.cuff_scatter.CuffScatter`).  The runs whose bound
binds carry normal load cells in the cuffs (``--cuff-sensors normal``):
without them the margin covers the patient's unknown cuff stiffness (about
40 N on the thighs), which the unsensed runs below measure.  Each
configuration is simulated once per module.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.exceptions import CuffBoundTooTight
from exo_ctrl.scenario.load import load_scenario
from exo_ctrl.sensing.cuff_load import CuffSensorParams
from exo_ctrl.sim import SimConfig, SimResult, simulate

#: The QP may track worse than CT by at most this, per joint (brief: 5 %),
#: where no bound binds.
RMS_TOLERANCE = 0.05
#: The QP's RMS tracking error over all joints may exceed CT's by at most this
#: on the passive default patient, its bound tightened by the margin (issue 31).
TRACKING_TOLERANCE = 0.10
#: The hips' RMS error over CT's where the torque box binds (measured 1.6).
HIP_BOX_TOLERANCE = 1.8
#: A bound the passive default run does not need [N].
F_FREE = 150.0
#: A bound below CT's peak on the default run (≈ 106 N with the default sensors) [N].
F_TIGHT = 80.0
#: The spastic scenario's bound [N].
F_SPASTIC = 150.0
#: The user's promise: the true peak within 5 % of the bound they set (issue 31),
#: never a margin the code under test computes.
BOUND_TOLERANCE = 0.05
#: URDF effort of every joint [N·m].
EFFORT = 150.0
#: A load cell in each cuff measuring its normal force.
LOAD_CELLS = CuffSensorParams(mode="normal")
#: How much larger the margin is without the load cells, at least [N]: the
#: patient's unknown cuff stiffness (e_cuffs, about 39 N on the thighs).
UNSENSED_EXTRA_N = 20.0


def _run(**kwargs) -> SimResult:
    # The default (split) cuffs; the QP's device holds the published split model.
    return simulate(SimConfig(safety=False, **kwargs))


def _run_qp(**kwargs) -> SimResult:
    """A QP run with load cells in the cuffs."""
    return _run(controller="qp", cuff_sensors=LOAD_CELLS, **kwargs)


@pytest.fixture(scope="module")
def ct_passive() -> SimResult:
    return _run(controller="ct")


@pytest.fixture(scope="module")
def qp_passive() -> SimResult:
    # 150 N: above CT's true peak on the default cuffs (129 N at the thighs)
    # plus the margin with load cells (≈ 12 N), so no cuff bound binds.  At the
    # default 120 N it binds: the QP departs from the plan to hold it.
    return _run_qp(cuff_force_limit_N=F_FREE)


@pytest.fixture(scope="module")
def qp_tight() -> SimResult:
    return _run_qp(cuff_force_limit_N=F_TIGHT)


@pytest.fixture(scope="module")
def ct_spastic() -> SimResult:
    return _run(controller="ct", patient_torque="spastic")


@pytest.fixture(scope="module")
def qp_spastic() -> SimResult:
    return _run_qp(cuff_force_limit_N=F_SPASTIC, patient_torque="spastic")


@pytest.fixture(scope="module")
def qp_spastic_unsensed() -> SimResult:
    return _run(controller="qp", cuff_force_limit_N=F_SPASTIC, patient_torque="spastic")


def rms(result: SimResult) -> np.ndarray:
    return np.array(list(result.summary()["rms_tracking_error_rad"].values()))


def peak_force(result: SimResult) -> np.ndarray:
    return np.array(list(result.summary()["peak_cuff_force_N"].values()))


def describe(name: str, result: SimResult) -> str:
    s = result.summary()
    torque = np.array(list(s["peak_drive_torque_Nm"].values()))
    return (
        f"{name}: {result.status}, RMS error {np.round(rms(result) * 1e3, 3)} mrad, "
        f"peak cuff force {np.round(peak_force(result), 1)} N, "
        f"peak drive torque {np.round(torque, 1)} N·m, {s['qp_failures']} fallbacks"
    )


def test_closed_loop_qp_tracks_as_well_as_ct(ct_passive, qp_passive) -> None:
    print(f"\n{describe('ct', ct_passive)}\n{describe(f'qp {F_FREE:g} N', qp_passive)}")
    assert ct_passive.status == qp_passive.status == "completed"
    assert qp_passive.qp_failures == 0
    # The knees: no bound binds, the QP's answer is the CT command.  The hips
    # pass through zero speed at 110–130 N·m, near the joint's 150 N·m effort
    # once the gearbox's 1/η of a braking joint is counted from the measured
    # speed's sign: the QP holds them in the box where CT's command goes
    # beyond it (the plant's current limit then caps CT).  Measured: hips
    # 0.77/0.63 mrad against CT's 0.59/0.55, knees equal (split cuffs and model).
    qp, ct = rms(qp_passive), rms(ct_passive)
    assert np.all(qp[[1, 3]] <= (1.0 + RMS_TOLERANCE) * ct[[1, 3]])
    assert np.all(qp[[0, 2]] <= HIP_BOX_TOLERANCE * ct[[0, 2]])
    # The cuff bound is not binding on this run: the peak is CT's, within 5 %
    # (the hips' box lowers it by 4 %).
    np.testing.assert_allclose(peak_force(qp_passive), peak_force(ct_passive), rtol=0.05)


def test_closed_loop_tight_bound_holds_within_5_percent(ct_passive, qp_tight) -> None:
    peak = peak_force(qp_tight)
    print(
        f"\n{describe(f'qp {F_TIGHT:g} N', qp_tight)}\n"
        f"peak {peak.max():.1f} N = bound + {100 * (peak.max() / F_TIGHT - 1):.1f} %; "
        f"margin {qp_tight.summary()['cuff_bound_margin_N']}; "
        f"ct peak {peak_force(ct_passive).max():.1f} N"
    )
    assert qp_tight.status == "completed"
    assert np.all(np.isfinite(rms(qp_tight)))
    assert np.all(peak <= F_TIGHT * (1.0 + BOUND_TOLERANCE))
    # Fallbacks are counted, in the summary and in the logged signal alike.
    assert qp_tight.summary()["qp_failures"] == qp_tight.qp_failures
    assert qp_tight.signals["qp_failures"][-1] == qp_tight.qp_failures


def test_closed_loop_tight_bound_lowers_the_peak_below_cts(ct_passive, qp_tight) -> None:
    assert peak_force(qp_tight).max() < peak_force(ct_passive).max() - 10.0


def test_closed_loop_tight_bound_needs_no_fallback(qp_tight) -> None:
    assert qp_tight.qp_failures == 0


@pytest.mark.parametrize(
    "run", ["ct_passive", "qp_passive", "qp_tight", "ct_spastic", "qp_spastic"]
)
def test_closed_loop_no_drive_torque_beyond_the_urdf_effort(request, run) -> None:
    result = request.getfixturevalue(run)
    peak = np.abs(result.signals["drive_torque"]).max()
    print(f"\n{run}: peak drive torque {peak:.3f} N·m")
    assert peak <= EFFORT + 1e-9


def test_closed_loop_spastic_patient_pushes_ct_beyond_the_bound(ct_spastic) -> None:
    print(f"\n{describe('ct spastic', ct_spastic)}")
    assert ct_spastic.status == "completed"
    assert peak_force(ct_spastic).max() > F_SPASTIC


def test_closed_loop_spastic_patient_qp_completes_and_counts_its_fallbacks(qp_spastic) -> None:
    summary = qp_spastic.summary()
    print(
        f"\n{describe(f'qp {F_SPASTIC:g} N spastic', qp_spastic)}; peak = "
        f"bound + {100 * (peak_force(qp_spastic).max() / F_SPASTIC - 1):.1f} %"
    )
    assert qp_spastic.status == "completed"
    assert np.all(np.isfinite(rms(qp_spastic)))
    assert isinstance(summary["qp_failures"], int) and summary["qp_failures"] >= 0
    assert summary["qp_failures"] == qp_spastic.qp_failures
    assert qp_spastic.signals["qp_failures"][-1] == qp_spastic.qp_failures
    assert np.all(np.diff(qp_spastic.signals["qp_failures"]) >= 0)


def test_closed_loop_spastic_patient_qp_keeps_the_bound_within_5_percent(qp_spastic) -> None:
    assert peak_force(qp_spastic).max() <= F_SPASTIC * (1.0 + BOUND_TOLERANCE)


def test_closed_loop_tightened_qp_tracks_within_10_percent_of_ct(ct_passive, qp_passive) -> None:
    """The passive default patient, the bound (F_FREE) tightened by its margin."""
    qp, ct = np.sqrt(np.mean(rms(qp_passive) ** 2)), np.sqrt(np.mean(rms(ct_passive) ** 2))
    margin = qp_passive.summary()["cuff_bound_margin_N"]
    print(f"\nRMS over the joints: qp {1e3 * qp:.3f} mrad, ct {1e3 * ct:.3f} mrad; margin {margin}")
    assert all(m > 0.0 for m in margin.values())
    assert qp <= (1.0 + TRACKING_TOLERANCE) * ct


@pytest.mark.parametrize("run", ["qp_passive", "qp_tight", "qp_spastic", "qp_spastic_unsensed"])
def test_closed_loop_tightened_qp_commands_within_the_supply(request, run) -> None:
    result = request.getfixturevalue(run)
    assert np.abs(result.signals["voltage_cmd"]).max() <= SimConfig().motor.supply_voltage_V + 1e-9


@pytest.mark.parametrize("run", ["qp_passive", "qp_tight", "qp_spastic"])
def test_closed_loop_recorded_margin_peaks_at_the_summarys(request, run) -> None:
    """The log's per-tick margin m_c: never below its static part, its largest the summary's."""
    result = request.getfixturevalue(run)
    logged = result.signals["cuff_bound_margin"]
    stated = np.array(list(result.summary()["cuff_bound_margin_N"].values()))
    assert np.array_equal(logged.max(axis=0), stated)
    assert (logged.min(axis=0) > 0.0).all()
    assert logged.min(axis=0).max() < stated.max()  # the estimate's term varies per tick


def test_closed_loop_ct_records_no_margin(ct_passive) -> None:
    assert not ct_passive.signals["cuff_bound_margin"].any()
    assert ct_passive.summary()["cuff_bound_margin_N"] is None


def test_closed_loop_without_load_cells_the_bound_holds_with_a_wider_margin(
    qp_spastic, qp_spastic_unsensed
) -> None:
    """No cuff sensors: the margin covers the unknown cuff stiffness, the bound still holds."""
    peak = peak_force(qp_spastic_unsensed)
    sensed = qp_spastic.summary()["cuff_bound_margin_N"]
    unsensed = qp_spastic_unsensed.summary()["cuff_bound_margin_N"]
    print(
        f"\n{describe('qp spastic, no cuff sensors', qp_spastic_unsensed)}\n"
        f"margin without cells {unsensed}\nwith {sensed}"
    )
    assert qp_spastic_unsensed.status == "completed"
    assert peak.max() <= F_SPASTIC * (1.0 + BOUND_TOLERANCE)
    for name in ("left_thigh", "right_thigh"):
        assert unsensed[name] > sensed[name] + UNSENSED_EXTRA_N
    # The run said before it started that the QP would leave the plan.
    assert any("the QP will leave the plan" in w for w in qp_spastic_unsensed.warnings)
    assert not any("--cuff-sensors normal" in w for w in qp_spastic.warnings)


def test_closed_loop_a_tight_bound_without_load_cells_is_refused() -> None:
    """F_TIGHT runs with load cells; without them its margin leaves less than the working force."""
    with pytest.raises(CuffBoundTooTight):
        _run(controller="qp", cuff_force_limit_N=F_TIGHT)


@pytest.mark.parametrize(
    ("limit", "gait"),
    [(150.0, []), (120.0, ["gait.period=1.0", "gait.step_length=0.4"])],
)
def test_over_the_belt_with_the_pelvis_fixed_the_bound_holds(limit: float, gait: list) -> None:
    """The default scenario (the belt on, the feet skimming it) with a spastic patient and no
    cuff sensors: the QP leaves the plan to hold the bound, and where a leg leaves it by more
    than the swing foot's lift over the leg's length the walk stops before the foot strikes
    the belt (exo_ctrl/safety/departure.py; without the stop the 120 N case reached 263 N).
    The truth's peak is within 5 % of the user's bound."""
    settings = ["run.controller=qp", "interaction.patient_torque=spastic"]
    settings += [f"qp.cuff_force_limit_N={limit}", "safety.safety=false", *gait]
    config = load_scenario(overrides=settings).config
    assert config.contact.enabled and not config.pelvis.supported
    result = simulate(config)
    peak = float(np.linalg.norm(result.cuff_force, axis=2).max())
    print(f"\nbound {limit:.0f} N: true peak {peak:.1f} N ({peak / limit - 1:+.1%})")
    assert peak <= limit * 1.05


def test_the_default_scenarios_qp_walks_within_its_per_region_bound() -> None:
    """The default scenario (the belt on) bounds the thighs at 200 N and the shanks at 120 N:
    room for the gait's load and the margin, so the passive patient walks two cycles with the
    supervisor on and no stop (at 120 N on every cuff the thighs' bound left less than the
    gait's load and the departure stop ended the walk about 1 s in); every true peak within
    its region's bound plus 5 %, the tracking within 10 % of CT's on the same scenario."""
    runs = {
        c: simulate(load_scenario(overrides=[f"run.controller={c}"]).config) for c in ("ct", "qp")
    }
    qp = runs["qp"]
    assert qp.config.cuff_force_limit_N == (200.0, 120.0) and qp.config.safety
    assert qp.status == "completed" and qp.safety_state == "normal"
    assert [e for e in qp.events if e["kind"] == "violation"] == []
    assert qp.summary()["touchdown_count"] >= 4
    peak = np.linalg.norm(qp.cuff_force, axis=2).max(axis=0)
    assert (peak <= np.array([200.0, 120.0, 200.0, 120.0]) * 1.05).all(), peak
    rms = {c: np.sqrt(np.mean((r.signals["q_des"] - r.signals["q"]) ** 2)) for c, r in runs.items()}
    print(f"\npeaks {np.round(peak, 1)} N; RMS error qp {rms['qp']:.2e}, ct {rms['ct']:.2e} rad")
    assert rms["qp"] <= 1.10 * rms["ct"]
