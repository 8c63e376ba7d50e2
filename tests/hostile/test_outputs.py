"""Outputs never replace inputs, never follow a link the user did not name, never hang.

Each case runs ``exo-ctrl`` in this process (:func:`exo_ctrl.cli.app.main`,
the checks come before any work) and asserts the exact line on stderr, the
exit code and that the file it would have replaced is unchanged.
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest
from hostile_corpus import csv_log, exo_urdf_text

from exo_ctrl import _io
from exo_ctrl.cli.app import main
from exo_ctrl.exceptions import OutputError
from exo_ctrl.sweep.journal import Journal

OUT_ALLOWED = "a writable file in an existing directory"


def run(argv: list[str], capsys) -> tuple[int, str]:
    """``exo-ctrl ARGV`` in this process: (exit code, stderr)."""
    code = main(argv)
    return code, capsys.readouterr().err


@pytest.fixture
def inputs(tmp_path: Path, monkeypatch) -> Path:
    """The working directory, holding an exoskeleton URDF, a session, a CSV log, a recording."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "e.urdf").write_text(exo_urdf_text())
    (tmp_path / "s.json").write_text('[{"duration": 0.05, "mode": "tracking"}]')
    csv_log(tmp_path, "log.csv", n=50)
    (tmp_path / "run.rrd").write_bytes(b"a recording")  # refused before it is read
    return tmp_path


#: The files of :func:`inputs`.
INPUTS = ["e.urdf", "s.json", "log.csv", "run.rrd"]


@pytest.mark.parametrize(
    ("argv", "victim", "message"),
    [
        # listed in issue 32: the URDF replaced by the summary, by its name and a hard link
        (
            ["simulate", "--exo", "e.urdf", "--summary", "e.urdf", "--no-record"],
            "e.urdf",
            "--summary must be a file other than --exo; got 'e.urdf' (one would replace the other)",
        ),
        (
            ["simulate", "--exo", "e.urdf", "--summary", "hard.urdf", "--no-record"],
            "e.urdf",
            "--summary must be a file other than --exo; got 'hard.urdf' "
            "(one would replace the other)",
        ),
        # sibling: the URDF named by a scenario key, not an option
        (
            ["simulate", "--set", "urdf.exo=e.urdf", "--summary", "hard.urdf", "--no-record"],
            "e.urdf",
            "--summary must be a file other than the exoskeleton URDF (urdf.exo); got "
            "'hard.urdf' (one would replace the other)",
        ),
        # listed: estimate --out a hard link to its input recording (refused before reading)
        (
            ["estimate", "run.rrd", "--out", "hardrun.rrd"],
            "run.rrd",
            "--out must be a file other than the input file; got 'hardrun.rrd' "
            "(one would replace the other)",
        ),
        # listed: the session replaced by the recording
        (
            ["simulate", "--session", "s.json", "--out", "s.json"],
            "s.json",
            "--out must be a file other than --session; got 's.json' (one would replace the other)",
        ),
        # siblings: the device's URDF given to the controller, through a symbolic link
        (
            ["simulate", "--controller-exo", "e.urdf", "--out", "soft.urdf"],
            "e.urdf",
            "--out must be a file other than --controller-exo; got 'soft.urdf' "
            "(one would replace the other)",
        ),
        (
            ["estimate", "log.csv", "--summary", "hardlog.csv"],
            "log.csv",
            "--summary must be a file other than the input file; got 'hardlog.csv' "
            "(one would replace the other)",
        ),
        (
            ["identify", "log.csv", "--exo", "e.urdf", "--out", "hard.urdf"],
            "e.urdf",
            "--out must be a file other than --exo; got 'hard.urdf' (one would replace the other)",
        ),
    ],
)
def test_an_output_naming_an_input_by_any_name_is_refused(
    inputs: Path, capsys, argv: list[str], victim: str, message: str
) -> None:
    os.link(inputs / "e.urdf", inputs / "hard.urdf")
    os.link(inputs / "log.csv", inputs / "hardlog.csv")
    os.link(inputs / "run.rrd", inputs / "hardrun.rrd")
    os.symlink("e.urdf", inputs / "soft.urdf")
    before = (inputs / victim).read_bytes()
    code, err = run(argv, capsys)
    assert (code, err) == (2, f"exo-ctrl {argv[0]}: error: {message}\n")
    assert (inputs / victim).read_bytes() == before
    assert sorted(p.name for p in inputs.iterdir()) == sorted(
        [*INPUTS, "hard.urdf", "hardlog.csv", "hardrun.rrd", "soft.urdf"]
    )


