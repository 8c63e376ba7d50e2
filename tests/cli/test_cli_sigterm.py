"""SIGTERM ends a run as Ctrl-C does: exit 143, every tick so far kept, the recording whole.

The recording of a run cut short stays as ``NAME.partial.rrd`` (named in the
output); ``NAME.rrd`` is not replaced.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

from exo_ctrl.record import read_recording


def test_sigterm_keeps_a_whole_recording_up_to_the_signal(tmp_path: Path) -> None:
    rrd, summary = tmp_path / "run.rrd", tmp_path / "s.json"
    exe = Path(sys.executable).parent / "exo-ctrl"
    argv = [str(exe), "simulate", "--duration", "600", "--out", str(rrd), "--summary", str(summary)]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    deadline = time.monotonic() + 60.0
    partial = tmp_path / "run.partial.rrd"
    while not (partial.is_file() and partial.stat().st_size > 1_000_000):  # recording
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.1)
    proc.send_signal(signal.SIGTERM)  # well before the 600 s run ends (≈ 8 s of wall time)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err.decode()
    assert not rrd.exists()
    assert f"recording: {partial} (the run was cut short: {rrd} not written" in out.decode()
    rrd = partial
    back = read_recording(rrd)
    assert back.status == "interrupted" and back.error.startswith("terminated by SIGTERM")
    assert 0 < back.n_ticks < 600_000
    assert any(e["kind"] == "interrupted" for e in back.events)
    assert summary.is_file() and b"terminated by SIGTERM" in summary.read_bytes()
    viewer = Path(sys.executable).parent / "rerun"
    verify = subprocess.run([str(viewer), "rrd", "verify", str(rrd)], capture_output=True)
    assert verify.returncode == 0, verify.stderr.decode()
