"""Interaction modes, one tick at a time (exo_ctrl/control/modes): the laws and their maths."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.control import PDController
from exo_ctrl.control.modes import FORCE_GAINS, InteractionController, ModeParams
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import FRICTION_SMOOTHING_RAD_S
from exo_ctrl.plant import MotorBank
from exo_ctrl.sensing.readings import SensorReadings
from exo_ctrl.sim import SimConfig, build


@pytest.fixture(scope="module")
def setup():
    return build(SimConfig(duration_s=7.2))


def _readings(rng, setup, k) -> SensorReadings:
    row = setup.plan.row(k)
    q = setup.plan.q[row] + rng.normal(0.0, 0.05, 4)
    dq = setup.plan.dq[row] + rng.normal(0.0, 0.3, 4)
    force = rng.normal(0.0, 40.0, (4, 2))
    return SensorReadings(q=q, dq=dq, tau=np.zeros(4), cuff_force_est=force)


def _mode(setup, mode, **params) -> InteractionController:
    tracking = PDController(setup.plan, setup.config.gains) if mode == "guidance" else None
    return InteractionController(
        mode,
        ModeParams(**params),
        setup.plan,
        setup.device_exo,
        setup.device_motor,
        tracking=tracking,
        dt=setup.config.dt,
    )


def test_guidance_blends_tracking_and_the_free_command(setup) -> None:
    """U_G = G U_track + (1 - G) U_free; G = 1 is the tracking command bit for bit.

    The free command's force feedback without guidance's low-pass (a cut-off
    whose step weight is 1); the filter itself:
    tests/control/test_guidance_force_loop.py.  U_free is transparent's law
    with guidance's force gain and no lead (transparent's defaults differ:
    FORCE_GAINS, FORCE_LEADS).
    """
    rng = np.random.default_rng(1)
    ticks = [0, 1, 2, 700, 1500, 2600, 4000]
    readings = [_readings(rng, setup, k) for k in ticks]
    pd = PDController(setup.plan, setup.config.gains)
    kf = ModeParams().force_gain_for("guidance")
    free = _mode(setup, "transparent", force_gain=kf, force_lead_s=0.0)
    u_pd = [pd.command(k, r).copy() for k, r in zip(ticks, readings, strict=True)]
    u_free = [free.command(k, r).copy() for k, r in zip(ticks, readings, strict=True)]
    for g in (0.0, 0.3, 1.0):
        ctrl = _mode(setup, "guidance", guidance=g, force_filter_hz=1e9)
        for k, r, a, b in zip(ticks, readings, u_pd, u_free, strict=True):
            u = ctrl.command(k, r)
            np.testing.assert_allclose(u, g * a + (1.0 - g) * b, rtol=1e-13, atol=1e-12)
            if g == 1.0:
                np.testing.assert_array_equal(u, a)
            if g == 0.0:
                np.testing.assert_array_equal(u, b)


def test_interaction_torque_is_the_cuff_jacobians_transpose(setup) -> None:
    """τ̂_int = Σ J_cᵀ f̂_c, against Pinocchio's frame Jacobians of the device's exoskeleton."""
    exo = setup.device_exo
    model, data = exo.model, exo.model.createData()
    rng = np.random.default_rng(2)
    ctrl = _mode(setup, "transparent")
    for k in range(5):
        r = _readings(rng, setup, 100 * k)
        ctrl.command(100 * k, r)
        want = np.zeros(4)
        for c, frame in enumerate(exo.cuff_frame_ids):
            jac = pin.computeFrameJacobian(
                model, data, r.q, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
            )
            want += jac[[0, 2]].T @ r.cuff_force_est[c]
        np.testing.assert_allclose(ctrl.record["tau_int_est"][0], want, atol=1e-9)


def test_free_command_is_the_drive_model_of_the_compensating_torque(setup) -> None:
    """U_free = voltage_for(n(q, q̇) + b q̇ + f_c tanh(q̇/ε) + K_f τ̂_int, q̇) of the device's drive."""
    exo, motor = setup.device_exo, setup.device_motor
    bank = MotorBank(4, motor)
    model, data = pin.Model(exo.model), exo.model.createData()
    rng = np.random.default_rng(3)
    for kf in (0.0, 10.0):
        ctrl = _mode(setup, "transparent", force_gain=kf)
        r = _readings(rng, setup, 0)  # first tick: the speed is the reading's
        u = ctrl.command(0, r).copy()
        w = r.dq
        tau = pin.nonLinearEffects(model, data, r.q, w) + exo.damping * w
        tau += exo.friction * np.tanh(w / FRICTION_SMOOTHING_RAD_S)
        tau += kf * ctrl.record["tau_int_est"][0]
        np.testing.assert_allclose(u, bank.voltage_for(tau, w), rtol=1e-12, atol=1e-12)