def test_the_default_recording_path_is_not_followed_through_a_link(inputs: Path, capsys) -> None:
    victim = inputs / "someone_elses.rrd"
    victim.write_bytes(b"precious")
    os.symlink(victim, inputs / "exo_run.rrd")
    code, err = run(["simulate", "--duration", "0.05"], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl simulate: error: --out must be {OUT_ALLOWED}; got 'exo_run.rrd' "
        f"(exo_run.rrd, the default, is a symbolic link to {victim}; a link is followed "
        "only when named)\n",
    )
    assert victim.read_bytes() == b"precious"


def test_a_planted_partial_file_link_is_refused(inputs: Path, capsys) -> None:
    """Sibling: the partial file a recording is written to is a name the user did not give."""
    victim = inputs / "victim.rrd"
    victim.write_bytes(b"precious")
    os.symlink(victim, inputs / "run.partial.rrd")
    code, err = run(["simulate", "--duration", "0.05", "--out", "run.rrd"], capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl simulate: error: --out must be {OUT_ALLOWED}; got 'run.rrd' "
        "(run.partial.rrd is a symbolic link; the recording is written there first)\n",
    )
    assert victim.read_bytes() == b"precious"


NAMED_BY_COMMAND = (
    "named by the command, is a symbolic link to {target}; a link is followed only when named"
)


@pytest.mark.parametrize(
    ("argv", "link", "option", "got"),
    [
        # the files a command names inside or beside a path the user gave (siblings of the
        # default exo_run.rrd listed in issue 32): a torque-speed plot in --plots DIR
        (["simulate", "--duration", "0.05", "--no-record", "--plots", "D"],
         "D/torque_speed.png", "--plots", "D/torque_speed.png"),
        # compare's table in --out DIR
        (["compare", "--controllers", "pd", "--duration", "0.05", "--out", "D"],
         "D/compare.csv", "--out", "D/compare.csv"),
        # a sweep's journal (appended to) and report beside --out NAME.parquet
        (["sweep", "--param", "step_length=0.3", "--duration", "0.05", "--out", "sw.parquet"],
         "sw.journal.jsonl", "--out", "sw.parquet"),
        (["sweep", "--param", "step_length=0.3", "--duration", "0.05", "--out", "sw.parquet"],
         "sw.report.txt", "--out", "sw.parquet"),
        (["sweep", "--param", "step_length=0.3", "--duration", "0.05", "--out", "sw.parquet"],
         "sw.urdf_cache", "--out", "sw.parquet"),
        # a cohort's files in a directory, and one URDF's default name in a directory
        (["urdf", "--kind", "patient", "--height", "1.7", "--mass", "70", "--cohort", "2",
          "--out", "D"], "D/patient_s0_001.urdf", "--out", "D/patient_s0_001.urdf"),
        (["urdf", "--kind", "exo", "--out", "D"],
         "D/exoskeleton.urdf", "--out", "D/exoskeleton.urdf"),
        # a cohort's pattern: each file it expands to was not named literally
        (["urdf", "--kind", "patient", "--height", "1.7", "--mass", "70", "--cohort", "2",
          "--out", "p_{i}.urdf"], "p_1.urdf", "--out", "p_1.urdf"),
    ],
)  # fmt: skip
def test_a_file_the_command_names_is_not_followed_through_a_link(
    inputs: Path, capsys, monkeypatch, argv: list[str], link: str, option: str, got: str
) -> None:
    monkeypatch.setattr("exo_ctrl.cli.simulate.simulate", _must_not_run)
    monkeypatch.setattr("exo_ctrl.sweep.run.simulate", _must_not_run)
    (inputs / "D").mkdir()
    victim = inputs / "victim"
    victim.write_bytes(b"precious")
    os.symlink(victim, inputs / link)
    code, err = run(argv, capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl {argv[0]}: error: {option} must be {OUT_ALLOWED}; got '{got}' "
        f"({link}, {NAMED_BY_COMMAND.format(target=victim)})\n",
    )
    assert victim.read_bytes() == b"precious"
    assert os.path.islink(inputs / link)


