"""The QP controller: the soft bound, force feedback, limits and fallbacks, CT equivalence.

Every check is against something computed independently of the code under
test: the controller's soft problem against the one assembled in the
tests' conftest from the cuff model's A and b (and against scipy's
SLSQP and linprog), the limits against the motor equations written
out here (the closed loop: test_closed_loop.py).

The penalty is quadratic, so a binding cuff row always leaves s_c = λ_c / ρ
> 0 (λ_c the row's multiplier): "s = 0 when the torques can meet the bound"
holds only up to that, and is asserted as such (s_c < 0.2 N, measured).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import LinearConstraint, linprog, minimize

from exo_ctrl.control import ComputedTorqueController, SensorReadings
from exo_ctrl.control.qp import (
    CuffHorizonModel,
    CuffKnowledge,
    QPController,
)
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyModel
from exo_ctrl.plant.drive import MotorParams
from exo_ctrl.plant.motor import MotorBank
from exo_ctrl.sim import drive_for

#: ρ, the brief's slack weight [(N·m)²/N²].
RHO = 1e4
#: URDF effort of every joint [N·m].
EFFORT = 150.0


def test_a_generous_limit_leaves_zero_slack_and_the_commanded_torque(
    exo, patient, motor, plan, near_plan
) -> None:
    ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=1e6)
    rng = np.random.default_rng(21)
    for k in range(0, 1200, 60):
        ctrl.command(k, near_plan(plan, rng, k, q_noise=1e-4, dq_noise=1e-3))
        assert ctrl.last_status == "solved", ctrl.last_status
        assert np.all(ctrl.slack <= 1e-9)
        np.testing.assert_allclose(ctrl.torque, ctrl.torque_cmd, atol=1e-6, rtol=0)
    assert ctrl.failures == 0


def test_a_tight_limit_the_torques_can_meet_puts_the_force_on_the_polygon(
    exo, patient, motor, plan, on_plan, soft_problem, assert_is_the_soft_optimum
) -> None:
    """F_max = 60 N on the plan (CT's predicted peak 93.8 N): every solved tick is the optimum.

    A fresh (cold) controller per tick.  Some of these cold solves fail
    (solver tolerance); they are counted, checked
    to be solver fallbacks, and printed.
    """
    binding = fallbacks = 0
    slack_max = 0.0
    for k in range(0, 1200, 5):
        ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=60.0, tighten=False)
        ctrl.command(k, on_plan(plan, k))
        if ctrl.last_status != "solved":
            assert ctrl.last_status.startswith("fallback: τ_cmd clipped to the torque box")
            fallbacks += 1
            continue
        problem = soft_problem(ctrl)
        assert_is_the_soft_optimum(ctrl, problem)
        if problem.edge_excess(ctrl.torque_cmd).max() <= 0.0:
            np.testing.assert_array_equal(ctrl.slack, 0.0)
            continue
        # The bound binds, and a torque in the box meets the octagon (an LP says so).
        res = linprog(
            np.zeros(4),
            A_ub=problem.C[:, :4],
            b_ub=problem.upper,
            bounds=list(zip(ctrl.torque_lo, ctrl.torque_hi, strict=True)),
        )
        assert res.status == 0
        binding += 1
        assert np.abs(ctrl.torque - ctrl.torque_cmd).max() > 0.01
        # Quadratic penalty: s_c = λ_c / ρ, small but not zero where the bound
        # binds, and the predicted force sits on the octagon widened by s_c.
        assert np.all(ctrl.slack < 0.2)
        slack_max = max(slack_max, ctrl.slack.max())
        on_edge = ctrl.slack > 1e-6
        assert on_edge.any()
        np.testing.assert_allclose(
            problem.edge_excess(ctrl.torque)[on_edge], ctrl.slack[on_edge], atol=1e-6
        )
        f = np.linalg.norm(ctrl.cuff_force_pred, axis=2).max(axis=0)
        assert np.all(f <= (problem.radius + ctrl.slack) / math.cos(math.pi / 8) + 1e-6)
    print(
        f"\nF_max = 60 N on the plan: {binding} binding ticks of 48, largest slack "
        f"{slack_max:.4f} N; {fallbacks} cold solves fell back"
    )
    assert binding >= 5  # measured 8 (the horizon model at fitted cuffs, on the plan)


def weak_exo(exo: BodyModel, effort: float) -> BodyModel:
    weak = dataclasses.replace(exo, model=pin.Model(exo.model))
    weak.model.effortLimit = np.full(4, effort)
    return weak


@pytest.mark.parametrize(
    ("effort", "limit", "k", "n_inside"),
    [
        (1.0, 1.0, 0, 0),  # every torque at the box
        # k = 299, the tick before the right foot's lift-off (k = 300 was used before the
        # lift-off blend, control/lift_off.py: at the lift-off rows 300 and 900 the blended
        # command now needs more screening rounds than SCREEN_ROUNDS under these bounds)
        (5.0, 0.5, 299, 0),
        (60.0, 1.0, 299, 1),  # one torque inside the box
    ],
    ids=["1 N·m/1 N", "5 N·m/0.5 N", "60 N·m/1 N"],
)
def test_a_limit_the_torque_box_cannot_meet_is_softened_not_a_fallback(
    exo,
    patient,
    motor,
    plan,
    effort,
    limit,
    k,
    n_inside,
    on_plan,
    soft_problem,
    assert_is_the_soft_optimum,
) -> None:
    """Drives too weak (URDF effort cut to 1, 5 or 60 N·m) to keep the cuffs within F_max."""
    ctrl = QPController(
        plan, weak_exo(exo, effort), patient, motor, cuff_force_limit_N=limit, tighten=False
    )
    u = ctrl.command(k, on_plan(plan, k))
    problem = soft_problem(ctrl)
    # Independent confirmation that no torque in the box meets the octagon.
    res = linprog(
        np.zeros(4),
        A_ub=problem.C[:, :4],
        b_ub=problem.upper,
        bounds=list(zip(ctrl.torque_lo, ctrl.torque_hi, strict=True)),
    )
    assert res.status == 2  # infeasible
    assert ctrl.failures == 0 and ctrl.last_status == "solved"
    assert np.all(np.isfinite(u))
    assert ctrl.slack.max() > 0.1
    assert np.all(ctrl.torque >= -effort) and np.all(ctrl.torque <= effort)
    inside = (ctrl.torque > ctrl.torque_lo + 1e-3) & (ctrl.torque < ctrl.torque_hi - 1e-3)
    assert inside.sum() == n_inside
    assert_is_the_soft_optimum(ctrl, problem)
    # And scipy's SLSQP (another method: sequential least squares, with its
    # own active set) on the same problem, slack scaled to σ = √ρ s, started
    # from a feasible point of the problem's own data (τ_cmd clipped into the
    # box, each slack 1 N above its cuff's largest excess there): 9-11
    # iterations, and it stops on its line search (status 8) with the answer
    # within 5e-7 of the controller's, so its answer is compared, not its status.
    scale = math.sqrt(RHO)
    c_scaled = problem.C / np.concatenate((np.ones(4), np.full(4, scale)))
    tc = ctrl.torque_cmd.copy()
    tau0 = np.clip(tc, ctrl.torque_lo, ctrl.torque_hi)
    excess = problem.C[:, :4] @ tau0 - problem.upper
    uses = problem.C[:, 4:] < 0  # row r bounds cuff c's force: its slack enters
    s0 = np.array([max(0.0, excess[uses[:, c]].max()) + 1.0 for c in range(4)])
    sol = minimize(
        lambda z: 0.5 * ((z[:4] - tc) @ (z[:4] - tc) + z[4:] @ z[4:]),
        np.concatenate((tau0, scale * s0)),
        jac=lambda z: np.concatenate((z[:4] - tc, z[4:])),
        bounds=list(zip(ctrl.torque_lo, ctrl.torque_hi, strict=True)) + [(0.0, np.inf)] * 4,
        constraints=[LinearConstraint(c_scaled, -np.inf, problem.upper)],
        method="SLSQP",
        options={"ftol": 1e-12, "maxiter": 1000},
    )
    print(
        f"\neffort {effort:g} N·m, F_max {limit:g} N: τ {np.round(ctrl.torque, 3)} N·m, "
        f"slack {np.round(ctrl.slack, 4)} N, {inside.sum()} inside the box; SLSQP Δτ "
        f"{np.abs(sol.x[:4] - ctrl.torque).max():.1e}"
    )
    np.testing.assert_allclose(ctrl.torque, sol.x[:4], atol=1e-6, rtol=0)
    np.testing.assert_allclose(ctrl.slack, sol.x[4:] / scale, atol=1e-5, rtol=0)


def test_controller_qps_are_soft_optima_near_the_plan(
    exo, patient, motor, plan, near_plan, soft_problem, assert_is_the_soft_optimum
) -> None:
    """The controller's own instances (real cuff rows, a 40 N bound) pass the KKT check."""
    rng = np.random.default_rng(5)
    ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=40.0, tighten=False)
    binding = 0
    for k in rng.integers(0, plan.q.shape[0], 150):
        ctrl.command(int(k), near_plan(plan, rng, int(k), dq_noise=0.5))
        assert ctrl.last_status == "solved", ctrl.last_status
        assert_is_the_soft_optimum(ctrl, soft_problem(ctrl))
        binding += ctrl.slack.max() > 0.0
    assert binding > 20


