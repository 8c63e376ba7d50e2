"""Trial of the recorder on rerun's own file sink, against the recorder as it is (issue 32).

The recorder writes the ``.rrd`` file itself, with a footer after every
chunk (exo_ctrl/record/rrd_file.py, rrd_footer.py, write_process.py).  This
script swaps that for rerun's ``FileSink`` on the same partial file (claimed
and renamed as now), flushed where the recorder writes a chunk, and measures
what docs/performance.md reports ("The recorder's file"):

    kill    N runs of ``.venv/bin/exo-ctrl simulate --duration 600`` killed with SIGKILL at a
            random moment after 1-3 chunks were flushed: ticks flushed before the
            kill, ticks read back, whether ``.venv/bin/rerun rrd verify`` accepts the file and
            whether ``.venv/bin/rerun rrd optimize`` repairs it (read back equal)
    fault   a file-size limit (RLIMIT_FSIZE) reached by rerun's sink: what flush()
            and disconnect() do
    bench   ``.venv/bin/python tools/bench.py`` with the swapped recorder (compare with it alone)
    run     ``.venv/bin/exo-ctrl ARGS`` with the swapped recorder (what ``kill`` runs)

Usage: .venv/bin/python tools/rrd_sink_trial.py kill --runs 20 [--current]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import bench
import numpy as np
import rerun as rr

from exo_ctrl import _io
from exo_ctrl.cli import main as exo_ctrl_main
from exo_ctrl.cli import simulate as cli_simulate
from exo_ctrl.exceptions import RecordingError
from exo_ctrl.record import writer
from exo_ctrl.record.reader import read_recording_integrity

BIN = Path(sys.executable).parent
CHUNK = 2000  # the command line's chunk_ticks
#: Where the swapped recorder appends "ticks flushed" after each flush (kill reads it).
LOG_ENV = "EXO_CTRL_SINK_TRIAL_LOG"


class SinkFile:
    """Stands in for RrdFile: the partial file claimed (locked) and renamed as now; no writes."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.partial = _io.partial_path(self.path)
        self._fd: int | None = _io.claim_partial(self.path)
        self.written = self.partial

    def reserve(self, size: int) -> None:
        pass

    def wait(self) -> None:
        pass  # rerun's sink has written what flush() waited for

    def close(self, publish: bool = True) -> None:
        if self._fd is not None and publish:
            os.replace(self.partial, self.path)
            self.written = self.path
        self.abandon()

    def abandon(self) -> None:
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)


class SinkRecorder(writer.RerunRecorder):
    """RerunRecorder with rerun's FileSink on the partial file, flushed at each write."""

    def start(self, result) -> None:
        made: dict[str, SinkFile] = {}

        def file_sink(recording: rr.RecordingStream | None = None) -> rr.FileSink:
            return rr.FileSink(str(made["file"].partial))

        def sink_file(path: str | os.PathLike[str]) -> SinkFile:
            made["file"] = SinkFile(path)
            return made["file"]

        saved = writer.rr.binary_stream, writer.RrdFile
        writer.rr.binary_stream, writer.RrdFile = file_sink, sink_file
        try:
            super().start(result)
        finally:
            writer.rr.binary_stream, writer.RrdFile = saved

    def _write(self, wait: bool = True) -> None:
        if self._rec is None:
            return
        self._rec.flush(timeout_sec=writer.FLUSH_TIMEOUT_S)
        log = os.environ.get(LOG_ENV)
        if log:
            with open(log, "a") as handle:
                handle.write(f"{self._next_tick}\n")


def _flushed(log: Path) -> int:
    try:
        return max((int(x) for x in log.read_text().split()), default=0)
    except FileNotFoundError:
        return 0


def _on_disk(partial: Path) -> int:
    """Ticks of the current design's file, 0 while unreadable or cut (mid-write)."""
    try:
        back, integrity = read_recording_integrity(partial)
    except RecordingError:
        return 0
    return back.n_ticks if integrity.cut_at_byte is None else 0


def _verify(path: Path) -> int:
    """``.venv/bin/rerun rrd verify``'s exit code for the file."""
    verify = [str(BIN / "rerun"), "rrd", "verify", str(path)]
    return subprocess.run(verify, capture_output=True).returncode


