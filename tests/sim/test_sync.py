"""Synchronisation with the measured belt: a detuned plan's slip, a session's speed profile.

Figures are the runs' own measurements: the contact's slip relative to the
moving belt (in contact, after the ramp-in), the belt encoder's reading and
the plan's foot velocities as the generator wrote them each tick.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl import cli
from exo_ctrl.plan import GaitParams, SpeedProfile
from exo_ctrl.plant import ContactParams
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.setup import build
from exo_ctrl.sim.tick import Runner

ON = ContactParams(enabled=True)
V_F = GaitParams().belt_speed
#: Slip thresholds reported with sync on [m/s]: RMS in contact, and the mean |slip|.
SLIP_RMS = 0.01
SLIP_MEAN = 0.005


def slip_figures(result) -> tuple[float, float, float]:
    """(mean |slip|, RMS, max) of both feet in contact after the ramp-in [m/s]."""
    late = result.t >= result.config.ramp_in
    mask = (result.signals["contact_state"] > 0) & late[:, None]
    s = np.abs(result.signals["foot_slip"][mask])
    return float(s.mean()), float(np.sqrt(np.mean(s**2))), float(s.max())


@pytest.mark.parametrize("controller", ["ct", "pd"])
def test_a_detuned_plan_slips_as_kinematics_predicts_and_sync_removes_it(controller) -> None:
    """The belt 10 % faster than the plan: the stance foot slips at 0.1 v_f; sync follows it."""
    profile = SpeedProfile.constant(1.1 * V_F)
    figures = {}
    for sync in (False, True):
        config = SimConfig(controller=controller, contact=ON, speed_profile=profile, sync=sync)
        result = simulate(config)
        assert result.status == "completed"
        figures[sync] = slip_figures(result)
    predicted = 0.1 * V_F  # the foot at -v_f on a belt at -1.1 v_f
    off, on = figures[False], figures[True]
    print(
        f"{controller}: predicted slip {predicted:.4f} m/s; sync off mean {off[0]:.4f} "
        f"(RMS {off[1]:.4f}, max {off[2]:.4f}); sync on mean {on[0]:.4f} "
        f"(RMS {on[1]:.4f}, max {on[2]:.4f}) m/s"
    )
    assert off[0] == pytest.approx(predicted, rel=0.2)
    assert on[0] < SLIP_MEAN and on[1] < SLIP_RMS
    assert on[0] < 0.1 * off[0]


def test_a_speed_profile_keeps_the_feet_c1_on_the_belt_without_slip() -> None:
    """0.4 to 0.7 m/s over 3 s after the ramp-in: C¹ planned feet, stance at the measured speed."""
    config = SimConfig(
        controller="ct",
        contact=ON,
        speed_profile=SpeedProfile.parse("1.2:0.4,4.2:0.7"),
        duration_s=5.4,
    )
    assert config.synced  # the default with contact on
    runner = Runner(build(config))
    gen = runner.setup.online
    n, dt = config.n_ticks, config.dt
    pos, vel = np.zeros((n, 2, 2)), np.zeros((n, 2, 2))
    measured, belt = np.zeros(n), np.zeros(n)
    slip, state = np.zeros((n, 2)), np.zeros((n, 2))
    for k in range(n):
        row = k % runner.chunk
        runner.tick(k, row)
        pos[k], vel[k] = gen.plan.foot_pos[0], gen.plan.foot_vel[0]
        measured[k] = runner.belt_encoder.speed[0]
        belt[k] = runner.setup.plant.contact.belt[0]["v"]
        slip[k], state[k] = runner.log["foot_slip"][row], runner.log["contact_state"][row]
    t = np.arange(n) * dt
    # C1: position differences are the mean velocity; no velocity step beyond
    # what a planned acceleration of 20 m/s² gives in a tick
    fd = np.diff(pos, axis=0) / dt
    fd_err = np.abs(fd - 0.5 * (vel[1:] + vel[:-1])).max()
    jump = np.abs(np.diff(vel, axis=0)).max()
    # the planned stance foot against the measured belt speed (after the ramp-in)
    stance = np.isclose(pos[:, :, 1], -config.gait.hip_height, rtol=0, atol=1e-12)
    late = stance & (t[:, None] >= 1.2)
    follow = (-vel[:, :, 0] - measured[:, None])[late]
    truth = (-vel[:, :, 0] - belt[:, None])[late]
    contact = (state > 0) & (t[:, None] >= 1.2)
    s = np.abs(slip[contact])
    print(
        f"finite differences vs planned velocity: max {1e3 * fd_err:.2f} mm/s, largest "
        f"velocity change in a tick {1e3 * jump:.1f} mm/s; stance foot vs measured belt speed "
        f"RMS {1e3 * np.sqrt(np.mean(follow**2)):.2f} mm/s (vs the true belt "
        f"{1e3 * np.sqrt(np.mean(truth**2)):.2f}); slip RMS {np.sqrt(np.mean(s**2)):.4f} m/s, "
        f"mean {s.mean():.4f}, max {s.max():.4f}; belt at the end {belt[-1]:.4f} m/s"
    )
    assert fd_err < 5e-3 and jump < 0.02
    assert np.sqrt(np.mean(follow**2)) < 0.005
    assert np.sqrt(np.mean(s**2)) < SLIP_RMS and s.mean() < SLIP_MEAN
    assert belt[-1] == pytest.approx(0.7, abs=0.002)


def test_sync_off_keeps_the_precomputed_plan() -> None:
    config = SimConfig(controller="ct", contact=ON, sync=False, duration_s=0.2)
    setup = build(config)
    assert setup.online is None and setup.plan.q.shape[0] == config.plan_rows > 1
    synced = build(SimConfig(controller="ct", contact=ON, duration_s=0.2))
    assert synced.online is not None and synced.plan.q.shape == (1, 4)
    # both start at the same standing posture
    np.testing.assert_allclose(synced.plan.q[0], setup.plan.q[0], atol=1e-12)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--speed-profile", "3:0.5,1:0.6"],
            "--speed-profile: treadmill.speed_profile: must be times in increasing order; got "
            "'3:0.5,1:0.6' "
            "(point 2, 1:0.6 is not after 3 s)",
        ),
        (
            ["--speed-profile", "0:-0.5"],
            "--speed-profile: treadmill.speed_profile: must be speeds >= 0.01 m/s; got "
            "'0:-0.5' (point 1, 0:-0.5)",
        ),
        (
            ["--speed-profile", "0:0.5;1"],
            "--speed-profile: treadmill.speed_profile: must be points T:V separated by commas, T "
            "in s and V in m/s "
            "(e.g. \"0:0.4,3:0.7\"); got '0:0.5;1' ('0:0.5;1' is not T:V)",
        ),
        (
            ["--speed-profile", "0:0.5,2:3.5"],
            "speed_profile must be speeds the leg reaches and the drives follow; got "
            "'0:0.5,2:3.5' (at t = 2 s the belt speed 3.5 m/s needs step_length 0.8573 m and "
            "period 0.4899 s: planned left_knee speed must be at most 5.18 rad/s, where the "
            "drive's back-EMF i_G ω / k_E (4.633 V·s/rad × ω) takes the whole 24 V supply; got "
            "12.6 (rad/s, at t = 0.06908 s of a gait with period 0.489898 s and step_length "
            "0.857321 m: a longer period or a shorter step slows it))",
        ),
        (
            ["--hip-height", "0.98", "--speed-profile", "0:0.5,2:2.5"],
            "speed_profile must be speeds the leg reaches and the drives follow; got "
            "'0:0.5,2:2.5' (at t = 2 s the belt speed 2.5 m/s needs step_length 0.6575 m (the "
            "longest the leg reaches) and period 0.526 s: planned left_knee speed must be at "
            "most 5.18 rad/s",
        ),
        (
            ["--belt-height", "1.2"],
            "belt height must be in (0, 1.04) m, within the leg's reach; got 1.2",
        ),
        (
            ["--friction", "0"],
            "scenario preset paper-free-air: contact: friction coefficient must be > 0; got 0.0",
        ),
        (
            ["--friction", "-0.3"],
            "scenario preset paper-free-air: contact: friction coefficient must be > 0; got -0.3",
        ),
    ],
)
def test_bad_belt_inputs_are_refused_with_exit_2(args, message, capsys, tmp_path) -> None:
    base = ["simulate", "--contact", "on", "--controller", "ct", "--no-record", "--duration"]
    code = cli.main([*base, "1.5", *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1
    assert err[0].startswith(f"exo-ctrl simulate: error: {message}")


def test_sync_and_a_profile_need_the_belt(capsys) -> None:
    code = cli.main(["simulate", "--no-record", "--duration", "0.1", "--speed-profile", "0:0.5"])
    assert code == 2
    assert capsys.readouterr().err.strip() == (
        "exo-ctrl simulate: error: --speed-profile: treadmill.speed_profile: must be unset "
        "without the belt (contact on); "
        "got '0:0.5'"
    )
    code = cli.main(["simulate", "--no-record", "--duration", "0.1", "--sync", "on"])
    assert code == 2
    assert capsys.readouterr().err.strip() == (
        "exo-ctrl simulate: error: --sync: treadmill.sync: must be off here; got 'on' (the "
        "belt's speed is "
        "measured with contact on only)"
    )


def test_ct_feedforward_row_is_the_tables_formula_on_the_device_models() -> None:
    """The per-tick row equals feedforward_torque and voltage_for on the same targets."""
    from exo_ctrl.control import feedforward_torque
    from exo_ctrl.plant.motor import MotorBank

    config = SimConfig(controller="ct", contact=ON, duration_s=0.5)
    runner = Runner(build(config))
    setup = runner.setup
    for k in range(400):
        runner.tick(k, k % runner.chunk)
    ctrl = setup.controller
    tau = feedforward_torque(setup.plan, setup.device_exo, setup.device_patient, setup.device_motor)
    volts = MotorBank(4, setup.device_motor).voltage_for(tau, setup.plan.dq)
    np.testing.assert_allclose(ctrl.torque_ff_table, tau, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ctrl.voltage_ff_table, volts, rtol=1e-12, atol=1e-12)
    assert np.any(np.abs(setup.plan.dq[0]) > 0.1)  # on the gait, not at rest


def test_a_profile_run_reads_back_from_its_recording(tmp_path) -> None:
    from exo_ctrl.record import RerunRecorder, read_recording

    path = tmp_path / "run.rrd"
    config = SimConfig(controller="ct", contact=ON, speed_profile="0:0.5,0.2:0.55", duration_s=0.3)
    assert config.speed_profile == SpeedProfile((0.0, 0.2), (0.5, 0.55))
    simulate(config, observers=[RerunRecorder(path)])
    back = read_recording(path).config
    assert back.speed_profile == config.speed_profile and back.synced
