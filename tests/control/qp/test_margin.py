"""The margin the QP tightens each cuff bound by: its terms, the refusal, the filter's σ_c.

The bounds the closed loop must keep are asserted elsewhere against the
user's bound (test_closed_loop.py, test_load_held.py); here the mechanism.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl import cli
from exo_ctrl.control.qp import QPController
from exo_ctrl.control.qp.cuff_knowledge import CuffKnowledge, link_normals, unobserved
from exo_ctrl.control.qp.margin import (
    PREDICTION_ERROR_N,
    BoundMargin,
    contact_warning,
    departure_warning,
    share_matrices,
)
from exo_ctrl.control.qp.prediction import CuffHorizonModel
from exo_ctrl.estimation.kalman import CuffForceKalman
from exo_ctrl.exceptions import CuffBoundTooTight, InvalidParameter
from exo_ctrl.model import CUFF_NAMES
from exo_ctrl.plant import CuffParams, PelvisParams
from exo_ctrl.plant.cuff_scatter import CuffScatter
from exo_ctrl.sim import Runner, SimConfig, build
from exo_ctrl.sim.belief import Belief
from exo_ctrl.sim.supervision import departure_for


def _margin(exo, patient, motor, plan, cuffs=None, **knowledge) -> BoundMargin:
    """The margin of a QP on the default gait with a 150 N bound."""
    return QPController(
        plan,
        exo,
        patient,
        motor,
        cuffs=cuffs or CuffParams(),
        cuff_knowledge=CuffKnowledge(**knowledge),
    ).margin


def test_margin_terms_on_the_default_gait(exo, patient, motor, plan) -> None:
    exact = _margin(exo, patient, motor, plan, spread_rel=0.0)
    isotropic = _margin(exo, patient, motor, plan, CuffParams.isotropic(), spread_rel=0.0)
    default = _margin(exo, patient, motor, plan)
    print(
        f"\nexact cuffs: patient {exact.patient_N.round(1)}, working "
        f"{exact.working_N.round(1)}; isotropic model: cuffs {isotropic.cuffs_N.round(1)} N; "
        f"scattered cuffs: {default.cuffs_N.round(1)} N"
    )
    np.testing.assert_array_equal(exact.prediction_N, PREDICTION_ERROR_N)
    # The device holds the true cuffs exactly: nothing to cover.
    np.testing.assert_allclose(exact.cuffs_N, 0.0, atol=1e-9)
    assert np.all(exact.patient_N > 0.0) and np.all(exact.working_N > 0.0)
    # The isotropic model shares the hip's load otherwise than the true cuffs.
    assert np.all(isotropic.cuffs_N > 10.0)
    # The patient's cuffs scatter by 20 %: the split of a load is not known.
    assert np.all(default.cuffs_N > 20.0)
    np.testing.assert_allclose(default.patient_N, exact.patient_N)
    total = exact.prediction_N + exact.patient_N + exact.cuffs_N
    np.testing.assert_allclose(exact.static_N, total + exact.estimate_N)
    # The whole load the plan puts on a cuff is above its gravity share.
    assert np.all(default.load_N >= default.working_N)


def _scaled(cuffs: CuffParams, f_n: float, f_u: float) -> CuffParams:
    return dataclasses.replace(
        cuffs,
        stiffness_N_per_m=f_n * cuffs.stiffness_N_per_m,
        shear_stiffness_N_per_m=f_u * cuffs.shear_stiffness_N_per_m,
    )


def test_every_cuff_model_carries_the_load_the_torques_see(exo, patient, motor, plan) -> None:
    """Jᵀ D = −I for any stiffness; D depends on the ratio k_n/k_u only."""
    k = 400
    shares = {}
    for f_n, f_u in ((1.0, 1.0), (1.4, 0.6), (0.6, 1.4), (2.0, 2.0)):
        model = CuffHorizonModel(exo, patient, motor, _scaled(CuffParams(), f_n, f_u), 1e-3)
        model.linearise(plan.q[k], plan.dq[k])
        share = share_matrices(model, model.split)
        for leg in range(2):
            np.testing.assert_allclose(model.jac[leg].T @ share[leg], -np.eye(2), atol=1e-12)
        shares[(f_n, f_u)] = share
    np.testing.assert_allclose(shares[(2.0, 2.0)], shares[(1.0, 1.0)], rtol=1e-12)
    assert np.abs(shares[(1.4, 0.6)] - shares[(0.6, 1.4)]).max() > 1e-3


def test_normal_load_cells_leave_the_along_link_components(exo, patient, motor, plan) -> None:
    """U against the links' directions from Pinocchio's joint and cuff frames."""
    model = CuffHorizonModel(exo, patient, motor, CuffParams(), 1e-3)
    data = exo.model.createData()
    for k in (0, 300, 700):
        q = plan.q[k]
        model.linearise(q, plan.dq[k])
        normals = link_normals(model, q)
        q_model = pin.neutral(exo.model)
        q_model[exo.q_index] = q
        pin.framesForwardKinematics(exo.model, data, q_model)
        for leg, side in enumerate(("left", "right")):

            def at(frame: str) -> np.ndarray:
                return data.oMf[exo.model.getFrameId(frame)].translation[[0, 2]]

            thigh = at(f"{side}_knee") - at(f"{side}_hip")
            shank = at(f"{side}_shank_cuff") - at(f"{side}_knee")
            along = np.zeros((4, 4))
            along[:2, :2] = np.outer(thigh, thigh) / thigh.dot(thigh)
            along[2:, 2:] = np.outer(shank, shank) / shank.dot(shank)
            own = normals[2 * leg : 2 * leg + 2]
            np.testing.assert_allclose(unobserved(own, "normal"), along, atol=1e-9)
            np.testing.assert_array_equal(unobserved(own, "none"), np.eye(4))
            np.testing.assert_array_equal(unobserved(own, "full"), 0.0)


def test_cuff_sensors_and_a_smaller_spread_shrink_the_cuff_term(exo, patient, motor, plan) -> None:
    none = _margin(exo, patient, motor, plan)
    normal = _margin(exo, patient, motor, plan, sensors="normal")
    full = _margin(exo, patient, motor, plan, sensors="full")
    narrow = _margin(exo, patient, motor, plan, spread_rel=0.1)
    print(
        f"\ne_cuffs none {none.cuffs_N.round(2)}, normal {normal.cuffs_N.round(2)}, "
        f"spread 0.1 {narrow.cuffs_N.round(2)} N"
    )
    np.testing.assert_array_equal(full.cuffs_N, 0.0)
    # The thigh cuff's split error lies across the thigh: the load cell measures it all.
    np.testing.assert_allclose(normal.cuffs_N[[0, 2]], 0.0, atol=1e-6)
    # The shank's lies mostly along the shank, which a load cell does not measure.
    assert np.all(normal.cuffs_N[[1, 3]] <= none.cuffs_N[[1, 3]])
    assert np.all(normal.cuffs_N[[1, 3]] > 0.5 * none.cuffs_N[[1, 3]])
    assert np.all(narrow.cuffs_N < none.cuffs_N)
    assert np.all(narrow.cuffs_N > 0.0)
    np.testing.assert_allclose(normal.patient_N, none.patient_N)


def test_departure_warning_names_the_load_and_the_cuff_sensors() -> None:
    four = np.ones(4)
    margin = BoundMargin(
        5.5 * four,
        four,
        np.array([30.0, 1.0, 1.0, 1.0]),
        0 * four,
        40 * four,
        np.array([110.0, 60.0, 60.0, 60.0]),
    )
    text = departure_warning(margin, 120.0, "none")
    assert text == (
        "the QP will leave the plan to hold cuff_force_limit 120 N: the gait loads the "
        "left_thigh cuff with up to 110 N, and the margin 36.5 N leaves 83.5 N (30.0 N of "
        "it for the patient's unknown cuff stiffness, which cuff sensors measure: "
        "--cuff-sensors full removes it, normal its part across the link)"
    )
    assert departure_warning(margin, 120.0, "normal").endswith("leaves 83.5 N")
    assert departure_warning(margin, 150.0, "none") is None


def test_feet_over_the_belt_are_told_before_the_run_and_free_air_not(
    supported_qp: SimConfig,
) -> None:
    """The horizon holds no ground contact: a run with the feet over the belt (the pelvis
    supported or fixed) says how the bound holds, in a note (not a warning: no figure is in
    doubt); one in free air has no belt to strike.  Untightened, the bound is not promised
    there: that is a warning."""
    supported = supported_qp
    setup = build(supported)
    legs = setup.device_exo.legs.values()
    limit = supported.gait.lift_height / min(g.thigh_length + g.shank_length for g in legs)
    text = (
        f"with the feet over the belt the walk stops (yield) where a leg leaves its plan by more "
        f"than {limit:.3f} rad: the QP holds cuff_force_limit 300 N by leaving the plan where "
        "the patient loads the cuffs beyond it, and a leg off its plan can strike the belt "
        "(docs/performance.md, the QP's cuff-force bound)"
    )
    assert f"{limit:.3f}" == "0.096"  # 0.10 m of lift over the default legs' 1.04 m
    assert contact_warning(300.0, limit) == text
    fixed = dataclasses.replace(supported, pelvis=PelvisParams())
    fixed_setup = build(fixed)
    assert fixed_setup.notes == (text,)  # the pelvis fixed: nothing falls, no look-ahead
    assert not any("over the belt" in w for w in fixed_setup.warnings)
    ahead = departure_for(supported, setup.device_exo).lookahead_s
    supported_text = text.replace(
        " rad:", f" rad, or a knee folds there within the harness's arrest ({1e3 * ahead:.0f} ms):"
    )
    assert contact_warning(300.0, limit, lookahead_s=ahead) == supported_text
    assert setup.notes == (supported_text,)
    free_air = dataclasses.replace(fixed, contact=dataclasses.replace(fixed.contact, enabled=False))
    ct = dataclasses.replace(supported, controller="ct")
    for quiet in (build(free_air), build(ct)):
        assert quiet.notes == () and not any("over the belt" in w for w in quiet.warnings)
    loose = dataclasses.replace(supported, qp_tighten_bound=False)
    for sync in (True, False):  # the stop on either plan
        assert build(dataclasses.replace(supported, sync=sync)).notes == (supported_text,)
    loose_text = (
        "cuff_force_limit 300 N is not promised with the feet over the belt: the QP's horizon "
        "holds no ground contact, and where it leaves the plan a foot can strike the belt; on "
        "the synchronised plan, which follows the measured legs, the "
        "plan can then leave the leg's reach and the run end (docs/performance.md, the QP's "
        "cuff-force bound)"
    )
    untightened = build(dataclasses.replace(loose, sync=True))
    assert loose_text in untightened.warnings and untightened.notes == ()
    precomputed = dataclasses.replace(loose, sync=False)
    assert not any("leg's reach" in w for w in build(precomputed).warnings)


def test_a_supported_pelvis_needs_room_for_the_plans_whole_load(supported_qp: SimConfig) -> None:
    """The QP may not leave the plan on the belt: a bound below load + margin is refused."""
    fixed = SimConfig(controller="qp", cuff_force_limit_N=150.0)
    supported = dataclasses.replace(supported_qp, cuff_force_limit_N=150.0)
    margin = build(fixed).controller.margin  # the fixed pelvis runs, leaving the plan
    with pytest.raises(CuffBoundTooTight) as info:
        build(supported)
    err = info.value
    assert err.supported and err.bound_N == 150.0
    loaded = build(dataclasses.replace(supported, cuff_force_limit_N=400.0)).controller.margin
    c = CUFF_NAMES.index(err.cuff)
    assert err.working_N == pytest.approx(loaded.load_N[c], rel=1e-12)
    assert err.working_N > 150.0 - err.margin_N
    assert str(err) == (
        f"qp.cuff_force_limit_N = 150 N cannot be held on {err.gait}: the {err.cuff} cuff's "
        f"margin of {err.margin_N:.1f} N (what the device does not know) leaves "
        f"{150.0 - err.margin_N:.1f} N, less than the {err.working_N:.1f} N the plan puts on "
        "the cuff: with the pelvis supported the QP cannot leave the plan to hold its bound, "
        "since a leg off its plan can strike the belt; raise the bound to at least "
        f"{math.ceil(err.margin_N + err.working_N)} N or add cuff sensors (--cuff-sensors), "
        "which shrink the margin"
    )
    assert margin.working_N[c] < err.working_N  # the fixed pelvis needs the leg's weight only


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"spread_rel": 0.5}, "cuff knowledge spread_rel must be in [0, 0.45]; got 0.5"),
        (
            {"sensors": "both"},
            "cuff knowledge sensors must be one of none, normal, full; got 'both'",
        ),
        ({"published": 8000.0}, "cuff knowledge published must be a CuffParams; got 8000.0"),
    ],
)
def test_cuff_knowledge_refuses_bad_values(kwargs, message) -> None:
    with pytest.raises(InvalidParameter) as info:
        CuffKnowledge(**kwargs)
    assert str(info.value) == message


def test_a_bound_the_margin_cannot_hold_is_refused(exo, patient, motor, plan) -> None:
    with pytest.raises(CuffBoundTooTight) as info:
        QPController(
            plan,
            exo,
            patient,
            motor,
            cuffs=CuffParams(),
            cuff_force_limit_N=50.0,
            cuff_knowledge=CuffKnowledge(spread_rel=0.0),
        )
    err = info.value
    assert err.bound_N == 50.0 and err.margin_N > PREDICTION_ERROR_N
    assert err.bound_N - err.margin_N < err.working_N


def test_cli_refuses_before_the_run_naming_bound_margin_and_gait(capsys) -> None:
    argv = ["simulate", "--controller", "qp", "--no-record"]
    argv += ["--set", "qp.cuff_force_limit_N=55", "--set", "gait.period=1.1"]
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 2
    assert "qp.cuff_force_limit_N = 55 N cannot be held on the gait with period 1.1 s" in err
    assert "cuff's margin of" in err and "raise the bound to at least" in err


def test_a_synchronised_run_refused_names_the_speed_profile_its_gait_adapts_along(capsys) -> None:
    """The margin is taken along each profile point's gait: the refusal names the profile."""
    argv = ["simulate", "--controller", "qp", "--contact", "on", "--sync", "on", "--no-record"]
    argv += ["--speed-profile", "0:0.45,2:0.7", "--cuff-force-limit", "60"]
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 2
    assert (
        "qp.cuff_force_limit_N = 60 N cannot be held on the gait with period 1.2 s and "
        "step_length 0.35 m adapted along speed_profile 0:0.45,2:0.7: the left_thigh cuff's "
        "margin of"
    ) in err


