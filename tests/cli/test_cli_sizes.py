"""The memory cap (issue 19): every allocation a user's number sets is refused up front.

Each refusal is a one-line message naming the parameter, its value, the size
it would need and the limit, with exit code 2 and no file written.  The bytes
per element the checks use are measured here with tracemalloc (which sees
every numpy allocation) on the real code paths.  Also: an e-stop time beyond
the run's last tick is refused instead of being silently ignored.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import pytest

from exo_ctrl import SimConfig, cli, simulate
from exo_ctrl import _validate as v
from exo_ctrl.cli import gait as gait_cli
from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter
from exo_ctrl.plan import GaitParams
from exo_ctrl.sim import build
from exo_ctrl.sim.config import CHUNK_ROW_BYTES, HISTORY_BYTES_PER_TICK, PLAN_ROW_BYTES

GiB = 1 << 30


def traced_peak(run: Callable[[], object]) -> int:
    """Peak of the memory traced while ``run`` runs, above what was held before [bytes]."""
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        run()
        return tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


def assert_refused(code: int, err: str, expected: str, directory: Path) -> None:
    assert code == 2
    assert err == expected
    assert list(directory.iterdir()) == []  # no output, no temporary file


# --------------------------------------------------------------------------- the one check


def test_allocation_accepts_up_to_the_cap_and_refuses_one_byte_more() -> None:
    assert GiB == v.MAX_ALLOCATION_BYTES
    assert v.allocation("n", 1, GiB // 8, 8) == GiB // 8
    assert v.max_items(8) == GiB // 8
    with pytest.raises(InvalidParameter) as info:
        v.allocation("n", 7, GiB // 8 + 1, 8, what="numbers", limit="at most 7")
    exc = info.value
    assert isinstance(exc, ExoCtrlError) and isinstance(exc, ValueError)
    assert (exc.name, exc.value) == ("n", 7)
    assert str(exc) == (
        "n must be at most 7 so that the numbers fit in the 1 GiB memory cap "
        "(at most 134,217,728 of 8 B each); got 7 (134,217,729 numbers would need "
        "1,073,741,832 B)"
    )


@pytest.mark.parametrize(
    ("size", "text"),
    [(0, "0 B"), (544, "544 B"), (1024, "1 KiB"), (3 * 2**20 // 2, "1.5 MiB"), (3.2e9, "2.98 GiB")],
)
def test_sizes_are_written_in_binary_units(size: float, text: str) -> None:
    assert v.format_bytes(size) == text


# --------------------------------------------------------------------------- exo-ctrl gait

GAIT_PERIOD = (  # the gait period's own bound comes first (GaitParams, MAX_PERIOD_S)
    "exo-ctrl gait: error: period must be <= 100 s; got 1000000.0 (one gait cycle sizes "
    "the plan and the monitors' windows: a longer one would not fit in memory, or overflow)\n"
)
GAIT_RATE = (
    "exo-ctrl gait: error: rate must be at most 1.645e+06 Hz over 1.2 s so that the samples "
    "fit in the 1 GiB memory cap (at most 1,973,790 of 544 B each); got 1000000000.0 "
    "(1,200,000,001 samples would need 608 GiB)\n"
)
GAIT_DURATION = (
    "exo-ctrl gait: error: duration must be at most 9869 s at 200 Hz so that the samples "
    "fit in the 1 GiB memory cap (at most 1,973,790 of 544 B each); got 100000.0 "
    "(20,000,001 samples would need 10.13 GiB)\n"
)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--period", "1e6"], GAIT_PERIOD),
        (["--rate", "1e9"], GAIT_RATE),
        (["--duration", "1e5", "--rate", "200"], GAIT_DURATION),
    ],
    ids=["period", "rate", "duration"],
)
def test_gait_beyond_the_cap_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], expected: str
) -> None:
    code = cli.main(["gait", *args, "--csv", str(tmp_path / "g.csv")])
    assert_refused(code, capsys.readouterr().err, expected, tmp_path)


@pytest.mark.parametrize(
    ("args", "expected"), [(["--period", "1e6"], GAIT_PERIOD), (["--rate", "1e9"], GAIT_RATE)]
)
def test_gait_beyond_the_cap_via_the_installed_command(
    tmp_path: Path, args: list[str], expected: str
) -> None:
    exe = Path(sys.executable).with_name("exo-ctrl")
    proc = subprocess.run(
        [str(exe), "gait", *args, "--csv", str(tmp_path / "g.csv")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert_refused(proc.returncode, proc.stderr, expected, tmp_path)
    assert proc.stdout == ""


def test_gait_limit_is_exact_at_the_stated_sample_count() -> None:
    most = v.max_items(gait_cli.GAIT_BYTES_PER_SAMPLE)
    args = argparse.Namespace(duration=None, period=1.2, rate=100.0)
    gait_cli._check_size(args, 1.2, 100.0, most)  # the last count allowed
    with pytest.raises(InvalidParameter, match=r"^period must be at most"):
        gait_cli._check_size(args, 1.2, 100.0, most + 1)


@pytest.mark.heavy
def test_gait_memory_per_sample_is_bounded_by_the_stated_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """The whole command's peak, the model and imports subtracted with a short run."""
    runs = {}
    for duration in (10.0, 1010.0):  # 1,001 and 101,001 samples at 100 Hz
        out = tmp_path / f"g{duration:g}.csv"
        argv = ["gait", "--duration", str(duration), "--csv", str(out)]
        runs[duration] = traced_peak(lambda argv=argv: cli.main(argv))
    capsys.readouterr()
    per_sample = (runs[1010.0] - runs[10.0]) / 100_000
    print(f"\ngait: {per_sample:.1f} B a sample (stated {gait_cli.GAIT_BYTES_PER_SAMPLE})")
    assert 8 * len(gait_cli.GAIT_CSV_HEADER) < per_sample <= gait_cli.GAIT_BYTES_PER_SAMPLE
    assert 1.5 * per_sample > gait_cli.GAIT_BYTES_PER_SAMPLE


