"""The torque-sensor consistency check: its maths, its threshold, no false alarm, the campaign.

- The kernel against the recursion written out: at constant speed and current
  r_k = (1 − KΔt) r_{k−1} + KΔt (τ_s,k − τ_m), so a bias b gives
  r_n = b (1 − (1 − KΔt)^n) and a drift ρ its discrete ramp response.
- The limit T is six standard deviations of r under the sensors' noise: the
  standard deviation measured over 60 000 noisy ticks is σ_r = T/6 within 5 %.
- The model bound B: ε |τ_m| away from a speed reversal, plus the gear
  factor's span |η^{s(+δω)} − η^{s(−δω)}| i_G k_m |I| at standstill.
- No false alarm on the default runs (PD, CT, QP; the active patient in every
  interaction mode; the belt; body-weight support): |r| − B < T at every tick,
  read from the supervisor's own record.
- The campaign's drifting torque sensor in transparent mode (tools/faults.py's
  API): detected by this check within t_d ≤ 2 (B + T)/ρ + 1/K (B the largest
  bound before the detection), and the true cuff forces after the stop within
  ISO/TS 15066 (220 N thigh, 130 N shank); the same for the slipped shank cuff,
  whose free exoskeleton knee leaves its range and is braked alone, outward.
"""

from __future__ import annotations

import math

import fault_campaign as campaign  # tools/faults.py, loaded by tests/conftest.py
import numpy as np
import pytest

from exo_ctrl import simulate
from exo_ctrl.estimation.cuff_geometry import CuffGeometry
from exo_ctrl.model import JOINT_NAMES
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import CompliantJoint, ContactParams, MotorParams, PelvisParams
from exo_ctrl.plant.drive import EFFICIENCY_SMOOTHING_RAD_S
from exo_ctrl.plant.motor import drive_model, steady_voltage
from exo_ctrl.safety import (
    ISO_TS_15066_CUFF_FORCE_N,
    ResolvedLimits,
    SafetyLimits,
    SafetySupervisor,
    monitor_record,
)
from exo_ctrl.safety.consistency import (
    CONSIST,
    NOISE_SIGMAS,
    OBSERVER_GAIN_PER_S,
    PERSIST_TICKS,
    TORQUE_MODEL_TOLERANCE,
    consistency,
    consistency_limit,
    consistency_threshold,
    detection_bound_s,
)
from exo_ctrl.safety.plausibility import plausibility_record
from exo_ctrl.safety.stop_reaction import (
    PATIENT_ACCELERATION_RAD_S2,
    YIELD_FORCE_SHARE,
    YieldCommand,
    yield_breach,
)
from exo_ctrl.sensing import CurrentSensorParams, SensorParams
from exo_ctrl.sim import SimConfig, build
from exo_ctrl.sim.tick import Runner

DT = 1e-3
MOTOR = MotorParams()
KT = MOTOR.torque_per_amp_Nm_per_A
ETA = MOTOR.gear_efficiency
GAIN = OBSERVER_GAIN_PER_S
A = 1.0 - GAIN * DT
LIMITS = ResolvedLimits(*(np.full(4, 1e9) for _ in range(5)))
THIGH, SHANK = ISO_TS_15066_CUFF_FORCE_N[0], ISO_TS_15066_CUFF_FORCE_N[1]
T_DEFAULT = consistency_threshold(MOTOR, SensorParams(), DT)


def fresh(sensors: SensorParams | None = None) -> tuple[np.ndarray, np.ndarray]:
    sensors = sensors if sensors is not None else SensorParams()
    mon = monitor_record(LIMITS, math.inf)
    mon["limit"][0][CONSIST] = consistency_limit(MOTOR, sensors, DT)
    return plausibility_record(MOTOR, sensors, DT), mon