def test_without_a_force_estimate_the_prediction_starts_from_fitted_cuffs(
    exo, patient, motor, plan, on_plan, soft_problem, assert_is_the_soft_optimum
) -> None:
    for feedback, est in (
        (False, np.full((4, 2), 30.0)),
        (True, None),
        (True, np.array([[np.nan, 0.0]] + [[0.0, 0.0]] * 3)),
    ):
        ctrl = QPController(
            plan,
            exo,
            patient,
            motor,
            cuff_force_limit_N=80.0,
            force_feedback=feedback,
            tighten=False,
        )
        ctrl.command(300, on_plan(plan, 300, est))
        assert ctrl.last_status == "solved" and ctrl.failures == 0
        ref = CuffHorizonModel(exo, patient, motor)
        ref.update(plan.q[300], plan.dq[300], np.zeros(4), np.zeros(4), np.zeros(4))
        np.testing.assert_allclose(ctrl.cuff_model.b, ref.b, rtol=1e-12, atol=1e-9)
        assert_is_the_soft_optimum(ctrl, soft_problem(ctrl))


# --------------------------------------------------------------------------- CT equivalence


def test_with_no_bound_active_the_command_is_the_ct_command(
    exo, patient, motor, plan, near_plan
) -> None:
    ct = ComputedTorqueController(plan, exo, patient, motor)
    qp = QPController(plan, exo, patient, motor, cuff_force_limit_N=1e6)
    rng = np.random.default_rng(1)
    for k in range(0, plan.q.shape[0], 7):
        s = near_plan(plan, rng, k, q_noise=1e-4, dq_noise=1e-3)
        u_ct = ct.command(k, s).copy()
        u_qp = qp.command(k, s)
        assert qp.last_status == "solved"
        assert np.all(qp.slack <= 1e-9)
        assert np.all(qp.torque > qp.torque_lo) and np.all(qp.torque < qp.torque_hi)
        np.testing.assert_allclose(u_qp, u_ct, atol=1e-6, rtol=0)
    assert qp.failures == 0