def test_kalman_force_std_is_the_covariance_mapped_to_each_cuff() -> None:
    """σ_c = √λ_max(H_c P H_cᵀ), recomputed here from the filter's record."""
    config = SimConfig(controller="qp", belief=Belief(cuffs=CuffParams()))
    setup = build(config)
    runner = Runner(setup)
    for k in range(300):
        runner.tick(k, k % runner.chunk)
    est = runner.estimator
    assert isinstance(est, CuffForceKalman)
    rec, cuffs = est.record[0], est.cuffs.record[0]
    for c in range(4):
        leg = c // 2
        cos, sin = cuffs["cs"][c], cuffs["cs"][8 + c]
        u = np.array(
            [
                cuffs["along0"][c, 0] * cos - cuffs["along0"][c, 1] * sin,
                cuffs["along0"][c, 1] * cos + cuffs["along0"][c, 0] * sin,
            ]
        )
        n = np.array([-u[1], u[0]])
        stiff = cuffs["k"] * np.outer(n, n) + cuffs["k_u"] * np.outer(u, u)
        damp = cuffs["c"] * np.outer(n, n) + cuffs["c_u"] * np.outer(u, u)
        jac = rec["jd"][[c, 4 + c]][:, rec["joints"][leg]]  # (2, 4)
        h = np.hstack((-stiff @ jac, -damp @ jac, np.zeros((2, 2))))
        cov = h @ rec["cov"][leg] @ h.T
        expected = np.sqrt(np.linalg.eigvalsh(cov).max())
        assert rec["cuff_force_std"][c] == pytest.approx(expected, rel=1e-9)
        assert 0.0 < expected < 5.0  # settled: a few newtons at most
    # The controller sees it and tightens each cuff by its three σ_c on top.
    ctrl = setup.controller
    margin = ctrl.record["margin"][0]
    np.testing.assert_allclose(margin, ctrl.margin.static_N + 3.0 * rec["cuff_force_std"])