def moving(n: int, speed: float, current: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """n ticks at a constant speed [rad/s] and current [A]: angles, torque readings, currents.

    The torque reading is the drive's, η^s i_G k_m I, with s = ±1 (|speed| ≫ ω_η).
    """
    q = 0.3 + speed * DT * np.arange(n)[:, None] * np.ones(4)
    gear = ETA ** (np.sign(speed) * np.sign(current))
    tau = np.full((n, 4), gear * KT * current)
    return q, tau, np.full((n, 4), current)


def run(q, tau, i, speed, state, mon) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kernel over the rows; r, B and the excess per tick."""
    n = q.shape[0]
    r, b, e = np.zeros((n, 4)), np.zeros((n, 4)), np.zeros((n, 4))
    dq = np.full(4, speed)
    for k in range(n):
        consistency(q[k], dq, tau[k], i[k], state, mon)
        r[k], b[k], e[k] = state["c_r"][0], state["c_bound"][0], mon["excess"][0][CONSIST]
    return r, b, e


def test_a_bias_and_a_drift_pass_through_the_discrete_lag() -> None:
    n, k0 = 400, 100
    q, tau, i = moving(n, 0.8, 6.0)
    r, b, _ = run(q, tau, i, 0.8, *fresh(SensorParams.ideal()))
    np.testing.assert_allclose(r, 0.0, atol=1e-9)  # consistent readings: r = 0
    # B: ε |τ_m| through the lag 1 - exp(-KΔt) per tick, no gear span at 0.8 rad/s.
    lag = 1.0 - math.exp(-GAIN * DT)
    expected = TORQUE_MODEL_TOLERANCE * ETA * KT * 6.0 * (1.0 - (1.0 - lag) ** np.arange(1, n + 1))
    np.testing.assert_allclose(b[:, 0], expected, rtol=1e-12)
    bias = 20.0
    biased = tau.copy()
    biased[k0:] += bias
    r, _, _ = run(q, biased, i, 0.8, *fresh(SensorParams.ideal()))
    steps = np.arange(1, n - k0 + 1)
    np.testing.assert_allclose(r[k0:, 1], bias * (1.0 - A**steps), rtol=1e-9)
    rate = 100.0
    drifted = tau.copy()
    drifted[k0:] += rate * DT * np.arange(n - k0)[:, None]
    r, _, _ = run(q, drifted, i, 0.8, *fresh(SensorParams.ideal()))
    ref = np.zeros(n)
    for k in range(k0, n):
        ref[k] = A * ref[k - 1] + GAIN * DT * rate * (k - k0) * DT
    np.testing.assert_allclose(r[:, 2], ref, rtol=1e-9, atol=1e-9)
    # The ramp response stays within the bound's premise: r ≥ ρ (t - 1/K) for t ≥ 1/K.
    t = (np.arange(n) - k0) * DT
    late = t >= 1.0 / GAIN
    assert np.all(ref[late] >= rate * (t[late] - 1.0 / GAIN) - 1e-9)


def test_a_drift_is_detected_within_its_bound() -> None:
    """With the default sensors' noise: the first excess > 0 after the onset, within
    2 (B + T)/ρ + 1/K, and none before it."""
    n, k0, rate = 1500, 500, 100.0
    rng = np.random.default_rng(7)
    sensors, cur = SensorParams(), CurrentSensorParams()
    q, tau, i = moving(n, -0.6, 5.0)
    q = q + rng.standard_normal(q.shape) * sensors.encoder_noise_std_rad
    q = np.rint(q / sensors.encoder_resolution_rad) * sensors.encoder_resolution_rad
    tau = tau + rng.standard_normal(tau.shape) * sensors.torque_noise_std_Nm
    i = np.rint((i + rng.standard_normal(i.shape) * cur.noise_std_A) / cur.resolution_A)
    i = i * cur.resolution_A
    tau[k0:] += rate * DT * np.arange(n - k0)[:, None]
    state, mon = fresh(sensors)
    _, b, e = run(q, tau, i, -0.6, state, mon)
    assert np.all(e[50:k0] <= 0.0)
    for j in range(4):
        first = k0 + int(np.argmax(e[k0:, j] > 0.0))
        assert e[first, j] > 0.0
        bound = detection_bound_s(rate, float(b[k0 : first + 1, j].max()), T_DEFAULT)
        assert 0.0 < (first - k0) * DT <= bound, (j, first - k0, bound)


def test_a_late_frame_is_two_ticks_of_excess_and_no_violation() -> None:
    """One joint-sensor frame held a tick (the current fresh): r jumps by K J_eff ω for two
    ticks, beyond T, short of the PERSIST_TICKS (3) in a row of a violation; a frame held
    two ticks (three ticks of excess) is one."""
    speed = 1.5
    jeff = float(fresh()[0]["c_jeff"][0])
    assert GAIN * jeff * speed > 3.0 * T_DEFAULT  # the jump is well beyond T
    for held in (1, 2):
        q, tau, i = moving(300, speed, 5.0)
        q[200 : 200 + held] = q[199]
        tau[200 : 200 + held] = tau[199]
        state, mon = fresh()
        r, b, e = run(q, tau, i, speed, state, mon)
        beyond = np.abs(r[:, 0]) - b[:, 0] > T_DEFAULT
        assert beyond.sum() == held + 1 and beyond[200 : 201 + held].all()
        assert bool(np.any(e[:, 0] > 0.0)) == (held + 1 >= PERSIST_TICKS)


def test_the_limit_is_six_sigmas_of_the_noise_it_leaves_in_r() -> None:
    """σ_r measured over 60 000 ticks of noisy readings equals T/6 within 5 %."""
    n = 60_000
    rng = np.random.default_rng(3)
    sensors, cur = SensorParams(), CurrentSensorParams()
    q, tau, i = moving(n, 1.0, -4.0)  # braking: the gear factor is 1/η
    q = q + rng.standard_normal(q.shape) * sensors.encoder_noise_std_rad
    q = np.rint(q / sensors.encoder_resolution_rad) * sensors.encoder_resolution_rad
    tau = tau + rng.standard_normal(tau.shape) * sensors.torque_noise_std_Nm
    tau = np.rint(tau / sensors.torque_resolution_Nm) * sensors.torque_resolution_Nm
    i = np.rint((i + rng.standard_normal(i.shape) * cur.noise_std_A) / cur.resolution_A)
    i = i * cur.resolution_A
    r, _, _ = run(q, tau, i, 1.0, *fresh(sensors))
    sigma = r[1000:].std()
    assert sigma == pytest.approx(T_DEFAULT / NOISE_SIGMAS, rel=0.05)


def test_the_bound_widens_by_the_gear_factors_span_at_standstill() -> None:
    n, current = 600, 5.0
    q = np.full((n, 4), 0.4)
    tau = np.full((n, 4), KT * current)  # at ω = 0 the gear factor is 1
    state, mon = fresh()
    _, b, _ = run(q, tau, np.full((n, 4), current), 0.0, state, mon)
    dw = float(state["c_dw"][0])
    th = math.tanh(dw / EFFICIENCY_SMOOTHING_RAD_S)
    span = ETA**-th - ETA**th
    settled = (span + TORQUE_MODEL_TOLERANCE) * KT * current
    assert b[-1, 0] == pytest.approx(settled, rel=1e-6)
    assert span > 0.3  # near a reversal the gearbox may pass η or 1/η


def test_the_check_is_off_where_its_model_does_not_hold() -> None:
    big = np.finfo(float).max
    assert consistency_limit(MOTOR, SensorParams(), DT)[0] == pytest.approx(T_DEFAULT)
    assert np.all(consistency_limit(MOTOR, SensorParams(), 2e-3) == big)
    assert np.all(consistency_limit(MOTOR, SensorParams(sample_rate_hz=250.0), DT) == big)
    assert np.all(consistency_limit(MOTOR, SensorParams.ideal(), DT) == big)
    setup = build(SimConfig(duration_s=0.01))
    compliant = SafetySupervisor(
        SafetyLimits(),
        setup.exo,
        setup.patient,
        setup.device_motor,
        DT,
        compliant_drives=True,
    )
    assert np.all(compliant.record["limit"][0][CONSIST] == big)


def trace(config: SimConfig) -> tuple[np.ndarray, np.ndarray, float, list, object]:
    """Run ``config`` tick by tick; the supervisor's r and B per tick, T, its events, runner."""
    runner = Runner(build(config))
    sup = runner.supervisor
    rec = sup.plausibility_record
    n = config.n_ticks
    r, b = np.zeros((n, 4)), np.zeros((n, 4))
    for k in range(n):
        runner.tick(k, k % runner.chunk)
        r[k], b[k] = rec["c_r"][0], rec["c_bound"][0]
    return r, b, float(sup.record["limit"][0][CONSIST, 0]), sup.events, runner


ON = ContactParams(enabled=True)
ACTIVE = {"patient_torque": "active"}
BWS = {
    "controller": "ct",
    "contact": ON,
    "sync": False,
    "gait": GaitParams(hip_height=1.0, pelvis_excursion=0.05),
    "pelvis": PelvisParams(supported=True, bws_fraction=0.5),
}
CLEAN = {
    "pd": {},
    "ct": {"controller": "ct"},
    "qp": {"controller": "qp"},
    "pd-contact": {"contact": ON},
    "qp-contact": {"controller": "qp", "contact": ON},
    "transparent": {"mode": "transparent", **ACTIVE},
    "transparent-contact": {"mode": "transparent", "contact": ON, **ACTIVE},
    "guidance": {"mode": "guidance", **ACTIVE},
    "aan": {"mode": "aan", **ACTIVE},
    "path": {"mode": "path", **ACTIVE},
    "bws": BWS,
}


@pytest.mark.parametrize("name", list(CLEAN))
def test_no_false_alarm_on_the_default_runs(name) -> None:
    r, b, limit, events, _ = trace(SimConfig(**CLEAN[name]))
    assert limit == pytest.approx(T_DEFAULT)
    margin = np.abs(r) - b
    print(f"\n{name}: max |r| - B = {margin.max():.2f} N·m, T = {limit:.2f} N·m")
    assert margin.max() < limit
    assert not [e for e in events if str(e.get("quantity", "")).startswith("torque sensor vs")]


@pytest.fixture(scope="module")
def transparent_reference():
    return simulate(SimConfig(mode="transparent", **ACTIVE))


@pytest.mark.parametrize("seed", [0, 1])  # a knee and a hip
def test_the_campaigns_drifting_torque_sensor_in_transparent(seed, transparent_reference) -> None:
    fault = campaign.plan_fault("torque_drift", seed)
    rate = float(fault.magnitude)
    result = campaign.run_fault(fault, mode="transparent", reference=transparent_reference)
    assert result.detected and result.channel == f"torque sensor vs current {fault.target}"
    # The bound from the supervisor's own B over [onset, detection].
    config = SimConfig(mode="transparent", faults=(fault,), **ACTIVE)
    _, b, limit, _, _ = trace(config)
    j = JOINT_NAMES.index(fault.target)
    k0 = round(fault.at_s / DT)
    k1 = k0 + round(result.detection_s / DT)
    bound = detection_bound_s(rate, float(b[k0 : k1 + 1, j].max()), limit)
    print(
        f"\n{fault.label}: detected after {1e3 * result.detection_s:.0f} ms (bound "
        f"{1e3 * bound:.0f} ms, offset {rate * result.detection_s:.1f} N·m); after the stop "
        f"{result.thigh_after_stop_N:.0f} N thigh, {result.shank_after_stop_N:.0f} N shank"
    )
    assert result.detection_s > 0.0  # the offset builds through the lag
    assert result.detection_s <= bound + 1e-9
    assert result.reaction == "yield"
    assert result.thigh_after_stop_N <= THIGH and result.shank_after_stop_N <= SHANK
    assert result.worst_thigh_N <= THIGH and result.worst_shank_N <= SHANK


def test_the_campaigns_slipped_shank_cuff_in_transparent(transparent_reference) -> None:
    """The free exoskeleton knee leaves its range (the slip is not seen otherwise: the mode
    drives that cuff's force to zero whether it is on or not); the yield brakes that knee
    alone, outward, stops carrying the patient's shank, and the thigh cuff the patient walks
    on with stays within 220 N.  Seeds 0–3 (the shank cuffs; where the knee leaves its range
    within the run)."""
    stopped = []
    for seed in range(4):
        fault = campaign.plan_fault("cuff_slip", seed)
        result = campaign.run_fault(fault, mode="transparent", reference=transparent_reference)
        if not result.detected:
            assert result.state == "normal"
            continue
        knee = fault.target.replace("shank", "knee")
        assert result.channel == f"angle {knee}"
        assert result.reaction == "yield" and result.state in ("stopping", "yielding")
        assert result.thigh_after_stop_N <= THIGH and result.shank_after_stop_N <= SHANK
        stopped.append((fault, knee))
    assert stopped
    fault, knee = stopped[0]
    _, _, _, events, runner = trace(SimConfig(mode="transparent", faults=(fault,), **ACTIVE))
    braked = [e for e in events if e["quantity"] == f"yield angle {knee}"]
    assert len(braked) == 1 and "braked outward" in braked[0]["message"]
    assert not [e for e in events if e["kind"] == "state" and e["value"] == "power_cut"]
    # The shank the knee carried is dropped from the yield's patient model, the rest kept.
    cmd = runner.supervisor.yield_command
    model = cmd._patient[0]
    j = JOINT_NAMES.index(knee)
    masses = [model.inertias[i].mass for i in range(1, model.njoints)]
    shank = runner.setup.device_patient.joint_ids[j]
    assert model.inertias[shank].mass == 0.0 and sum(m > 0.0 for m in masses) == 3


def test_a_joint_out_of_range_is_braked_outward_only() -> None:
    setup = build(SimConfig(duration_s=0.01))
    damping = np.full(4, 5.0)
    cmd = YieldCommand(
        setup.device_exo, setup.device_patient, setup.device_motor, damping, np.full(4, 6.0), DT
    )
    lo, hi = np.zeros(4), np.full(4, 1.0)
    q = np.array([0.5, 1.2, 0.5, -0.1])  # the left knee above, the right knee below
    brake = setup.device_motor.torque_per_amp_Nm_per_A * (
        setup.device_motor.back_emf_V_per_rad_s / setup.device_motor.resistance_ohm
    )
    drive = drive_model(setup.device_motor)
    for speed, outward in ((0.4, True), (-0.4, False)):  # left knee: out, then back in
        cmd.start(q, np.array([0.0, speed, 0.0, -speed]))
        out = cmd.command(q, np.zeros(4))
        free = out.copy()
        events = cmd.brake_outside(q, lo, hi, out)
        assert [e[0] for e in events] == ["yield angle left_knee", "yield angle right_knee"]
        assert cmd.brake_outside(q, lo, hi, out.copy()) == []  # logged once per yield
        np.testing.assert_array_equal(out[[0, 2]], free[[0, 2]])  # the hips still yield
        for j in (1, 3):
            w = cmd.speed[j]
            expected = steady_voltage(cmd.torque[j] - brake * w, w, drive) if outward else free[j]
            assert out[j] == pytest.approx(expected, rel=1e-12)
    fast = yield_breach(np.array([1.0, 7.0, 0.0, 0.0]), np.full(4, 6.0))
    assert fast is not None and fast[0] == "yield speed left_knee"
    assert yield_breach(np.ones(4), np.full(4, 6.0)) is None


def test_compliant_joints_and_their_runs_trip_nothing() -> None:
    """The compliant joints' spring breaks the rigid relation; the check is off there."""
    _, _, limit, events, _ = trace(
        SimConfig(joint_compliance=CompliantJoint(enabled=True), duration_s=1.5)
    )
    assert limit > 1e300
    assert not [e for e in events if e["kind"] == "violation"]


def test_the_yields_ramp_keeps_the_held_voltages_pull_within_the_dampings_share() -> None:
    """T_y = min 4 d_y ω_max / (D q̈_p): the held voltage's pull (1 − α) D (ω − ω_0) peaks at
    D q̈_p T_y / 4 = d_y ω_max = σ F_lim r at a joint; the supervisor's ramp to a yield lasts
    T_y (its "ramp done" T_y after the stop), to a hold ramp_s."""
    setup = build(SimConfig(duration_s=0.01))
    motor = setup.device_motor
    d = motor.torque_per_amp_Nm_per_A * motor.back_emf_V_per_rad_s / motor.resistance_ohm
    geo = CuffGeometry.from_body(setup.device_exo)
    arms = np.array([geo.thigh_arm[0], geo.shank_arm[0], geo.thigh_arm[1], geo.shank_arm[1]])
    budget = YIELD_FORCE_SHARE * np.array(ISO_TS_15066_CUFF_FORCE_N) * arms  # σ F_lim r
    expected = float(np.min(4.0 * budget / (d * PATIENT_ACCELERATION_RAD_S2)))
    sup = SafetySupervisor(
        SafetyLimits(), setup.exo, setup.patient, motor, DT, estop_at_s=0.0, stop_reaction="yield"
    )
    assert sup.yield_command.ramp_s == pytest.approx(expected, rel=1e-12)
    assert 0.005 < expected < sup.ramp_s  # some ticks, shorter than the hold's 0.2 s
    for reaction, ramp in (("yield", expected), ("hold", sup.ramp_s)):
        config = SimConfig(estop_at_s=0.3, duration_s=0.6, stop_reaction=reaction)
        *_, events, _ = trace(config)
        done = next(e for e in events if e["kind"] == "state" and "ramp done" in e["message"])
        assert done["t"] - 0.3 == pytest.approx(math.ceil(ramp / DT - 1e-9) * DT, abs=1e-9)