def test_the_drive_speed_filters_the_encoder_difference(setup) -> None:
    """v_k = v_{k-1} + α ((q_k - q_{k-1}) / Δt - v_{k-1}), α = 1 - exp(-2π f Δt)."""
    ctrl = _mode(setup, "transparent", speed_filter_hz=150.0)
    dt = setup.config.dt
    alpha = 1.0 - np.exp(-2.0 * np.pi * 150.0 * dt)
    q = np.full(4, 0.3)
    v = np.full(4, 0.5)
    zero_force = np.zeros((4, 2))
    ctrl.command(
        0, SensorReadings(q=q.copy(), dq=v.copy(), tau=np.zeros(4), cuff_force_est=zero_force)
    )
    speed = v.copy()
    for k in range(1, 40):
        q_new = q + 1.2 * dt  # a steady 1.2 rad/s
        ctrl.command(k, SensorReadings(q=q_new, dq=v, tau=np.zeros(4), cuff_force_est=zero_force))
        speed += alpha * ((q_new - q) / dt - speed)
        q = q_new
        np.testing.assert_allclose(ctrl.record["speed"][0], speed, rtol=1e-12)
    assert ctrl.record["speed"][0][0] == pytest.approx(1.2, abs=1e-3)


def test_assist_as_needed_follows_its_learning_law(setup) -> None:
    """A constant error e gives F_k = g e (1 + f + … + f^{k-1}) in every bin; then F fades by f."""
    f, g = 0.8, 60.0
    ctrl = _mode(setup, "aan", aan_forgetting=f, aan_gain=g, aan_bins=50)
    lead, period, _ = setup.plan.row_rule
    err = np.array([0.02, -0.01, 0.03, 0.005])
    zero_force = np.zeros((4, 2))

    def tick(k: int, e: np.ndarray) -> None:
        row = setup.plan.row(k)
        q = setup.plan.q[row] - e
        ctrl.command(
            k,
            SensorReadings(q=q, dq=setup.plan.dq[row], tau=np.zeros(4), cuff_force_est=zero_force),
        )

    k = 0
    for k in range(lead):  # the ramp-in: nothing learned, no support
        tick(k, err)
        assert np.all(ctrl.record["tau_support"][0] == 0.0)
    assert not ctrl.support.any()
    expected = np.zeros(4)
    for cycle in range(3):
        for k in range(lead + cycle * period, lead + (cycle + 1) * period):
            tick(k, err)
            # The support applied is the bin's from the cycles before.
            np.testing.assert_allclose(ctrl.record["tau_support"][0], expected, rtol=1e-12)
        expected = f * expected + g * err
    tick(k + 1, np.zeros(4))  # enters the next cycle: its last bin is learned
    np.testing.assert_allclose(ctrl.support, np.broadcast_to(expected, (50, 4)), rtol=1e-12)
    assert ctrl.support_history[-1] == pytest.approx(np.sqrt(np.mean(expected**2)), rel=1e-12)
    for cycle in range(2):  # no error: the support fades by f per cycle
        start = k + 1 + cycle * period
        for kk in range(start, start + period):
            tick(kk, np.zeros(4))
        expected = f * expected
    tick(start + period, np.zeros(4))
    np.testing.assert_allclose(ctrl.support, np.broadcast_to(expected, (50, 4)), rtol=1e-12)
    assert len(ctrl.support_history) == 5