# --------------------------------------------------------------------------- simulate


SIM_PLAN = (
    "exo-ctrl simulate: error: --duration: run.duration_s: must be at most 2275 s at 1000 Hz so "
    "that the plan "
    "rows fit in the 1 GiB memory cap (at most 2,274,876 of 472 B each); got 100000.0 "
    "(100,000,001 plan rows would need 43.96 GiB; the plan holds every tick, as the period "
    "1.2003 s is not a whole number of 1 ms ticks)\n"
)
SIM_PERIOD = (  # the gait period's own bound comes first (GaitParams, MAX_PERIOD_S)
    "exo-ctrl simulate: error: --period: gait.period: must be <= 100 s; got 1000000.0 (one "
    "gait cycle sizes "
    "the plan and the monitors' windows: a longer one would not fit in memory, or overflow)\n"
)
SIM_PERIOD_AT_SPEED = (  # the gait period's own bound comes first (GaitParams, MAX_PERIOD_S)
    "exo-ctrl simulate: error: --period: gait.period: must be <= 100 s; got 1000000.0 (one "
    "gait cycle sizes "
    "the plan and the monitors' windows: a longer one would not fit in memory, or overflow)\n"
)
SIM_ESTOP = (  # the default run: the ramp-in and two cycles, 3.6 s
    "exo-ctrl simulate: error: --estop-at: safety.estop_at_s: must be in [0, 3.599] s, within the "
    "run; got 4.0 "
    "(the run lasts 3.6 s; its last control tick is at t = 3.599 s)\n"
)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--duration", "1e5", "--period", "1.2003"], SIM_PLAN),
        (["--duration", "2e6", "--period", "1e6"], SIM_PERIOD),
        (["--duration", "2e6", "--period", "1e6", "--ramp-in", "0"], SIM_PERIOD_AT_SPEED),
        (["--estop-at", "4"], SIM_ESTOP),
    ],
    ids=["plan-every-tick", "plan-one-period", "plan-one-period-at-speed", "estop-after-the-end"],
)
def test_simulate_refuses_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], expected: str
) -> None:
    argv = ["simulate", *args, "--out", str(tmp_path / "r.rrd")]
    code = cli.main([*argv, "--summary", str(tmp_path / "s.json")])
    assert_refused(code, capsys.readouterr().err, expected, tmp_path)


def test_estop_at_the_last_tick_is_accepted_and_one_tick_later_refused() -> None:
    SimConfig(duration_s=2.4, estop_at_s=2.399)
    SimConfig(duration_s=2.4, estop_at_s=0.0)
    with pytest.raises(InvalidParameter) as info:
        SimConfig(duration_s=2.4, estop_at_s=2.4)  # no tick at t = 2.4 s: never acted
    assert (info.value.name, info.value.value) == ("estop_at", 2.4)
    with pytest.raises(InvalidParameter, match=r"^duration must be in \[0.001, 1e\+07\] s; got"):
        SimConfig(duration_s=0.0005, estop_at_s=0.0)  # a run has at least one tick
    with pytest.raises(InvalidParameter, match=r"^estop_at must be >= 0 s; got -1"):
        SimConfig(estop_at_s=-1.0)