# --------------------------------------------------------------------------- limits and fallbacks


def gear(motor: MotorParams, tau_m: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """The gearbox's η^s, s = sign(τ_m) tanh(ω / 0.05 rad/s): η motoring, 1/η braking."""
    return motor.gear_efficiency ** (np.sign(tau_m) * np.tanh(omega / 0.05))


def expected_box(exo: BodyModel, motor: MotorParams, omega: np.ndarray):
    """Joint torque box written out from the motor equations: effort ∩ (current ∩ supply) [N·m].

    The motor's box (current and supply) times the gearbox factor of each
    bound's own sign, then the URDF effort at the joint.
    """
    kt = motor.gear_ratio * motor.torque_constant_Nm_per_A
    back_emf = motor.gear_ratio / motor.speed_constant_rad_per_Vs * omega
    r = motor.resistance_ohm
    i_hi = np.minimum(motor.current_limit_A, (motor.supply_voltage_V - back_emf) / r)
    i_lo = np.maximum(-motor.current_limit_A, (-motor.supply_voltage_V - back_emf) / r)
    effort = exo.model.effortLimit[:4]
    lo, hi = kt * i_lo, kt * i_hi
    return np.maximum(-effort, lo * gear(motor, lo, omega)), np.minimum(
        effort, hi * gear(motor, hi, omega)
    )


def delivered(u: np.ndarray, omega: np.ndarray, motor: MotorParams, exo: BodyModel) -> np.ndarray:
    """Steady-state joint torque of voltage u at speed ω as the plant's driver gives it.

    The supply clips the voltage, the driver's current loop the current to ±I_max
    (plant/motor.py) and the joint's torque to its rated effort (plant/step.py).
    """
    v = np.clip(u, -motor.supply_voltage_V, motor.supply_voltage_V)
    back_emf = motor.gear_ratio / motor.speed_constant_rad_per_Vs * omega
    i = np.clip(
        (v - back_emf) / motor.resistance_ohm, -motor.current_limit_A, motor.current_limit_A
    )
    tau_m = motor.gear_ratio * motor.torque_constant_Nm_per_A * i
    effort = exo.model.effortLimit[:4]
    return np.clip(tau_m * gear(motor, tau_m, omega), -effort, effort)


#: The default drive with a 40 A driver: 185 N·m, beyond the URDF's 150 N·m effort.
STRONG = MotorParams(current_limit_A=40.0)


@pytest.mark.parametrize("capped", [True, False], ids=["drive_for", "185 N·m drive"])
def test_no_torque_beyond_its_limits_on_random_inputs(exo, patient, plan, capped, octagon) -> None:
    """Also with a drive stronger than the URDF effort (185 N·m), so the effort bound binds.

    Whether the QP solved or fell back, the torque is in the box; where it
    solved, each cuff's predicted force is within the octagon widened by its
    slack.
    """
    motor = drive_for(STRONG, exo) if capped else STRONG
    rng = np.random.default_rng(4)
    # The box is empty above ω = (U_max + R I_max) k_E / i_G (module docstring): stay below.
    kb = motor.gear_ratio / motor.speed_constant_rad_per_Vs
    empty_above = (motor.supply_voltage_V + motor.resistance_ohm * motor.current_limit_A) / kb
    at_limit = fallbacks = 0
    for limit in (30.0, 80.0, 300.0):
        # The QP itself at bounds from 30 N (below the legs' working force: a
        # tightened 30 N bound is refused) to 300 N: the bound as given.
        ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=limit, tighten=False)
        radius = limit * math.cos(math.pi / 8)
        for _ in range(150):
            k = int(rng.integers(0, plan.q.shape[0]))
            s = SensorReadings(
                q=plan.q[k] + rng.normal(0.0, 0.4, 4),  # large errors: the PD saturates
                dq=rng.uniform(-0.9, 0.9, 4) * empty_above,
                tau=np.zeros(4),
            )
            u = ctrl.command(k, s)
            lo, hi = expected_box(exo, motor, s.dq)
            tau = ctrl.torque  # the answer
            assert np.all(tau >= lo - 1e-9) and np.all(tau <= hi + 1e-9)
            assert np.all(np.abs(tau) <= EFFORT + 1e-9)  # the URDF effort
            assert np.all(np.abs(u) <= motor.supply_voltage_V + 1e-9)
            # The voltage gives the answer as the driver delivers it: at a bound the
            # command exceeds, the command's voltage, which the driver holds at the cap.
            np.testing.assert_allclose(delivered(u, s.dq, motor, exo), tau, rtol=0, atol=1e-6)
            at_limit += np.any(np.isclose(tau, lo, atol=1e-6) | np.isclose(tau, hi, atol=1e-6))
            if ctrl.last_status != "solved":
                assert ctrl.last_status.startswith("fallback: τ_cmd clipped to the torque box")
                continue
            f = ctrl.cuff_force_pred @ octagon().T  # (point, cuff, edge direction)
            assert np.all(np.abs(f).max(axis=(0, 2)) <= radius + ctrl.slack + 1e-6)
        fallbacks += ctrl.failures
    print(f"\nrandom saturated inputs ({'drive_for' if capped else '175 N·m'}): ", end="")
    print(f"{fallbacks} fallbacks of 450 ticks")
    assert at_limit > 50  # the box was binding in many of them