def _must_not_run(*args: object, **kwargs: object) -> None:
    raise AssertionError("the run started")


def test_a_link_planted_after_the_check_is_replaced_not_followed(tmp_path: Path) -> None:
    """Sibling: between the check and the write a link appears; the rename replaces the link."""
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    os.symlink(victim, tmp_path / "report.txt")
    with _io.atomic_write(_io.DerivedOutput(tmp_path / "report.txt")) as handle:
        handle.write("the report\n")
    assert victim.read_bytes() == b"precious"
    assert not os.path.islink(tmp_path / "report.txt")
    assert (tmp_path / "report.txt").read_text() == "the report\n"
    named = tmp_path / "named.txt"  # a link the user named is written through, as before
    os.symlink(victim, named)
    with _io.atomic_write(named) as handle:
        handle.write("asked for")
    assert victim.read_text() == "asked for"


def test_a_sweep_journal_link_planted_after_the_check_is_refused(tmp_path: Path) -> None:
    """Sibling: the journal is appended to, never through a link (O_NOFOLLOW)."""
    victim = tmp_path / "victim"
    victim.write_bytes(b"precious")
    os.symlink(victim, tmp_path / "s.journal.jsonl")
    with pytest.raises(OutputError) as caught:
        Journal(tmp_path / "s.journal.jsonl")
    assert str(caught.value) == (
        f"cannot write {tmp_path / 's.journal.jsonl'}: a symbolic link; a link is followed "
        "only when named"
    )
    assert victim.read_bytes() == b"precious"


def _mkfifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["gait", "--csv", "fifo"], "fifo"),  # a FIFO as the gait's table
        (["simulate", *["--duration", "0.05", "--no-record"], "--summary", "fifo"], "fifo"),
        # the recording, opened before the run: the same line and exit code (was 2)
        (["simulate", "--duration", "0.05", "--out", "fifo"], "fifo"),
    ],
)
def test_a_fifo_without_reader_fails_after_the_timeout_not_never(
    inputs: Path, capsys, monkeypatch, argv: list[str], option: str
) -> None:
    monkeypatch.setattr(_io, "FIFO_OPEN_TIMEOUT_S", 0.3)
    _mkfifo(inputs / "fifo")
    start = time.monotonic()
    code, err = run(argv, capsys)
    waited = time.monotonic() - start
    assert err.splitlines()[-1] == (
        f"exo-ctrl {argv[0]}: error: cannot write {option}: "
        "no process opened the FIFO for reading within 0.3 s"
    )
    assert code == 1
    assert waited < 120.0  # a run and 0.3 s, not forever
    assert (inputs / "fifo").exists() and not (inputs / "fifo").is_file()


def test_open_special_waits_for_a_late_reader(tmp_path: Path) -> None:
    """Sibling: a reader that comes within the timeout gets everything (nothing refused early)."""
    import threading

    fifo = _mkfifo(tmp_path / "late")
    got: list[bytes] = []

    def reader() -> None:
        time.sleep(0.2)
        with open(fifo, "rb") as handle:
            got.append(handle.read())

    thread = threading.Thread(target=reader)
    thread.start()
    with _io.atomic_write(fifo, "wb") as handle:
        handle.write(b"x" * 100_000)
    thread.join(10)
    assert got == [b"x" * 100_000]