def test_estop_refused_via_the_installed_command(tmp_path: Path) -> None:
    exe = Path(sys.executable).with_name("exo-ctrl")
    proc = subprocess.run(
        [str(exe), "simulate", "--estop-at", "4", "--out", str(tmp_path / "r.rrd")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert_refused(proc.returncode, proc.stderr, SIM_ESTOP, tmp_path)


def test_long_runs_with_a_periodic_plan_are_not_capped() -> None:
    """Only what grows is capped: the ramp-in's and one period's plan rows serve any duration."""
    config = SimConfig(duration_s=1e5)  # 1e8 ticks, the old 5e7-tick cap refused it
    assert config.plan_rows == 1200 + 1200
    with pytest.raises(InvalidParameter) as info:
        config.check_history()
    rows = v.max_items(HISTORY_BYTES_PER_TICK)  # grows with every logged signal
    assert str(info.value) == (
        f"duration must be at most {rows / 1000:.4g} s at 1000 Hz so that the history rows fit in "
        f"the 1 GiB memory cap (at most {rows:,} of {HISTORY_BYTES_PER_TICK} B each); got "
        f"100000.0 (100,000,000 history rows would need "
        f"{v.format_bytes(10**8 * HISTORY_BYTES_PER_TICK)}; "
        "simulate(keep_history=False) keeps none)"
    )
    # Just within the cap: one second less than the limit the message states.
    SimConfig(duration_s=rows // 1000 - 1.0).check_history()  # [s]


def test_chunk_ticks_beyond_the_cap() -> None:
    SimConfig(duration_s=3000.0, chunk_ticks=v.max_items(CHUNK_ROW_BYTES))
    SimConfig(duration_s=2.4, chunk_ticks=10**9)  # the chunk never exceeds the run
    with pytest.raises(InvalidParameter) as info:
        SimConfig(duration_s=3000.0, chunk_ticks=10**9)
    assert str(info.value) == (
        "chunk_ticks must be smaller so that the log chunk rows fit in the 1 GiB memory cap "
        f"(at most {v.max_items(CHUNK_ROW_BYTES):,} of {CHUNK_ROW_BYTES} B each); got "
        f"1000000000 (3,000,000 log chunk rows would need "
        f"{v.format_bytes(3 * 10**6 * CHUNK_ROW_BYTES)})"
    )


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"duration_s": 0.5},
        {"gait": GaitParams(period=1.2003)},
        {"gait": GaitParams(period=0.9), "control_rate_hz": 800.0},
        {"gait": GaitParams(period=1.0), "control_rate_hz": 300.0},
    ],
)
def test_plan_rows_are_the_ones_the_run_builds(kwargs: dict) -> None:
    config = SimConfig(**kwargs)
    assert config.plan_rows == build(config).plan.q.shape[0]


# --------------------------------------------------------------------------- measured sizes


def test_plan_rows_of_a_run_take_at_most_the_stated_bytes() -> None:
    gait = GaitParams(period=1.2003)  # not a whole number of ticks: a row per tick
    build(SimConfig(gait=gait, duration_s=0.1, controller="ct"))  # compiled, warmed
    peaks = {
        d: traced_peak(lambda d=d: build(SimConfig(gait=gait, duration_s=d, controller="ct")))
        for d in (2.0, 42.0)
    }
    per_row = (peaks[42.0] - peaks[2.0]) / 40_000
    assert 200 < per_row <= PLAN_ROW_BYTES < 1.6 * per_row


def test_chunk_and_history_rows_take_at_most_the_stated_bytes() -> None:
    simulate(SimConfig(duration_s=0.01), keep_history=False)  # compiled, warmed
    chunk = {
        ticks: traced_peak(
            lambda ticks=ticks: simulate(
                SimConfig(duration_s=12.0, chunk_ticks=ticks), keep_history=False
            )
        )
        for ticks in (1000, 11_000)
    }
    per_chunk_row = (chunk[11_000] - chunk[1000]) / 10_000
    assert 600 < per_chunk_row <= CHUNK_ROW_BYTES < 1.25 * per_chunk_row
    history = {
        d: traced_peak(lambda d=d: simulate(SimConfig(duration_s=d), keep_history=True))
        for d in (2.4, 12.0)
    }
    per_tick = (history[12.0] - history[2.4]) / 9600
    assert 600 < per_tick <= HISTORY_BYTES_PER_TICK < 1.1 * per_tick