def test_a_command_beyond_the_drives_limit_gets_the_limit_within_the_tick(
    exo, patient, plan, motor
) -> None:
    """The driver holds the cap: the QP hands it the command's voltage there, as CT+PD does.

    From drives at 80 % of the cap, one 1 ms step of the plant's drive model (the
    current exact, clipped at ±I_max, plant/motor.py; the torque within the joint's
    rated effort, as the plant's driver keeps it, plant/step.py): the QP's voltage
    gives the cap over the step, as the CT+PD voltage does; the cap's steady-state
    voltage would give less (the winding's 0.7 ms time constant).
    """
    ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=1000.0, tighten=False)
    k = 300
    s = SensorReadings(q=plan.q[k] - 0.3, dq=plan.dq[k], tau=np.zeros(4))  # PD saturates, up
    u = ctrl.command(k, s)
    cmd, hi = ctrl.record["torque_cmd"][0], ctrl.record["torque_hi"][0]
    pushed = cmd > hi
    assert pushed.all() and ctrl.last_status == "solved"
    effort = exo.model.effortLimit[:4]
    kt = motor.gear_ratio * motor.torque_constant_Nm_per_A
    ct = ComputedTorqueController(plan, exo, patient, motor).command(k, s)

    def step_torque(voltage: np.ndarray) -> np.ndarray:
        bank = MotorBank(4, motor)
        bank.reset(0.8 * hi / kt)
        return np.clip(bank.step(voltage, s.dq, 1e-3), -effort, effort)

    qp, of_ct = step_torque(u), step_torque(ct)
    steady = step_torque(MotorBank(4, motor).voltage_for(hi, s.dq))
    np.testing.assert_allclose(qp, hi, rtol=1e-9)  # the cap
    np.testing.assert_allclose(qp, of_ct, rtol=1e-12)
    assert np.all(steady < hi - 1.0)  # short of it, by 4.7 to 21 N·m here


