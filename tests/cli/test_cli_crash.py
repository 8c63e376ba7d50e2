"""A recording survives SIGKILL and a full disk: real ``exo-ctrl simulate`` processes.

SIGKILL: a 600 s run is killed once its file holds a given number of whole
2000-tick chunks (read back while it runs), at once or a little later.  The
file must pass ``rerun rrd verify`` and read back with every tick it held
when the kill was decided, bit for bit equal to the same configuration run
again; the process that writes the file (exo_ctrl/record/write_process.py)
finishes its write and ends.  A kill inside a write cannot cut it: the
writer process completes a request it has received.

Full disk: ``--out /dev/full`` and a file-size limit reached in the second
chunk: exit 1, one line naming the path, the reason and the ticks kept, no
traceback, no hang; the limited file is a whole recording of the first chunk.
"""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil
import pytest

from exo_ctrl.exceptions import RecordingError
from exo_ctrl.record.reader import read_recording_integrity
from exo_ctrl.record.writer import BYTES_PER_TICK_ESTIMATE
from exo_ctrl.sim import SimResult, simulate
from exo_ctrl.sim.loop import STARTING

EXO_CTRL = Path(sys.executable).parent / "exo-ctrl"
RERUN = Path(sys.executable).parent / "rerun"
CHUNK = 2000  # SimConfig's default chunk_ticks, which the command line uses


def _verify(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(RERUN), "rrd", "verify", str(path)], capture_output=True, timeout=60)


def _ticks_on_disk(path: Path) -> int:
    """Ticks every signal of the file being written holds, 0 while it is unreadable or absent.

    A file read mid-write is cut at its last whole message; the ticks read
    before the cut count (waiting for an uncut read can outlast the run: at 30
    times real time the writer appends a chunk every 70 ms, sooner than a
    loaded machine reads the growing file).
    """
    try:
        back, _ = read_recording_integrity(path)
    except RecordingError:
        return 0
    return back.n_ticks


class StopAfter:
    """An observer that interrupts the run once ``ticks`` ticks are simulated."""

    def __init__(self, ticks: int) -> None:
        self.ticks = ticks

    def start(self, result: SimResult) -> None:
        pass

    def chunk(self, result: SimResult, start: int, rows: dict) -> None:
        if start + next(iter(rows.values())).shape[0] >= self.ticks:
            raise KeyboardInterrupt

    def finish(self, result: SimResult) -> None:
        pass


def _command_line(process: psutil.Process) -> str:
    """The process's command line ("" for one that ended: a zombie has none)."""
    try:
        return " ".join(process.cmdline())
    except psutil.Error:
        return ""


@pytest.mark.heavy
@pytest.mark.parametrize(("chunks", "wait_s"), [(1, 0.0), (2, 0.011), (3, 0.037)])
def test_sigkill_leaves_a_recording_of_every_written_chunk(
    tmp_path: Path, chunks: int, wait_s: float
) -> None:
    argv = [str(EXO_CTRL), "simulate", "--duration", "600", "--out", str(tmp_path / "run.rrd")]
    rrd = tmp_path / "run.partial.rrd"  # written beside run.rrd, renamed only when whole
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=tmp_path)
    deadline = time.monotonic() + 90.0
    try:
        while (seen := _ticks_on_disk(rrd)) < chunks * CHUNK:
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline, "the run did not record in time"
            time.sleep(0.005)
        # the file's writer process (beside it, on a cold cache, the compile helper,
        # perhaps ended and not yet reaped)
        children = psutil.Process(proc.pid).children()
        (writer,) = [c for c in children if "write_process.py" in _command_line(c)]
        time.sleep(wait_s)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    writer.wait(timeout=30)  # it ends with its input (psutil.TimeoutExpired otherwise)

    back, integrity = read_recording_integrity(rrd)
    assert integrity.cut_at_byte is None
    verify = _verify(rrd)
    assert verify.returncode == 0, verify.stderr.decode()
    assert seen <= back.n_ticks < 600_000 and back.n_ticks % CHUNK == 0
    assert back.status == "interrupted" and "without an end record" in back.error
    assert not integrity.has_end_record
    # Every tick is the run's own: the same configuration (stored in the file) run again.
    again = simulate(back.config, observers=[StopAfter(back.n_ticks)])
    n = back.n_ticks
    assert np.array_equal(back.t, again.t[:n])
    for name, values in back.signals.items():
        assert np.array_equal(values, again.signals[name][:n], equal_nan=True), name


def _one_line_error(proc: subprocess.CompletedProcess) -> str:
    """The one line of stderr that is not progress (on a loaded machine a start-up
    notice, exo_ctrl.sim.loop.STARTING, and the bar may come first)."""
    text = proc.stderr.decode()
    assert "Traceback" not in text
    notices = {f"simulate: {notice}" for notice in STARTING.values()}
    lines = [ln.rsplit("\r", 1)[-1] for ln in text.splitlines() if ln not in notices]
    lines = [ln for ln in lines if ln and not ln.startswith("simulate [")]  # the bar, ended
    assert len(lines) == 1, lines
    return lines[0]


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_a_full_device_is_exit_1_with_one_line(tmp_path: Path) -> None:
    argv = [str(EXO_CTRL), "simulate", "--duration", "0.3", "--out", "/dev/full"]
    proc = subprocess.run(argv, capture_output=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 1
    assert _one_line_error(proc) == (
        "exo-ctrl simulate: error: cannot write /dev/full: No space left on device; "
        "no tick was recorded"
    )


#: A file size [B] the first chunk fits in and the second does not: one and a half
#: chunks at the recorder's estimate per tick (the parameters and footer fit in the half).
FILE_LIMIT_B = int(1.5 * CHUNK * BYTES_PER_TICK_ESTIMATE)


def _limit_file_size() -> None:
    """In the child: files larger than FILE_LIMIT_B cannot be written (Python ignores SIGXFSZ)."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_LIMIT_B, FILE_LIMIT_B))


def test_a_disk_full_in_the_run_is_exit_1_and_keeps_a_whole_file(tmp_path: Path) -> None:
    """The first chunk (about 3.2 MB with the parameters and footer) fits, the second does not."""
    rrd = tmp_path / "run.rrd"
    argv = [str(EXO_CTRL), "simulate", "--duration", "10", "--out", str(rrd)]
    proc = subprocess.run(
        argv, capture_output=True, timeout=120, cwd=tmp_path, preexec_fn=_limit_file_size
    )
    assert proc.returncode == 1
    assert _one_line_error(proc) == (
        f"exo-ctrl simulate: error: cannot write {rrd}: File too large; "
        f"{tmp_path / 'run.partial.rrd'} holds ticks 0-{CHUNK - 1}, readable"
    )
    assert not rrd.exists()
    rrd = tmp_path / "run.partial.rrd"
    verify = _verify(rrd)
    assert verify.returncode == 0, verify.stderr.decode()
    back, integrity = read_recording_integrity(rrd)
    assert back.n_ticks == CHUNK and integrity.cut_at_byte is None