def test_a_tare_keeps_the_standing_split_error_on_the_measured_components(
    exo, patient, motor, plan
) -> None:
    """2-axis sensors tared at the standing start: e_cuffs is the standing split error.

    Recomputed here: the nominal patient's load at the plan's first row from
    Pinocchio's RNEA, shared by the device's model and by the scatter's two
    extremes (CuffScatter.extremes), the largest difference per cuff.
    """
    tared = _margin(exo, patient, motor, plan, sensors="full", tare=True)
    load = pin.rnea(patient.model, patient.model.createData(), plan.q[0], plan.dq[0], plan.ddq[0])
    device = CuffHorizonModel(exo, patient, motor, CuffParams(), 1e-3)
    device.linearise(plan.q[0], plan.dq[0])
    expected = np.zeros(4)
    for cuffs in CuffScatter().extremes(CuffParams()):
        truth = CuffHorizonModel(exo, patient, motor, cuffs, 1e-3)
        truth.linearise(plan.q[0], plan.dq[0])
        diff = share_matrices(device, True) - share_matrices(truth, True)
        for leg in range(2):
            error = (diff[leg] @ load[2 * leg : 2 * leg + 2]).reshape(2, 2)
            expected[2 * leg : 2 * leg + 2] = np.maximum(
                expected[2 * leg : 2 * leg + 2], np.linalg.norm(error, axis=1)
            )
    print(f"\nthe tare's standing split error per cuff {tared.cuffs_N.round(2)} N")
    np.testing.assert_allclose(tared.cuffs_N, expected, rtol=1e-9)
    assert np.all(tared.cuffs_N > 1.0)
    untared = _margin(exo, patient, motor, plan, sensors="full")
    np.testing.assert_array_equal(untared.cuffs_N, 0.0)