def test_same_file_key_counts_hard_and_symbolic_links(tmp_path: Path) -> None:
    a = tmp_path / "a"
    a.write_text("a")
    os.link(a, tmp_path / "b")
    os.symlink(a, tmp_path / "c")
    shutil.copy(a, tmp_path / "d")
    key = _io.same_file_key(a)
    assert _io.same_file_key(tmp_path / "b") == key == _io.same_file_key(tmp_path / "c")
    assert _io.same_file_key(tmp_path / "d") != key
    assert _io.same_file_key(tmp_path / "new") == ("path", str(tmp_path / "new"))


NOT_READ = "not a regular file (a FIFO or a device is not read: it may never end)"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        # siblings of the FIFO outputs in issue 32: a FIFO as an input would block the read
        (
            ["simulate", "--exo", "fifo", "--duration", "0.05", "--no-record"],
            f"invalid model: fifo: {NOT_READ}",
        ),
        (["estimate", "fifo.csv"], f"invalid log fifo.csv: {NOT_READ}"),
        (["export", "fifo.rrd", "--out", "x.csv"], f"cannot read recording fifo.rrd: {NOT_READ}"),
        (["estimate", "D.rrd"], "cannot read recording D.rrd: a directory, not a file"),
    ],
)
def test_a_fifo_or_directory_as_input_is_refused_not_read(
    inputs: Path, capsys, argv: list[str], message: str
) -> None:
    for name in ("fifo", "fifo.csv", "fifo.rrd"):
        _mkfifo(inputs / name)
    (inputs / "D.rrd").mkdir()
    code, err = run(argv, capsys)
    assert (code, err) == (2, f"exo-ctrl {argv[0]}: error: {message}\n")


NOT_REGULAR = "is not a regular file (a FIFO or a device); only a path you name is written to one"


@pytest.mark.parametrize(
    ("argv", "fifo", "got", "how"),
    [
        # siblings of the FIFO --out in issue 32: a FIFO at a path the user did not name would
        # have held the sweep 10 s after every run, then failed; now refused before the first
        (
            ["sweep", "--param", "step_length=0.3", "--duration", "0.05", "--out", "sw.parquet"],
            "sw.csv",
            "sw.parquet",
            "named by the command",
        ),
        (["simulate", "--duration", "0.05"], "exo_run.rrd", "exo_run.rrd", "the default"),
    ],
)
def test_a_fifo_at_a_path_the_user_did_not_name_is_refused_up_front(
    inputs: Path, capsys, monkeypatch, argv: list[str], fifo: str, got: str, how: str
) -> None:
    monkeypatch.setattr("exo_ctrl.cli.simulate.simulate", _must_not_run)
    monkeypatch.setattr("exo_ctrl.sweep.run.simulate", _must_not_run)
    _mkfifo(inputs / fifo)
    code, err = run(argv, capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl {argv[0]}: error: --out must be {OUT_ALLOWED}; got '{got}' "
        f"({fifo}, {how}, {NOT_REGULAR})\n",
    )


def test_the_recordings_partial_file_never_replaces_an_input(inputs: Path, capsys) -> None:
    """Sibling: the recorder claims NAME.partial.rrd and renames it over NAME.rrd; an input
    of that name (here the exoskeleton's URDF) was emptied and moved away (exit 0)."""
    urdf = inputs / "walk.partial.rrd"
    urdf.write_text(exo_urdf_text())
    argv = ["simulate", "--exo", "walk.partial.rrd", "--duration", "0.05", "--out", "walk.rrd"]
    code, err = run(argv, capsys)
    assert (code, err) == (
        2,
        "exo-ctrl simulate: error: --out must be a file other than --exo; got "
        "'walk.partial.rrd' (one would replace the other)\n",
    )
    assert urdf.read_text() == exo_urdf_text()
    assert not (inputs / "walk.rrd").exists()
