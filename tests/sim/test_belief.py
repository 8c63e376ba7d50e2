"""Truth and belief: the plant simulates the URDFs, the device holds models of its own.

Checks: the device's models are never the plant's objects; a nominal patient
has de Leva's inertial parameters on the true leg lengths (not the truth's
masses); PD, which holds no model, runs bit for bit the same with either
belief; CT with the nominal model tracks worse than with the truth (both
printed); bad inputs are refused with exact messages.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import cli
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyParams, nominal_patient, write_urdf
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import BeltParams, ContactParams, PelvisParams
from exo_ctrl.plant.motor import MotorBank
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief
from exo_ctrl.sim.setup import build, stance_sink_for
from exo_ctrl.sim.tick import Runner

SHORT = {"duration_s": 1.8, "safety": False}


def _thigh_mass(body) -> float:
    model = body.model
    return float(model.inertias[model.getJointId("left_hip")].mass)


@pytest.mark.parametrize("controller", ["ct", "qp"])
def test_the_device_never_holds_the_plants_objects(controller: str) -> None:
    setup = build(SimConfig(controller=controller, belief=Belief("truth")))
    assert setup.device_exo is not setup.exo and setup.device_patient is not setup.patient
    assert setup.device_exo.model is not setup.exo.model
    assert setup.device_patient.source == setup.patient.source  # truth: the same file, anew
    assert _thigh_mass(setup.device_patient) == _thigh_mass(setup.patient)
    # The drive: the datasheet as a parameter set of its own, equal in value.
    assert setup.device_motor is not setup.plant.motor_params
    assert setup.device_motor == setup.plant.motor_params
    controller_obj = setup.controller
    if controller == "qp":
        # The QP's cuffs are the nominal isotropic cuffs, not the truth's split ones.
        model = controller_obj.cuff_model
        assert model.stiffness == 8000.0 and model.damping == 100.0


def test_the_default_device_holds_the_nominal_patient() -> None:
    """The default belief is what a clinic knows, not the truth (design.md §2)."""
    config = SimConfig(controller="ct")
    assert config.belief.patient == "nominal" and config.safety_use_estimate
    setup = build(config)
    assert _thigh_mass(setup.device_patient) == pytest.approx(0.1416 * 80.0, rel=1e-9)
    assert _thigh_mass(setup.patient) == pytest.approx(11.3, rel=1e-12)


def test_a_drive_model_off_its_datasheet_changes_the_feedforward_not_the_plant() -> None:
    """The device's drive model is its own: a winding 20 % more resistive in the model.

    CT's feedforward voltage is U = R τ/(i_G k_m) + (back-EMF): with the
    model's R 20 % higher the tabulated voltage's resistive part is 20 %
    higher, the plant's drive unchanged.
    """
    base = SimConfig(controller="ct", belief=Belief("truth"))
    true_motor = base.motor
    hot = dataclasses.replace(true_motor, resistance_ohm=1.2 * true_motor.resistance_ohm)
    right = build(base)
    wrong = build(dataclasses.replace(base, belief=Belief("truth", motor=hot)))
    assert wrong.plant.motor_params == right.plant.motor_params
    assert wrong.device_motor.resistance_ohm == pytest.approx(1.2 * true_motor.resistance_ohm)
    tau = right.controller.torque_ff_table
    np.testing.assert_array_equal(tau, wrong.controller.torque_ff_table)  # torque: no drive in it
    u_right = right.controller.voltage_ff_table
    # The table's voltage is the drive model's steady state (MotorBank.voltage_for).
    expected_u = MotorBank(4, right.device_motor).voltage_for(tau, right.plan.dq)
    np.testing.assert_allclose(u_right, expected_u, rtol=1e-12, atol=1e-12)
    du = wrong.controller.voltage_ff_table - u_right
    back_emf = true_motor.back_emf_V_per_rad_s * right.plan.dq
    np.testing.assert_allclose(du, 0.2 * (u_right - back_emf), rtol=1e-9, atol=1e-9)
    assert np.max(np.abs(du)) > 0.1  # V


def test_a_nominal_patient_has_the_tables_masses_on_the_true_lengths() -> None:
    setup = build(SimConfig(controller="ct", belief=Belief(patient="nominal")))
    true_leg, model_leg = setup.patient.legs["left"], setup.device_patient.legs["left"]
    assert model_leg.thigh_length == pytest.approx(true_leg.thigh_length, rel=1e-12)
    assert model_leg.shank_length == pytest.approx(true_leg.shank_length, rel=1e-12)
    # de Leva's male thigh, 14.16 % of the paper's 80 kg, against Table I's 11.3 kg in the plant.
    assert _thigh_mass(setup.device_patient) == pytest.approx(0.1416 * 80.0, rel=1e-9)
    assert _thigh_mass(setup.patient) == pytest.approx(11.3, rel=1e-12)
    expected = nominal_patient(true_leg.thigh_length, true_leg.shank_length, 1.75, 80.0)
    knee = setup.device_patient.model.getJointId("left_knee")
    assert setup.device_patient.model.inertias[knee].mass == pytest.approx(
        expected.shank_mass, rel=1e-9
    )


def test_pd_holds_no_model_so_the_belief_changes_nothing() -> None:
    truth = simulate(SimConfig(belief=Belief("truth"), **SHORT))
    nominal = simulate(SimConfig(belief=Belief(patient="nominal"), **SHORT))
    for name in ("q", "voltage", "cuff_force"):
        np.testing.assert_array_equal(truth.signals[name], nominal.signals[name])


def _rms(result) -> np.ndarray:
    return np.array(list(result.summary()["rms_tracking_error_rad"].values()))


def test_computed_torque_with_the_nominal_patient(tmp_path: Path) -> None:
    """The nominal model changes CT's feedforward, and a grossly wrong one costs tracking.

    Measured: the nominal patient (de Leva's tables; the truth is Winter's
    shank, COM 0.61 L against 0.50 L) tracks as well as the truth on the
    passive patient: CT's residual error is the PD's answer to what no
    rigid model holds (the cuffs' compliance, the sensors), not the patient's
    inertia.  A model with twice the true thigh mass does track worse.
    """
    truth_setup = build(SimConfig(controller="ct", belief=Belief("truth")))
    nominal_setup = build(SimConfig(controller="ct", belief=Belief(patient="nominal")))
    gap = np.abs(truth_setup.controller.torque_ff_table - nominal_setup.controller.torque_ff_table)
    assert gap.max() > 1.0  # N·m: the model is what CT's feedforward is made of
    heavy = write_urdf(BodyParams.patient_default(thigh_mass=22.6), tmp_path / "heavy.urdf")
    truth = simulate(SimConfig(controller="ct", belief=Belief("truth"), **SHORT))
    nominal = simulate(SimConfig(controller="ct", belief=Belief(patient="nominal"), **SHORT))
    wrong = simulate(SimConfig(controller="ct", belief=Belief(patient=str(heavy)), **SHORT))
    pd = simulate(SimConfig(**SHORT))
    print(
        f"\nRMS error [mrad] hip/knee: CT truth {np.round(1e3 * _rms(truth)[:2], 3)}, "
        f"CT nominal {np.round(1e3 * _rms(nominal)[:2], 3)}, CT with 2x thigh mass "
        f"{np.round(1e3 * _rms(wrong)[:2], 3)}, PD {np.round(1e3 * _rms(pd)[:2], 3)}; "
        f"feedforward gap nominal-truth up to {gap.max():.1f} N·m"
    )
    assert nominal.status == truth.status == wrong.status == "completed"
    assert np.all(_rms(nominal) < 1.5 * _rms(truth))
    assert _rms(wrong)[0] > 2.0 * _rms(truth)[0]  # the hip carries the thigh
    assert np.all(_rms(nominal) < 0.1 * _rms(pd))


def test_a_patient_model_file_is_what_the_device_holds(tmp_path: Path) -> None:
    heavy = write_urdf(BodyParams.patient_default(thigh_mass=14.0), tmp_path / "heavy.urdf")
    setup = build(SimConfig(controller="ct", belief=Belief(patient=str(heavy))))
    assert _thigh_mass(setup.device_patient) == pytest.approx(14.0, rel=1e-12)
    assert _thigh_mass(setup.patient) == pytest.approx(11.3, rel=1e-12)


def test_a_nominal_model_of_another_patient_reads_what_is_not_given(tmp_path: Path) -> None:
    other = write_urdf(BodyParams.patient_default(thigh_mass=9.0), tmp_path / "other.urdf")
    setup = build(SimConfig(patient=str(other), belief=Belief(patient="nominal")))
    # de Leva's male leg share (thigh 14.16 %, leg 4.33 %, foot 1.37 % of the body, per leg)
    mass = setup.patient.mass / (2 * (0.1416 + 0.0433 + 0.0137))
    assert setup.patient.mass == pytest.approx(2 * (9.0 + 4.65), rel=1e-9)
    assert _thigh_mass(setup.device_patient) == pytest.approx(0.1416 * mass, rel=1e-9)
    leg = setup.patient.legs["left"]
    height = (leg.thigh_length + leg.shank_length) / ((0.4222 + 0.4340) / 1.741 + 0.039)
    assert setup.warnings == (
        f"the nominal patient's stature, {height:.3f} m, is the one whose de Leva thigh and "
        "shank make the patient URDF's 1.040 m leg (belief.patient_height_m sets it)",
        f"the nominal patient's body mass, {mass:.1f} kg, is the patient URDF's 27.30 kg of "
        "legs over de Leva's leg share (belief.patient_mass_kg sets it)",
    )
    with pytest.raises(InvalidParameter, match="patient_height must be given for a nominal"):
        build(SimConfig(patient="human", belief=Belief(patient="nominal")))
    setup = build(
        SimConfig(
            patient=str(other),
            belief=Belief(patient="nominal", patient_height_m=1.6, patient_mass_kg=60.0),
        )
    )
    assert _thigh_mass(setup.device_patient) == pytest.approx(0.1416 * 60.0, rel=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"patient_sex": "x"}, "patient_sex must be one of female, male; got 'x'"),
        ({"patient_mass_kg": -3.0}, "patient_mass must be > 0 kg; got -3.0"),
        ({"patient": ""}, "controller_patient must be truth, nominal or a URDF path; got ''"),
        (
            {"knee_fit_tolerance_m": 0.2},
            "belief knee_fit_tolerance_m must be in [0, 0.1] m; got 0.2",
        ),
        (
            {"knee_fit_tolerance_m": -0.01},
            "belief knee_fit_tolerance_m must be in [0, 0.1] m; got -0.01",
        ),
    ],
)
def test_bad_beliefs_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        Belief(**kwargs)
    assert str(info.value) == message


def test_the_cli_runs_a_nominal_model_and_refuses_a_missing_file(tmp_path: Path, capsys) -> None:
    argv = ["simulate", "--duration", "0.3", "--no-record", "--controller", "ct"]
    assert cli.main([*argv, "--controller-patient", "nominal"]) == 0
    capsys.readouterr()
    missing = tmp_path / "none.urdf"
    assert cli.main([*argv, "--controller-patient", str(missing)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("exo-ctrl simulate: error: ") and str(missing) in err
    assert err.count("\n") == 1


def test_the_belt_monitor_holds_the_treadmills_datasheet_not_the_belt() -> None:
    """The supervisor predicts the belt with the datasheet the device holds (Belief.belt).

    The truth's belt (20 kg) under a device told it weighs half that: the monitor's record
    holds 1/10 kg⁻¹ while the plant moves 20 kg; on a supported-pelvis run the feet's
    friction (hundreds of newtons) is then predicted to move the belt twice as fast as it
    does, and the monitor, quiet with the right datasheet, trips on the healthy run.
    """

    def run(belief: Belief) -> tuple[Runner, dict]:
        config = SimConfig(
            controller="ct",
            contact=ContactParams(enabled=True),
            pelvis=PelvisParams(supported=True, bws_fraction=0.5),
            gait=GaitParams(hip_height=1.0, pelvis_excursion=0.05),
            sync=True,
            duration_s=3.0,
            belief=belief,
        )
        runner = Runner(build(config))
        return runner, simulate(config).summary()

    true_mass = BeltParams().mass_kg
    light = Belief(belt=BeltParams(mass_kg=0.5 * true_mass))
    runner, wrong = run(light)
    assert runner.supervisor._belt[3]["inv_m"][0] == pytest.approx(2.0 / true_mass, rel=1e-15)
    assert runner.setup.plant.contact.belt["mass"][0] == pytest.approx(true_mass)
    _, right = run(Belief())
    assert right["safety_state"] == "normal" and right["device_belief"]["belt"] == "datasheet"
    assert wrong["device_belief"]["belt"] == "given"
    assert wrong["safety_state"] != "normal"
    assert "belt" in wrong["safety_events"][0]["message"]


def test_the_loading_plan_sinks_the_feet_by_the_soles_the_device_holds() -> None:
    """The plan's stance sink uses Belief.soles (the datasheet), not the plant's contact law.

    A true sole twice as stiff as its datasheet: the plan still sinks each foot
    standing by s₀ = (W₀ / 2k)^{1/n} with the datasheet's k, while the plant's
    contact holds the true k; a device told the true k plans 2^{-1/n} of that.
    """
    base = SimConfig(
        controller="ct",
        contact=ContactParams(enabled=True, stiffness_N_per_m_n=1.0e6),
        pelvis=PelvisParams(supported=True, bws_fraction=0.5),
        gait=GaitParams(hip_height=1.0, duty_factor=0.6),
        sync=False,
        duration_s=3.0,
    )
    datasheet = dataclasses.replace(base, belief=Belief(soles=(5.0e5, 1.5)))
    told = dataclasses.replace(base, belief=Belief(soles=(1.0e6, 1.5)))
    exo = build(base).device_exo
    sink, sink_true = stance_sink_for(datasheet, exo), stance_sink_for(told, exo)
    assert stance_sink_for(base, exo) == sink_true  # by default: the installed soles' law
    assert sink.stiffness_N_per_m_n == 5.0e5 and sink.weight_N == sink_true.weight_N > 0.0
    w0 = sink.weight_N
    assert sink.standing_sink_m == pytest.approx((0.5 * w0 / 5.0e5) ** (1 / 1.5), rel=1e-12)
    ratio = sink_true.standing_sink_m / sink.standing_sink_m
    assert ratio == pytest.approx(2.0 ** (-1 / 1.5), rel=1e-12)
    run = build(datasheet)
    assert run.plant.contact.params.stiffness_N_per_m_n == 1.0e6  # the truth is unchanged
    assert np.max(np.abs(run.plan.q - build(told).plan.q)) > 1e-4  # the plan is not
    assert simulate(datasheet).summary()["device_belief"]["soles"] == "given"


@pytest.mark.parametrize(
    ("soles", "message"),
    [
        ((0.0, 1.5), "belief sole stiffness must be > 0 N/m^n; got 0.0"),
        ((5e5, 0.5), "belief sole exponent must be >= 1; got 0.5"),
        ((5e5,), "belief soles must be a pair (k [N/m^n] > 0, n >= 1) or None; got (500000.0,)"),
    ],
)
def test_bad_sole_beliefs_are_refused(soles: tuple, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        Belief(soles=soles)
    assert str(info.value) == message
