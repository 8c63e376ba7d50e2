"""Parsing limits before parsers: sizes and depths refused by name before anything allocates.

Pinocchio's URDF parser crashes the process on about 6000 chained joints,
Python's JSON parser recurses per nesting level, numpy allocates what a
file declares: each case is refused with one line and exit 2 first.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tracemalloc
from pathlib import Path

import pytest
from hostile_corpus import (
    SHORT_RUN,
    chained_urdf,
    csv_log,
    exo_ctrl,
    exo_urdf_text,
    meta_rrd,
    nested_json,
    nested_xml_urdf,
    valid_meta,
)

from exo_ctrl.cli.app import main
from exo_ctrl.estimation.csvlog import CSV_REQUIRED_COLUMNS
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import default_urdf_path
from exo_ctrl.plant import ContactParams
from exo_ctrl.sim import SimConfig, build
from exo_ctrl.sim.config_checks import BELT_ROW_BYTES


def run(argv: list[str], capsys) -> tuple[int, str]:
    code = main(argv)
    return code, capsys.readouterr().err


def test_a_urdf_of_6000_chained_joints_is_refused_not_a_segfault(tmp_path: Path) -> None:
    urdf = chained_urdf(tmp_path, 6000)
    assert urdf.stat().st_size > 1_000_000
    proc = exo_ctrl(["simulate", "--exo", str(urdf), *SHORT_RUN], tmp_path)
    assert (proc.returncode, proc.stderr) == (
        2,
        f"exo-ctrl simulate: error: invalid model: {urdf}: more than 1000 links; a URDF may "
        "have at most 1000 (Pinocchio's parser crashes on about 6000 chained joints)\n",
    )


@pytest.mark.parametrize(
    ("make", "option", "reason"),
    [
        (
            lambda d: nested_xml_urdf(d, 40),
            "--patient",
            "elements nested more than 32 deep (at <a>); a URDF nests about 5",
        ),
        (
            lambda d: _padded_urdf(d, 9 << 20),
            "--exo",
            "the file is 9.005 MiB; a URDF is read up to 8 MiB (a leg model is a few kB)",
        ),
        (
            lambda d: _joints_only(d, 1001),
            "--controller-exo",
            "more than 1000 joints; a URDF may have at most 1000 (Pinocchio's parser crashes "
            "on about 6000 chained joints)",
        ),
    ],
)
def test_urdf_depth_size_and_parts_siblings(
    tmp_path: Path, capsys, make, option: str, reason: str
) -> None:
    urdf = make(tmp_path)
    code, err = run(["simulate", option, str(urdf), *SHORT_RUN], capsys)
    assert (code, err) == (2, f"exo-ctrl simulate: error: invalid model: {urdf}: {reason}\n")


def _padded_urdf(directory: Path, size: int) -> Path:
    text = exo_urdf_text().replace("</robot>", "<!--" + "x" * size + "--></robot>")
    path = directory / "padded.urdf"
    path.write_text(text)
    return path


def _joints_only(directory: Path, n: int) -> Path:
    joints = "".join(f'<joint name="j{i}" type="fixed"/>' for i in range(n))
    path = directory / "joints.urdf"
    path.write_text(exo_urdf_text().replace("</robot>", joints + "</robot>"))
    return path


@pytest.mark.parametrize("depth", [5000, 65])
def test_a_deeply_nested_session_is_refused_by_name(tmp_path: Path, capsys, depth: int) -> None:
    session = nested_json(tmp_path, depth)
    code, err = run(["simulate", "--session", str(session), *SHORT_RUN], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl simulate: error: session must be a JSON list of segments; got '{session}' "
        f"(nested {depth} levels deep; at most 64 are read)\n",
    )


@pytest.mark.parametrize(
    ("meta", "reason"),
    [
        ("[" * 5000 + "]" * 5000, "raw/meta is nested 5000 levels deep; at most 64 are read"),
        (
            json.dumps(valid_meta(signals={"q": [4], "huge": [1_000_000, 3_000_000]})),
            "raw/meta declares signals of 3,000,000,000,004 values a tick: 1 ticks would need "
            "21.83 TiB, beyond the 1 GiB memory cap",
        ),
        (
            json.dumps(valid_meta(signals={"q": [[4]]})),
            "raw/meta declares signal 'q' of shape [[4]]: at most 4 integers >= 0",
        ),
        (
            json.dumps(valid_meta(signals={"q": [-4]})),
            "raw/meta declares signal 'q' of shape [-4]: at most 4 integers >= 0",
        ),
    ],
)
def test_recording_metadata_is_checked_before_allocation(
    tmp_path: Path, capsys, meta: str, reason: str
) -> None:
    rrd = meta_rrd(tmp_path, meta)
    code, err = run(["estimate", str(rrd)], capsys)
    assert (code, err) == (2, f"exo-ctrl estimate: error: cannot read recording {rrd}: {reason}\n")


GOOD_OUTCOME = {"status": "completed", "error": "", "events": [], "ticks": 0, "warnings": []}


@pytest.mark.parametrize(
    ("meta", "outcome", "command", "reason"),
    [
        # siblings of the nested and oversized metadata in issue 32: values of the wrong type
        # (each was a traceback: AttributeError, TypeError, ValueError)
        (valid_meta(config=5), GOOD_OUTCOME, "estimate",
         "its config must be a table of SimConfig; got int"),
        (valid_meta(belt_speed_mps="x"), GOOD_OUTCOME, "export",
         "raw/meta's belt_speed_mps must be a finite number; got 'x'"),
        (valid_meta(exo_source=["a.urdf"]), GOOD_OUTCOME, "estimate",
         "raw/meta's exo_source must be a string; got ['a.urdf']"),
        (valid_meta(), 5, "scenario", "raw/outcome must be a table; got int"),
        (valid_meta(), {**GOOD_OUTCOME, "events": [5]}, "compare",
         "raw/outcome's events must be a list of tables, each with a number t; got [5]"),
        (valid_meta(), {**GOOD_OUTCOME, "wall_time_s": None}, "compare",
         "raw/outcome's wall_time_s must be a number; got None"),
    ],
)  # fmt: skip
def test_recording_documents_of_the_wrong_type_are_refused_by_key(
    tmp_path: Path, capsys, meta: dict, outcome: object, command: str, reason: str
) -> None:
    rrd = meta_rrd(tmp_path, json.dumps(meta), outcome_text=json.dumps(outcome))
    argv = {
        "estimate": ["estimate", str(rrd)],
        "export": ["export", str(rrd), "--out", str(tmp_path / "x.csv")],
        "scenario": ["scenario", "--from", str(rrd), "--out", str(tmp_path / "x.toml")],
        "compare": ["compare", str(rrd), str(shutil.copy(rrd, tmp_path / "b.rrd")), "--out",
                    str(tmp_path / "D")],
    }[command]  # fmt: skip
    code, err = run(argv, capsys)
    assert (code, err) == (2, f"exo-ctrl {command}: error: cannot read recording {rrd}: {reason}\n")


def test_a_recording_config_value_of_the_wrong_type_names_its_key(tmp_path: Path, capsys) -> None:
    """Sibling: a table where the config has a number (scenario --from failed writing TOML)."""
    config = {**valid_meta()["config"], "observer_gain_per_s": {"a": 1}}
    rrd = meta_rrd(tmp_path, json.dumps(valid_meta(config=config)))
    code, err = run(["scenario", "--from", str(rrd), "--out", str(tmp_path / "x.toml")], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl scenario: error: cannot read recording {rrd}: its config is invalid "
        "(observer_gain_per_s must be a number; got {'a': 1})\n",
    )


def test_a_recording_naming_a_hostile_urdf_is_refused_and_a_named_one_announced(
    tmp_path: Path, capsys
) -> None:
    exo = tmp_path / "my_exo.urdf"
    shutil.copy(default_urdf_path("exo"), exo)
    rrd = tmp_path / "run.rrd"
    assert main(["simulate", "--exo", str(exo), "--duration", "0.1", "--out", str(rrd)]) == 0
    capsys.readouterr()
    code, err = run(["estimate", str(rrd)], capsys)
    assert code == 0
    assert err == (
        f"exo-ctrl estimate: warning: {rrd}: read with the exoskeleton URDF it names, {exo} "
        "(--exo: another)\n"
    )
    chained_urdf(tmp_path, 6000, name="my_exo.urdf")  # the file the recording names, replaced
    reason = (
        f"cannot read {rrd}: the exoskeleton URDF it names, {exo}, cannot be loaded (invalid "
        f"model: {exo}: more than 1000 links; a URDF may have at most 1000 (Pinocchio's parser "
        "crashes on about 6000 chained joints)); give the model with --exo"
    )
    code, err = run(["estimate", str(rrd)], capsys)
    assert (code, err) == (2, f"exo-ctrl estimate: error: {reason}\n")
    # sibling: identify reads the recording's exoskeleton the same way
    code, err = run(["identify", str(rrd), "--out", str(tmp_path / "p.urdf")], capsys)
    assert (code, err) == (2, f"exo-ctrl identify: error: {reason}\n")


def test_a_recording_naming_a_patient_urdf_says_so_and_refuses_a_hostile_one(
    tmp_path: Path, capsys
) -> None:
    """Sibling: the Kalman filter reads the patient URDF a recording names (it said nothing)."""
    patient = tmp_path / "my_patient.urdf"
    shutil.copy(default_urdf_path("patient"), patient)
    rrd = tmp_path / "run.rrd"
    argv = ["simulate", "--patient", str(patient), "--duration", "0.1", "--out", str(rrd)]
    assert main(argv) == 0
    capsys.readouterr()
    code, err = run(["estimate", str(rrd)], capsys)
    assert (code, err) == (
        0,
        f"exo-ctrl estimate: warning: {rrd}: read with the patient URDF it names, {patient} "
        "(the Kalman filter's device model; --estimator momentum reads none)\n",
    )
    assert run(["estimate", str(rrd), "--estimator", "momentum"], capsys) == (0, "")
    chained_urdf(tmp_path, 6000, name="my_patient.urdf")
    code, err = run(["estimate", str(rrd)], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl estimate: error: cannot estimate from {rrd} with the kalman estimator: the "
        f"device's patient model cannot be rebuilt (invalid model: {patient}: more than 1000 "
        "links; a URDF may have at most 1000 (Pinocchio's parser crashes on about 6000 chained "
        "joints)); --estimator momentum needs none\n",
    )


def test_csv_logs_beyond_the_memory_cap_are_refused_before_reading(tmp_path: Path, capsys) -> None:
    rows = tmp_path / "rows.csv"  # 1.8 million lines: about 1 GiB to read, 1.8 MB on disk
    rows.write_bytes(b"\n" * 1_800_000)
    code, err = run(["estimate", str(rows)], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl estimate: error: invalid log {rows}: 1,800,000 rows would need about "
        "1.006 GiB to read (600 B a row), beyond the 1 GiB memory cap: at most 1,789,569 rows\n",
    )
    big = tmp_path / "big.csv"  # sibling: over the cap by its size alone (a sparse file)
    with big.open("wb") as handle:
        handle.truncate((1 << 30) + 1)
    code, err = run(["identify", str(big), "--out", str(tmp_path / "p.urdf")], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl identify: error: invalid log {big}: the file is 1 GiB; a CSV log is read "
        "up to 1 GiB\n",
    )
    ok = csv_log(tmp_path, n=100)  # a plausible log below the cap still reads
    assert run(["estimate", str(ok)], capsys)[0] == 0


def test_a_wide_csv_log_is_refused_by_its_width_before_reading(tmp_path: Path, capsys) -> None:
    """Few rows, 8 million columns: the header alone would take about 600 MB as text."""
    wide = tmp_path / "wide.csv"  # 16 MB on disk
    header = ",".join(CSV_REQUIRED_COLUMNS).encode() + b",x" * 8_000_000 + b"\n"
    wide.write_bytes(header + b"0,0,0,0,0,0,0,0,0\n0.001,0,0,0,0,0,0,0,0\n")
    code, err = run(["estimate", str(wide)], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl estimate: error: invalid log {wide}: a line of 8,000,009 fields would need "
        "about 1.103 GiB to read (the header and a row held as text, 72 B a field and the "
        "line's 15.26 MiB each; 600 B a row for 3 rows), beyond the 1 GiB memory cap\n",
    )
    # sibling: a million columns passes the check and is read (its short row then refused)
    narrower = tmp_path / "narrower.csv"
    header = ",".join(CSV_REQUIRED_COLUMNS).encode() + b",x" * 1_000_000 + b"\n"
    narrower.write_bytes(header + b"0,0,0,0,0,0,0,0,0\n")
    code, err = run(["estimate", str(narrower)], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl estimate: error: invalid log {narrower}, line 2: 9 fields, the header has "
        "1000009\n",
    )
    # sibling: one field past the csv module's limit was a traceback (_csv.Error)
    long = tmp_path / "long.csv"
    long.write_text(",".join(CSV_REQUIRED_COLUMNS) + ",x\n" + "0," * 9 + "a" * 200_000 + "\n")
    code, err = run(["estimate", str(long)], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl estimate: error: invalid log {long}: not a CSV log: field larger than field "
        "limit (131072)\n",
    )


@pytest.mark.parametrize(
    ("pattern", "reason"),
    [
        ("p_{i:99999999999}.urdf", "the field {i:99999999999} is wider than 32 characters"),
        ("p_{i:999999999}.urdf", "the field {i:999999999} is wider than 32 characters"),
        ("p_{i:{i}}.urdf", "a nested field in {i:{i}}"),
        ("p_{i:.40}.urdf", "the field {i:.40} is wider than 32 characters"),
    ],
)
def test_cohort_patterns_are_checked_before_formatting(
    tmp_path: Path, capsys, pattern: str, reason: str
) -> None:
    argv = ["urdf", "--kind", "patient", "--cohort", "2", "--height", "1.75", "--mass", "80"]
    code, err = run([*argv, "--out", str(tmp_path / pattern)], capsys)
    allowed = "an existing directory or a file pattern with {i} (e.g. cohort/p{i:02d}.urdf)"
    assert (code, err) == (
        2,
        f"exo-ctrl urdf: error: --out must be {allowed}; got '{tmp_path / pattern}' ({reason})\n",
    )
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("argv", "value"),
    [
        (["simulate", "--period", "1e7", *SHORT_RUN], "10000000.0"),
        (["simulate", "--period", "1e200", *SHORT_RUN], "1e+200"),
        (["gait", "--period", "1e12", "--csv", "g.csv"], "1000000000000.0"),
    ],
)
def test_an_absurd_gait_period_is_refused_by_name(
    tmp_path: Path, capsys, monkeypatch, argv: list[str], value: str
) -> None:
    monkeypatch.chdir(tmp_path)
    code, err = run(argv, capsys)
    prefix = "--period: gait.period: " if argv[0] == "simulate" else ""  # simulate names the key
    assert (code, err) == (
        2,
        f"exo-ctrl {argv[0]}: error: {prefix or 'period '}must be <= 100 s; got {value} (one gait "
        "cycle sizes "
        "the plan and the monitors' windows: a longer one would not fit in memory, or "
        "overflow)\n",
    )
    assert list(tmp_path.iterdir()) == []


def test_the_corpus_script_writes_every_kind_small(tmp_path: Path) -> None:
    """Item 6 of issue 32: the corpus is made by a script, nothing large stored."""
    script = Path(__file__).with_name("corpus.py")
    proc = subprocess.run(
        [sys.executable, str(script), str(tmp_path / "c")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    made = [Path(line) for line in proc.stdout.splitlines()]
    assert sorted(p.name for p in made) == sorted(p.name for p in (tmp_path / "c").iterdir())
    assert len(made) == 9
    assert max(p.stat().st_size for p in made) < 2_000_000
    assert script.stat().st_size < 20_000


def test_a_long_run_on_the_belt_is_refused_before_its_speeds_are_planned(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    """Sibling of the period in issue 32: 1e7 s on the belt (74.5 GiB asked, a traceback)."""
    monkeypatch.chdir(tmp_path)
    code, err = run(["simulate", "--duration", "1e7", "--no-record"], capsys)  # paper: belt on
    assert (code, err) == (
        2,
        "exo-ctrl simulate: error: --duration: run.duration_s: must be at most 8389 s at 1000 Hz "
        "with the belt on so that the belt speed samples fit in the 1 GiB memory cap (at most "
        "8,388,608 of 128 B each); got 10000000.0 (10,000,000,000 belt speed samples would "
        "need 1.164 TiB; the belt's set speed is planned for every tick)\n",
    )
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InvalidParameter):  # the library refuses it too, before any allocation
        SimConfig(contact=ContactParams(enabled=True), duration_s=8389.0)
    SimConfig(contact=ContactParams(enabled=True), duration_s=8388.0)
    SimConfig(duration_s=1e7)  # free air: nothing is planned per tick


def test_the_belt_speed_plan_takes_at_most_the_stated_bytes() -> None:
    def peak(duration: float) -> int:
        config = SimConfig(contact=ContactParams(enabled=True), duration_s=duration)
        tracemalloc.start()
        try:
            base = tracemalloc.get_traced_memory()[0]
            build(config)
            return tracemalloc.get_traced_memory()[1] - base
        finally:
            tracemalloc.stop()

    peak(0.5)  # compiled, warmed
    per_tick = (peak(62.0) - peak(2.0)) / 60_000
    assert 40 < per_tick <= BELT_ROW_BYTES < 3 * per_tick


@pytest.mark.parametrize(
    ("text", "depth"),
    [
        ("x = " + "[" * 5000 + "]" * 5000 + "\n", 5000),  # arrays (a RecursionError)
        ("x = " + "{a = " * 3000 + "1" + "}" * 3000 + "\n", 3000),  # inline tables
        ('# [[[[ a comment\nx = "[[[[ a string"\n' + "y = " + "[" * 65 + "]" * 65, 65),
    ],
)
def test_a_deeply_nested_scenario_file_is_refused_by_name(
    tmp_path: Path, capsys, text: str, depth: int
) -> None:
    """Siblings of the 5000-deep session JSON in issue 32: a scenario file, a --set value."""
    scenario = tmp_path / "deep.toml"
    scenario.write_text(text)
    code, err = run(["simulate", str(scenario), "--no-record"], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl simulate: error: scenario {scenario}: nested {depth} levels deep; at most 64 "
        "are read\n",
    )


def test_a_deeply_nested_set_value_is_refused_by_name(capsys) -> None:
    code, err = run(["simulate", "--set", "gait.period=" + "[" * 3000 + "]" * 3000], capsys)
    assert (code, err) == (
        2,
        "exo-ctrl simulate: error: --set: gait.period: the value is nested 3000 levels deep; "
        "at most 64 are read\n",
    )
