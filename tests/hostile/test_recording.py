"""Nothing lost: a recording is written beside its destination and renamed when whole.

A previous recording survives a run that is killed (SIGKILL, SIGTERM), the
partial file reads back and is named in the message; a second run writing
the same path refuses at its start; ``estimate --out`` is written whole or
not at all.  Real ``exo-ctrl`` processes where the process is the point.
"""

from __future__ import annotations

import fcntl
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hostile_corpus import EXO_CTRL, csv_log, exo_ctrl

from exo_ctrl import _io
from exo_ctrl.cli.app import main
from exo_ctrl.exceptions import RecordingError
from exo_ctrl.record import RerunRecorder, read_recording
from exo_ctrl.sim import SimConfig, simulate

RERUN = Path(sys.executable).parent / "rerun"
OLD = b"the previous recording, byte for byte"


def _verify(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(RERUN), "rrd", "verify", str(path)], capture_output=True, timeout=60)


def _wait_for(path: Path, size: int, proc: subprocess.Popen, timeout: float = 90.0) -> None:
    deadline = time.monotonic() + timeout
    while not (path.is_file() and path.stat().st_size > size):
        assert proc.poll() is None, proc.returncode
        assert time.monotonic() < deadline
        time.sleep(0.05)


def test_partial_path_names() -> None:
    assert _io.partial_path("runs/a.rrd") == Path("runs/a.partial.rrd")
    assert _io.partial_path("a") == Path("a.partial.rrd")
    assert _io.partial_path("a.b.rrd") == Path("a.b.partial.rrd")


def test_a_second_run_on_one_path_refuses_at_start(tmp_path: Path, capsys) -> None:
    """Another process's lock (here: another open file description, as flock sees it)."""
    out = tmp_path / "same.rrd"
    out.write_bytes(OLD)
    held = _io.claim_partial(out)
    try:
        code = main(["simulate", "--duration", "0.05", "--out", str(out)])
        err = capsys.readouterr().err
        assert (code, err) == (
            2,
            f"exo-ctrl simulate: error: --out must be a writable file in an existing directory; "
            f"got '{out}' ({tmp_path / 'same.partial.rrd'} is locked: another exo-ctrl process "
            f"is writing {out})\n",
        )
        # Sibling: the lock taken after the up-front check (a race) fails the recorder's start.
        with pytest.raises(RecordingError) as info:
            simulate(SimConfig(duration_s=0.05), observers=[RerunRecorder(out)])
        assert str(info.value) == (
            f"cannot write recording {out}: {tmp_path / 'same.partial.rrd'} is locked: "
            f"another exo-ctrl process is writing {out}"
        )
    finally:
        os.close(held)
    assert out.read_bytes() == OLD
    assert not _io.partial_in_use(out)


def test_claim_partial_unlinks_a_hard_link_instead_of_emptying_it(tmp_path: Path) -> None:
    other = tmp_path / "other.rrd"
    other.write_bytes(OLD)
    os.link(other, tmp_path / "x.partial.rrd")
    fd = _io.claim_partial(tmp_path / "x.rrd")
    try:
        assert os.fstat(fd).st_nlink == 1 and os.fstat(fd).st_size == 0
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # ours
    finally:
        os.close(fd)
    assert other.read_bytes() == OLD


@pytest.mark.parametrize("kill", ["SIGKILL", "SIGTERM"])
def test_a_killed_run_keeps_the_previous_recording_and_a_readable_partial(
    tmp_path: Path, kill: str
) -> None:
    out = tmp_path / "run.rrd"
    partial = tmp_path / "run.partial.rrd"
    out.write_bytes(OLD)
    argv = [str(EXO_CTRL), "simulate", "--duration", "600", "--out", str(out)]
    argv += ["--summary", str(tmp_path / "s.json")]
    # Output to files, not pipes left unread: SIGTERM while the progress bar's write to a
    # full stderr pipe blocks left a corrupt footer in 3 of 6 runs (cause not found; reported).
    log_out, log_err = (tmp_path / "out.txt").open("w+b"), (tmp_path / "err.txt").open("w+b")
    proc = subprocess.Popen(argv, cwd=tmp_path, stdout=log_out, stderr=log_err)
    try:
        _wait_for(partial, 1_000_000, proc)  # a chunk or more on disk
        second = exo_ctrl(["simulate", "--duration", "0.05", "--out", str(out)], tmp_path)
        assert second.returncode == 2
        assert second.stderr == (
            f"exo-ctrl simulate: error: --out must be a writable file in an existing directory; "
            f"got '{out}' ({partial} is locked: another exo-ctrl process is writing {out})\n"
        )
        proc.send_signal(getattr(signal, kill))
        proc.wait(timeout=60)
        stdout = (tmp_path / "out.txt").read_bytes()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        log_out.close()
        log_err.close()
    assert out.read_bytes() == OLD
    back = read_recording(partial)
    assert back.n_ticks > 0
    deadline = time.monotonic() + 30  # the writer process finishes its last write after a kill
    while _io.partial_in_use(out) and time.monotonic() < deadline:
        time.sleep(0.05)
    verify = _verify(partial)
    assert verify.returncode == 0, verify.stderr.decode()
    if kill == "SIGTERM":
        assert proc.returncode == 143
        assert back.status == "interrupted"
        lines = stdout.decode().splitlines()
        assert lines[-1] == (
            f"recording: {partial} (the run was cut short: {out} kept as it was; "
            f"view offline: {RERUN} {partial})"
        )
        assert b"terminated by SIGTERM" in (tmp_path / "s.json").read_bytes()
    else:
        assert proc.returncode == -signal.SIGKILL
    # The next run replaces the stale partial file and publishes a whole recording.
    again = exo_ctrl(["simulate", "--duration", "0.05", "--out", str(out)], tmp_path)
    assert again.returncode == 0, again.stderr
    assert read_recording(out).n_ticks == 50 and not partial.exists()


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))


def test_estimate_out_is_written_whole_or_not_at_all(tmp_path: Path) -> None:
    log = csv_log(tmp_path, n=2000)
    est = tmp_path / "est.rrd"
    ok = exo_ctrl(["estimate", str(log), "--out", str(est)], tmp_path)  # kernels compiled, cached
    assert ok.returncode == 0, ok.stderr
    assert _verify(est).returncode == 0
    est.write_bytes(OLD)
    argv = [str(EXO_CTRL), "estimate", str(log), "--out", str(est)]
    full = subprocess.run(
        argv, cwd=tmp_path, capture_output=True, text=True, preexec_fn=_limit_file_size
    )
    assert full.returncode == 1, full.stderr
    assert full.stderr == f"exo-ctrl estimate: error: cannot write {est}: File too large\n"
    assert est.read_bytes() == OLD
    assert sorted(p.name for p in tmp_path.iterdir()) == ["est.rrd", "log.csv"]
    # Sibling: a device that is full (written directly, never renamed over).
    dev = exo_ctrl(["estimate", str(log), "--out", "/dev/full"], tmp_path)
    assert (dev.returncode, dev.stderr) == (
        1,
        "exo-ctrl estimate: error: cannot write /dev/full: No space left on device\n",
    )
    assert Path("/dev/full").is_char_device()
