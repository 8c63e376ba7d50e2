"""Sessions (exo_ctrl/sim/session.py, control/modes/switch.py): segments switched bumplessly.

A weak active patient (strength 0.3) walks tracking → aan → transparent.
The commanded voltage's change over each tick of a blend window is checked
against the stated bound (each controller's own change plus the gap over
N_b + 1), the switch's share against 2 U_max / (N_b + 1); the switches are
events of the run and of its recording; the supervisor never trips and the
cuff forces (true and estimated), joint angles and currents stay within its
limits in every segment.  Figures are printed (pytest -s).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import cli, read_recording
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant.patient_active import ActiveParams
from exo_ctrl.sim import Runner, SimConfig, build
from exo_ctrl.sim.session import Segment, SessionParams, load_session

SEGMENT_S = 2.4
MODES_RUN = ("tracking", "aan", "transparent")


def _session(blend_s: float = 0.1) -> SessionParams:
    return SessionParams(tuple(Segment(SEGMENT_S, m) for m in MODES_RUN), blend_s=blend_s)


@functools.cache
def _run(blend_s: float = 0.1):
    """Tick by tick: the switched command and every segment controller's own, (n, 4) each."""
    config = SimConfig(
        patient_torque="active",
        patient_active=ActiveParams(strength=0.3),
        session=_session(blend_s),
        duration_s=SEGMENT_S * len(MODES_RUN),
    )
    setup = build(config)
    runner = Runner(setup)
    ctrl = setup.controller
    n = config.n_ticks
    u = np.empty((n, 4))
    own = np.full((len(MODES_RUN), n, 4), np.nan)  # NaN where a controller did not run
    log = {name: np.empty((n, *runner.log[name].shape[1:])) for name in ("cuff_force", "q")}
    log["cuff_force_est"] = np.empty((n, 4, 2))
    log["current"] = np.empty((n, 4))
    log["safety_state"] = np.empty(n)
    for k in range(n):
        row = k % runner.chunk
        runner.tick(k, row)
        u[k] = ctrl.record["u_cmd"][0]
        seg = ctrl.segment
        for i in (seg - 1, seg):
            since = k - ctrl.starts[seg]
            if i == seg or (i >= 0 and since < ctrl.blend_ticks):
                own[i, k] = ctrl.controllers[i].record["u_cmd"][0]
        for name in log:
            log[name][k] = runner.log[name][row]
    return config, setup, runner, u, own, log


def test_switches_keep_the_voltage_within_the_stated_bound() -> None:
    """|U_k − U_{k−1}| ≤ max(|ΔU_old|, |ΔU_new|) + gap / (N_b + 1) in every blend window.

    The switch's own share, gap / (N_b + 1), is at most 2 U_max / (N_b + 1)
    = 0.475 V (24 V supply, N_b = 100).  Without blending (T_b = 0) the
    command jumps by the whole gap at the switch.
    """
    config, setup, _runner, u, own, _ = _run()
    ctrl = setup.controller
    nb = ctrl.blend_ticks
    u_max = setup.device_motor.supply_voltage_V
    assert nb == 100
    for seg in (1, 2):
        start = ctrl.starts[seg]
        worst_step, worst_share = 0.0, 0.0
        for k in range(start, start + nb + 1):
            d_old = 0.0 if k == start + nb else np.abs(own[seg - 1, k] - own[seg - 1, k - 1])
            d_new = np.abs(own[seg, k] - own[seg, k - 1]) if k > start else 0.0
            ref = k if k == start else k - 1  # the gap the bound uses
            gap = np.abs(own[seg, ref] - own[seg - 1, ref])
            step = np.abs(u[k] - u[k - 1])
            assert np.all(step <= np.maximum(d_old, d_new) + gap / (nb + 1) + 1e-12)
            worst_step = max(worst_step, float(step.max()))
            worst_share = max(worst_share, float(gap.max()) / (nb + 1))
        assert worst_share <= 2 * u_max / (nb + 1)
        _, hard, _, u_hard, own_hard, _ = _run(0.0)
        k = hard.controller.starts[seg]
        jump = float(np.abs(u_hard[k] - u_hard[k - 1]).max())
        gap_hard = float(np.abs(own_hard[seg, k] - own_hard[seg - 1, k - 1]).max())
        print(
            f"\n{MODES_RUN[seg - 1]} → {MODES_RUN[seg]} at {start * config.dt:g} s: largest "
            f"step in the blend {worst_step:.3f} V, the switch's share at most "
            f"{worst_share:.4f} V (bound {2 * u_max / (nb + 1):.3f} V); hard switch: "
            f"{jump:.3f} V at the switch"
        )
        assert jump == pytest.approx(gap_hard, rel=1e-12)  # the whole gap at once