def test_a_mode_needs_the_cuff_force_estimate(setup) -> None:
    ctrl = _mode(setup, "transparent")
    r = SensorReadings(q=np.zeros(4), dq=np.zeros(4), tau=np.zeros(4))
    with pytest.raises(InvalidParameter, match=r"sensors.cuff_force_est must be the estimated"):
        ctrl.command(0, r)


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"guidance": 1.5}, r"guidance must be in \[0, 1\]"),
        ({"force_gain": -1.0}, r"force_gain\[left_hip\] must be >= 0"),
        ({"aan_forgetting": 1.0}, r"aan_forgetting must be in \[0, 1\)"),
        ({"aan_bins": 0}, r"aan_bins must be an integer in \[1, 10000\]"),
        ({"aan_gain": (1.0, 2.0)}, "aan_gain must be a number or 4 numbers"),
        ({"force_filter_hz": 0.0}, r"force_filter_hz must be > 0 Hz; got 0.0"),
        (
            {"estimator_torque_rate_Nm_per_sqrt_s": -1.0},
            r"estimator_torque_rate must be >= 0 N·m/√s; got -1.0",
        ),
        ({"force_lead_s": -0.01}, r"force_lead\[left_hip\] must be >= 0 s; got -0.01"),
        ({"force_lead_filter_hz": 0.0}, r"force_lead_filter must be > 0 Hz; got 0.0"),
        ({"force_lead_ramp_s": -1.0}, r"force_lead_ramp must be >= 0 s; got -1.0"),
    ],
)
def test_bad_mode_parameters_are_refused(params, message) -> None:
    with pytest.raises(InvalidParameter, match=message):
        ModeParams(**params)


def test_modes_are_refused_where_they_do_not_apply() -> None:
    with pytest.raises(InvalidParameter, match="mode must be one of tracking, guidance"):
        SimConfig(mode="walk")
    with pytest.raises(InvalidParameter, match="assist-as-needed learns per phase"):
        SimConfig(mode="aan", gait=SimConfig().gait.__class__(period=1.2345))
    with pytest.raises(InvalidParameter, match="the calibration swing tracks"):
        SimConfig(mode="transparent", exercise="calibration")
    with pytest.raises(InvalidParameter, match="the active patient walks a gait"):
        SimConfig(patient_torque="active", exercise="calibration")


@pytest.mark.parametrize("mode", ["transparent", "aan", "guidance", "path"])
def test_a_nan_reading_commands_nan_and_keeps_the_state(setup, mode) -> None:
    """A sensor fault is the supervisor's to catch: NaN volts, the mode's state untouched.

    After a NaN encoder frame the next finite tick commands what it would have
    without the frame in between (the filters, aan's table, path's phase as
    they were).
    """
    from exo_ctrl.control.modes.path import PathController, PathParams

    def make():
        if mode == "path":
            c = setup.config
            return PathController(
                PathParams(), c.modes, setup.plan, setup.device_exo, setup.device_motor, c.dt
            )
        return _mode(setup, mode)

    rng = np.random.default_rng(3)
    ticks = [1300, 1301, 1302]
    r0, r2 = _readings(rng, setup, ticks[0]), _readings(rng, setup, ticks[2])
    bad = SensorReadings(
        q=np.array([np.nan, *r0.q[1:]]), dq=r0.dq, tau=np.zeros(4), cuff_force_est=r0.cuff_force_est
    )
    faulted, clean = make(), make()
    faulted.command(ticks[0], r0)
    clean.command(ticks[0], r0)
    assert np.all(np.isnan(faulted.command(ticks[1], bad)))
    expected = clean.command(ticks[2], r2).copy()
    np.testing.assert_array_equal(faulted.command(ticks[2], r2), expected)


def test_force_gains_per_mode_and_estimator(setup) -> None:
    """K_f: FORCE_GAINS for the mode and the estimator unless set; aan has none."""
    params = ModeParams()
    assert params.force_gain is None
    assert params.force_gain_for("transparent") == (14.0, 10.0, 14.0, 10.0)
    assert params.force_gain_for("transparent", "momentum") == (10.0,) * 4
    assert params.force_gain_for("guidance", "momentum") == (10.0,) * 4
    assert ModeParams(force_gain=5.0).force_gain_for("transparent") == (5.0,) * 4
    for estimator in ("kalman", "momentum"):
        for mode in ("transparent", "guidance", "aan"):
            ctrl = InteractionController(
                mode,
                params,
                setup.plan,
                setup.device_exo,
                setup.device_motor,
                tracking=PDController(setup.plan, setup.config.gains),
                dt=setup.config.dt,
                estimator=estimator,
            )
            want = (0.0,) * 4 if mode == "aan" else FORCE_GAINS[(mode, estimator)]
            np.testing.assert_array_equal(ctrl.record["force_gain"][0], want)