@pytest.mark.parametrize(
    ("k", "q", "dq", "limit"),
    [
        pytest.param(
            1014,
            (0.5, 0.84, 0.58, 1.34),
            (-2.3, 1.1, -2.9, 1.5),
            1e6,
            id="box only",
        ),
        pytest.param(
            300,
            None,
            None,
            60.0,
            id="cuff bound on the plan",
        ),
    ],
)
def test_a_solvable_tick_is_solved_not_a_fallback(
    exo, patient, motor, plan, k, q, dq, limit, on_plan
):
    ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=limit, tighten=False)
    if q is None:
        readings = [(j, on_plan(plan, j)) for j in range(k, k + 4)]
    else:
        readings = [(k, SensorReadings(q=np.array(q), dq=np.array(dq), tau=np.zeros(4)))]
    for j, s in readings:
        ctrl.command(j, s)
        print(f"\ntick {j}: {ctrl.last_status}")
    assert ctrl.failures == 0, ctrl.last_status


def test_an_empty_torque_box_gives_a_finite_command_within_the_supply(
    exo, patient, motor, plan
) -> None:
    ctrl = QPController(plan, exo, patient, motor)
    # At 20 rad/s the back-EMF (38.6 V) exceeds the supply plus R I_max: no torque fits.
    s = SensorReadings(q=plan.q[100].copy(), dq=np.array([20.0, 0.5, 0.5, 0.5]), tau=np.zeros(4))
    lo, hi = expected_box(exo, motor, s.dq)
    assert lo[0] > hi[0]
    u = ctrl.command(100, s)
    assert ctrl.failures == 1
    assert "empty torque box at joint(s) 0" in ctrl.last_status
    assert np.all(np.isfinite(u)) and np.all(np.abs(u) <= motor.supply_voltage_V)
    assert ctrl.torque[0] == 0.0
    tau = ctrl.torque[1:]
    assert np.all(tau >= lo[1:] - 1e-9) and np.all(tau <= hi[1:] + 1e-9)
    np.testing.assert_allclose(delivered(u, s.dq, motor, exo)[1:], tau, rtol=0, atol=1e-6)


def test_bad_readings_give_zero_volts_and_programming_errors_raise(
    exo, patient, motor, plan, on_plan
) -> None:
    """Non-finite readings make non-finite problem data: the counted zero-volt fallback.

    Readings of the wrong length and a tick beyond the plan are programming
    errors: they raise, naming the input, and are not counted as fallbacks.
    """
    ctrl = QPController(plan, exo, patient, motor)
    bad = SensorReadings(q=plan.q[5].copy(), dq=np.array([np.nan, 0, 0, 0]), tau=np.zeros(4))
    np.testing.assert_array_equal(ctrl.command(5, bad), np.zeros(4))
    assert ctrl.failures == 1 and "zero volts" in ctrl.last_status
    bad = SensorReadings(q=np.array([np.inf, 0, 0, 0]), dq=np.zeros(4), tau=np.zeros(4))
    np.testing.assert_array_equal(ctrl.command(5, bad), np.zeros(4))
    assert ctrl.failures == 2
    good = SensorReadings(q=plan.q[5].copy(), dq=plan.dq[5].copy(), tau=np.zeros(4))
    with pytest.raises(InvalidParameter, match=r"^k must be a control tick on the plan's 1201"):
        ctrl.command(10**9, good)  # beyond the plan
    short = SensorReadings(q=plan.q[5].copy(), dq=np.zeros(3), tau=np.zeros(4))
    with pytest.raises(InvalidParameter, match=r"^sensors_dq must be an array of shape \(4,\)"):
        ctrl.command(5, short)
    wrong = on_plan(plan, 5, np.zeros((3, 2)))
    message = r"^sensors_cuff_force_est must be an array of shape \(4, 2\)"
    with pytest.raises(InvalidParameter, match=message):
        ctrl.command(5, wrong)
    assert ctrl.failures == 2
    ctrl.command(5, good)  # and it recovers
    assert ctrl.last_status == "solved" and ctrl.failures == 2


