"""The sweep's worker processes die with the sweep, however it ends.

A pool worker waits on the pool's queues and holds both ends of their pipes
itself, so nothing ended it when the parent was killed: each stayed alive,
about 290 MB, until killed by hand, and so did multiprocessing's resource
tracker, whose pipe they keep open.  Every process the sweep started must be
gone a few seconds after it is killed (SIGKILL: no clean-up code runs).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

EXO_CTRL = Path(sys.executable).with_name("exo-ctrl")


def _alive(proc: psutil.Process) -> bool:
    """Running and not a zombie (a dead child its new parent has not reaped yet)."""
    try:
        return proc.is_running() and proc.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def _workers(parent: psutil.Process) -> list[psutil.Process]:
    """The spawned pool workers among ``parent``'s children."""
    out = []
    for child in parent.children(recursive=True):
        try:
            if any("spawn_main" in part for part in child.cmdline()):
                out.append(child)
        except psutil.NoSuchProcess:
            pass
    return out


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process tree checks on Linux")
def test_workers_die_when_the_sweep_is_killed(tmp_path: Path) -> None:
    out = tmp_path / "k.parquet"
    # 50 gait cycles a run: the first point (made in this process before the pool's
    # workers start) at the default 1.2 s period, 61 s of simulated time, about 1 s
    # of wall time; the workers' at a 6 s period, 306 s, about 5 s: the sweep is
    # busy when it is killed.
    argv = [str(EXO_CTRL), "sweep", "--param", "period=1.2,6,6.1,6.2", "--cycles", "50"]
    argv += ["--workers", "2", "--no-plots", "--out", str(out)]
    sweep = subprocess.Popen(
        argv, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    parent = psutil.Process(sweep.pid)
    workers: list[psutil.Process] = []
    others: list[psutil.Process] = []
    try:
        deadline = time.monotonic() + 120.0
        while len(workers) < 2 and time.monotonic() < deadline and sweep.poll() is None:
            time.sleep(0.2)
            workers = _workers(parent)
        assert len(workers) == 2, "the pool did not start"
        others = [c for c in parent.children(recursive=True) if c not in workers]
        time.sleep(1.0)  # the workers are past their initializer, in a run
        assert sweep.poll() is None, "the sweep ended before it was killed"
        os.kill(sweep.pid, signal.SIGKILL)
        sweep.wait(timeout=10)
        deadline = time.monotonic() + 5.0
        while any(_alive(p) for p in workers + others) and time.monotonic() < deadline:
            time.sleep(0.1)
        survivors = [p.pid for p in workers + others if _alive(p)]
        assert survivors == [], f"processes alive 5 s after the sweep was killed: {survivors}"
    finally:  # whatever happened, leave none of this test's processes behind
        if sweep.poll() is None:
            sweep.kill()
            sweep.wait()
        for proc in workers + others:
            if _alive(proc):
                proc.kill()