def test_transparent_leads_the_estimated_interaction_torque(setup) -> None:
    """τ_free − τ_free(no lead) = K_f λ_k T_L r_k, r the filtered rate of τ̂_int, λ_k = min(1, k/N).

    r_k = r_{k−1} + α ((τ̂_k − τ̂_{k−1})/Δt − r_{k−1}), r_0 = 0, α = 1 − exp(−2π f Δt);
    the same readings through a controller with T_L = 0.  Defaults: 15 ms on
    every joint with the Kalman filter, none with the momentum observer or in
    guidance.
    """
    assert ModeParams().force_lead_for("transparent") == (0.015,) * 4
    assert ModeParams().force_lead_for("transparent", "momentum") == (0.0,) * 4
    assert ModeParams().force_lead_for("guidance") == (0.0,) * 4
    lead, f_hz, ramp_s, dt = np.array([0.015, 0.01, 0.02, 0.0]), 10.0, 0.005, setup.config.dt
    ctrl = _mode(setup, "transparent", force_lead_s=tuple(lead), force_lead_filter_hz=f_hz,
                 force_lead_ramp_s=ramp_s)  # fmt: skip
    plain = _mode(setup, "transparent", force_lead_s=0.0)
    alpha, n_ramp = 1.0 - np.exp(-2.0 * np.pi * f_hz * dt), round(ramp_s / dt)
    kf = np.asarray(ModeParams().force_gain_for("transparent"))
    rng = np.random.default_rng(5)
    rate, previous = np.zeros(4), None
    for k in range(12):
        r = _readings(rng, setup, 1300 + k)
        ctrl.command(1300 + k, r)
        plain.command(1300 + k, r)
        est = ctrl.record["tau_int_est"][0].copy()
        if previous is not None:
            rate += alpha * ((est - previous) / dt - rate)
        previous = est
        lam = min(1.0, k / n_ramp)
        want = est + lam * lead * rate
        np.testing.assert_allclose(ctrl.record["tau_int_lp"][0], want, rtol=1e-12, atol=1e-9)
        diff = ctrl.record["tau_free"][0] - plain.record["tau_free"][0]
        np.testing.assert_allclose(diff, kf * lam * lead * rate, rtol=1e-9, atol=1e-8)
    assert np.all(np.abs(rate[:3]) > 100.0)  # the random forces' rate: the lead acted


def test_transparent_tunes_the_kalman_filter_and_a_session_restores_it(setup) -> None:
    """Transparent sets the filter's σ_d; other modes leave it; a switch applies the segment's."""
    from exo_ctrl.control.modes.switch import SwitchedController
    from exo_ctrl.estimation import CuffForceEstimator, CuffForceKalman

    def kalman() -> CuffForceKalman:
        return CuffForceKalman(setup.device_exo, setup.device_patient, setup.config.dt)

    own = kalman().record["var_rate"][0]
    rate = ModeParams().estimator_torque_rate_Nm_per_sqrt_s
    for mode, want in (("transparent", rate**2), ("guidance", own), ("aan", own)):
        est = kalman()
        ctrl = _mode(setup, mode)
        ctrl.tune_estimator(est)
        assert est.record["var_rate"][0] == want
    observer = CuffForceEstimator(setup.device_exo, setup.config.dt)
    _mode(setup, "transparent").tune_estimator(observer)  # no such term: left alone
    session = SwitchedController(
        [_mode(setup, "guidance"), _mode(setup, "transparent"), _mode(setup, "aan")],
        ["guidance", "transparent", "aan"],
        [0, 3, 6],
        blend_ticks=2,
        dt=setup.config.dt,
    )
    est = kalman()
    session.tune_estimator(est)
    seen = []
    rng = np.random.default_rng(4)
    for k in range(9):
        session.command(k, _readings(rng, setup, k))
        seen.append(est.record["var_rate"][0])
    assert seen == [own] * 3 + [rate**2] * 3 + [own] * 3