def test_construction_checks_its_arguments(exo, patient, motor, plan) -> None:
    with pytest.raises(InvalidParameter, match="cuff_force_limit"):
        QPController(plan, exo, patient, motor, cuff_force_limit_N=0.0)
    with pytest.raises(InvalidParameter, match="torque_weights"):
        QPController(plan, exo, patient, motor, torque_weights=(1.0, 1.0, -1.0, 1.0))
    with pytest.raises(InvalidParameter, match="torque_weights"):
        QPController(plan, exo, patient, motor, torque_weights=(1.0, 1.0))
    with pytest.raises(InvalidParameter, match="max_iter"):
        QPController(plan, exo, patient, motor, max_iter=0)
    for bad in (0, 2.5, True):
        with pytest.raises(InvalidParameter, match=r"screened_rows.*an integer ≥ 1"):
            QPController(plan, exo, patient, motor, screened_rows=bad)
    with pytest.raises(InvalidParameter, match="patient"):
        QPController(plan, exo, None, motor)


def test_runs_with_the_human_patient(exo, human, motor, plan, near_plan, octagon) -> None:
    """example-robot-data's human (other link lengths, added cuff frames) is usable.

    With 2-axis sensors in the cuffs, so that the margin has no term for an
    unknown cuff stiffness: the bound then stays feasible within the drive
    limits (the slack below 0.2 N) on this patient's plan.
    """
    knowledge = CuffKnowledge(sensors="full")
    ctrl = QPController(plan, exo, human, motor, cuff_force_limit_N=100.0, cuff_knowledge=knowledge)
    rng = np.random.default_rng(8)
    radius = ctrl.record["radius"][0]  # (F_max − m_c) cos(π/8), tightened by the margin
    for k in range(0, 1200, 97):
        u = ctrl.command(k, near_plan(plan, rng, k))
        assert ctrl.last_status == "solved", ctrl.last_status
        assert np.all(np.isfinite(u))
        f = ctrl.cuff_force_pred @ octagon().T
        assert np.all(np.abs(f).max(axis=(0, 2)) <= radius + ctrl.slack + 1e-6)
        assert np.all(ctrl.slack < 0.2)


def test_the_record_holds_the_command_the_active_bounds_and_the_fallbacks(
    exo, patient, motor, plan, on_plan
) -> None:
    """What the loop logs by name: ``u_cmd``, ``active_constraints``, ``failures``."""
    ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=40.0, tighten=False)
    other = QPController(plan, exo, patient, motor, cuff_force_limit_N=40.0, tighten=False)
    assert ctrl.record.dtype is other.record.dtype  # one dtype object (see _jit.shared_dtype)
    rec = ctrl.record
    active = 0
    for k in range(0, 1200, 50):
        u = ctrl.command(k, on_plan(plan, k))
        np.testing.assert_array_equal(rec["u_cmd"][0], u)
        assert rec["active_constraints"][0] == ctrl.active_constraints
        assert rec["failures"][0] == ctrl.failures == 0
        active = max(active, ctrl.active_constraints)
    assert ctrl.solver_ticks > 0 and active > 0  # the bound binds on some ticks
    bad = SensorReadings(q=plan.q[5].copy(), dq=np.array([np.nan, 0, 0, 0]), tau=np.zeros(4))
    ctrl.command(5, bad)
    assert rec["failures"][0] == ctrl.failures == 1
    np.testing.assert_array_equal(rec["u_cmd"][0], 0.0)