def kill_once(out: Path, current: bool, rng: random.Random) -> dict:
    """One run killed with SIGKILL after 1-3 flushed chunks and 0-200 ms (a chunk takes ~170 ms)."""
    log, partial = out / "flushed.log", out / "run.partial.rrd"
    args = ["simulate", "--duration", "600", "--out", str(out / "run.rrd")]
    argv = [str(BIN / "exo-ctrl"), *args] if current else [sys.executable, __file__, "run", *args]
    errors = (out / "stderr.txt").open("wb")
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=errors,
                            env=dict(os.environ, **{LOG_ENV: str(log)}), cwd=out)  # fmt: skip
    chunks, wait_s = rng.randint(1, 3), rng.uniform(0.0, 0.2)
    deadline = time.monotonic() + 120.0
    while (_on_disk(partial) if current else _flushed(log)) < chunks * CHUNK:
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            tail = (out / "stderr.txt").read_text()[-500:]
            raise SystemExit(f"the run ended or did not record in time: {tail}")
        time.sleep(0.005)
    time.sleep(wait_s)
    before = _on_disk(partial) if current else _flushed(log)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    time.sleep(0.3)  # the current design's writer process completes its request
    back, integrity = read_recording_integrity(partial)
    fixed = out / "optimized.rrd"
    optimize = [str(BIN / "rerun"), "rrd", "optimize", str(partial), "-o", str(fixed)]
    repaired = subprocess.run(optimize, capture_output=True).returncode == 0
    again = read_recording_integrity(fixed)[0] if repaired else None
    equal = again is not None and all(
        np.array_equal(again.signals[k], v, equal_nan=True) for k, v in back.signals.items()
    )
    return {
        "flushed_before_kill": before,
        "read_back": back.n_ticks,
        "lost": max(0, before - back.n_ticks),
        "cut_at_byte": integrity.cut_at_byte,
        "bytes": partial.stat().st_size,
        "verify": _verify(partial),
        "optimized_verify": _verify(fixed) if repaired else None,
        "optimized_bytes": fixed.stat().st_size if repaired else None,
        "optimized_equal": equal,
    }


def fault() -> None:
    """rerun's FileSink past a 200 kB file-size limit: flush, then sinks swapped, disconnect."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))
    with tempfile.TemporaryDirectory() as tmp:
        rec = rr.RecordingStream("trial")
        rec.set_sinks(rr.FileSink(str(Path(tmp) / "f.rrd")))
        n = 20_000
        ticks = rr.TimeColumn("tick", sequence=np.arange(n))
        rec.send_columns("s", indexes=[ticks], columns=rr.Scalars.columns(scalars=np.ones(n)))
        t0 = time.monotonic()
        try:
            rec.flush(timeout_sec=writer.FLUSH_TIMEOUT_S)
            print("flush returned", flush=True)
        except RuntimeError as exc:
            print(f"flush raised after {time.monotonic() - t0:.1f} s: {exc}", flush=True)
        rec.set_sinks(rr.binary_stream(recording=rec))  # without this, disconnect() may hang
        rec.disconnect()
        print("disconnect returned", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=("kill", "fault", "bench", "run"))
    parser.add_argument("--runs", type=int, default=20, help="kill: runs (default 20)")
    parser.add_argument("--current", action="store_true", help="kill: the recorder as it is")
    parser.add_argument("--seed", type=int, default=0, help="kill: the kill moments' seed")
    args, rest = parser.parse_known_args()
    if args.what == "run":
        cli_simulate.RerunRecorder = SinkRecorder
        return exo_ctrl_main(rest)
    if args.what == "bench":
        bench.RerunRecorder = SinkRecorder
        sys.argv = [sys.argv[0], *rest]
        return bench.main()
    if args.what == "fault":
        fault()
        return 0
    rng = random.Random(args.seed)
    for _ in range(args.runs):
        with tempfile.TemporaryDirectory() as tmp:
            print(json.dumps(kill_once(Path(tmp), args.current, rng)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