def test_switches_are_events_and_the_supervisor_holds_in_every_segment() -> None:
    config, setup, runner, _u, _own, log = _run()
    events = setup.controller.events
    assert [(e["t"], e["kind"]) for e in events] == [
        (SEGMENT_S, "mode_switch"),
        (2 * SEGMENT_S, "mode_switch"),
    ]
    assert events[0]["message"] == "segment 2: tracking → aan at t = 2.4 s (blended over 0.1 s)"
    assert events[1]["message"] == "segment 3: aan → transparent at t = 4.8 s (blended over 0.1 s)"
    sup = runner.supervisor
    assert sup.state == "normal" and not sup.events
    limit = config.safety_limits.cuff_limit_N
    seg_ticks = round(SEGMENT_S / config.dt)
    for i, mode in enumerate(MODES_RUN):
        part = slice(i * seg_ticks, (i + 1) * seg_ticks)
        true = np.linalg.norm(log["cuff_force"][part], axis=-1).max(axis=0)
        est = np.linalg.norm(log["cuff_force_est"][part], axis=-1).max(axis=0)
        current = np.abs(log["current"][part]).max(axis=0)
        q = log["q"][part]
        print(
            f"\n{mode}: peak cuff force true {np.round(true, 1)} N, estimated {np.round(est, 1)} N "
            f"(limits {limit} N); peak current {np.round(current, 2)} A "
            f"(limit {np.round(sup.current_limit, 2)} A)"
        )
        assert np.all(log["safety_state"][part] == 0.0)
        assert np.all(true < limit) and np.all(est < limit)
        assert np.all(current < sup.current_limit)
        assert np.all((q >= sup.q_lower) & (q <= sup.q_upper))


def _write(tmp_path: Path, data: object, raw: str | None = None, name: str = "s") -> str:
    path = tmp_path / f"{name}.json"
    path.write_text(raw if raw is not None else json.dumps(data))
    return str(path)


@pytest.mark.parametrize(
    ("data", "raw", "message"),
    [
        (
            [{"duration": 1.0, "mode": "walk"}],
            None,
            "session segment 1 mode must be one of tracking, guidance, transparent, aan, path; "
            "got 'walk'",
        ),
        (
            [{"duration": 1.0, "mode": "tracking"}, {"duration": -2, "mode": "aan"}],
            None,
            "session segment 2 duration must be in (0, 1e+07] s; got -2",
        ),
        (
            [{"duration": 1.0, "mode": "tracking", "speed": 0.3}],
            None,
            "session segment 1 key must be one of duration, mode, belt_speed, guidance, "
            "force_gain, aan_forgetting, aan_gain, tunnel_width, path_support; got 'speed'",
        ),
        (
            None,
            '[{"duration": 1.0, "mode": "tracking"},]',
            "must be a JSON list of segments; got",
        ),
        (
            [{"duration": 1.0, "mode": "guidance", "guidance": 2}],
            None,
            "session segment 1 guidance must be in [0, 1] (1: tracking, 0: free); got 2",
        ),
    ],
)
def test_session_files_are_checked(tmp_path: Path, data, raw, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        load_session(_write(tmp_path, data, raw))
    assert message in str(info.value)


def test_cli_refuses_bad_sessions_in_one_line(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run.rrd"
    base = ["simulate", "--out", str(out)]
    missing = str(tmp_path / "none.json")
    cases = [
        (
            ["--session", missing],
            f"session must be an existing JSON file; got '{missing}' (no such file)",
        ),
        (
            ["--session", _write(tmp_path, None, "[{", "bad")],
            "session must be a JSON list of segments; got",
        ),
        (
            [
                "--session",
                _write(tmp_path, [{"duration": 1.0, "mode": "tracking"}]),
                "--duration",
                "2",
            ],
            "scenario preset paper-free-air: session total duration must be equal to the "
            "run's duration, 2 s; got 1.0 "
            "(the sum of its 1 segments' durations [s])",
        ),
    ]
    for args, message in cases:
        code = cli.main([*base, *args])
        err = capsys.readouterr().err
        assert code == 2, err
        assert err.startswith(f"exo-ctrl simulate: error: {message}"), err
        assert "Traceback" not in err and err.count("\n") == 1
        assert not out.exists()


def test_cli_session_runs_and_records_its_switches(tmp_path: Path, capsys) -> None:
    """A short session from the command line: its switch is an event of the recording."""
    out = tmp_path / "run.rrd"
    session = _write(
        tmp_path,
        [
            {"duration": 0.2, "mode": "tracking"},
            {"duration": 0.2, "mode": "transparent", "force_gain": 5},
        ],
    )
    assert cli.main(["simulate", "--session", session, "--out", str(out)]) == 0
    capsys.readouterr()
    back = read_recording(out)
    assert back.n_ticks == 400 and back.status == "completed"
    switches = [e for e in back.events if e["kind"] == "mode_switch"]
    assert [e["t"] for e in switches] == [0.2]
    assert back.config.session is not None and back.config.session.segments[1].params == (
        ("force_gain", 5.0),
    )


def test_belt_speeds_make_the_speed_profile() -> None:
    """Held within a segment, reached linearly over belt_ramp_s after a switch."""
    session = SessionParams(
        (Segment(2.0, "tracking"), Segment(3.0, "transparent", belt_speed_mps=0.5)),
        belt_ramp_s=1.0,
    )
    profile = session.speed_profile(0.3)
    assert profile.times == (0.0, 2.0, 3.0, 5.0)
    assert profile.speeds == (0.3, 0.3, 0.5, 0.5)
    speed, _ = profile.at(np.array([1.0, 2.5, 4.0]))
    np.testing.assert_allclose(speed, [0.3, 0.4, 0.5])
    assert _session().speed_profile(0.3) is None
    with pytest.raises(InvalidParameter, match="belt_speed must be unset without the belt"):
        SimConfig(session=session, duration_s=5.0)
    with pytest.raises(InvalidParameter, match=r"mode must be tracking \(unset\) with a session"):
        SimConfig(session=_session(), duration_s=7.2, mode="transparent")
