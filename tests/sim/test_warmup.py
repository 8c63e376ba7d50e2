"""The first run's compile helper (exo_ctrl/sim/warmup.py): safe, equal results, dies with parent.

The helper is safe only because every kernel is called with one signature per
run (exo_ctrl/_jit.py): then the two processes can only ever save the same
entry of a kernel's cache index.  The cold runs here compile into a fresh,
empty cache directory with the helper on and then read every index file.
"""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from exo_ctrl import SimConfig
from exo_ctrl.plan import GaitParams, online
from exo_ctrl.plant import ContactParams
from exo_ctrl.safety.cuff_load import CuffLoadMonitor
from exo_ctrl.sim import Runner, build
from exo_ctrl.sim.warmup import ENV, Warmup, core_free, feature_key

EXO_CTRL = Path(sys.executable).parent / "exo-ctrl"


def _index_entries(cache: Path) -> dict[str, int]:
    """Each numba index file under ``cache``: its number of saved signatures."""
    entries = {}
    for index in cache.rglob("*.nbi"):
        with index.open("rb") as f:
            pickle.load(f)  # numba's version
            _, overloads = pickle.loads(f.read())
        entries[index.name] = len(overloads)
    return entries


def _cold_run(cache: Path, summary: Path, *options: str, helper: bool = True) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), **{ENV: "1" if helper else "0"})
    argv = [str(EXO_CTRL), "simulate", "--duration", "0.3", "--no-record", *options]
    run = subprocess.run(
        [*argv, "--summary", str(summary)], env=env, capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, run.stderr
    return json.loads(summary.read_text())


@pytest.mark.heavy
@pytest.mark.parametrize(
    "options",
    [
        (),  # PD, the Kalman filter, the supervisor, split cuffs against the device's isotropic
        # the belt, the patient's feet, path control with the active patient (path control
        # needs the ramp-in and a whole period of the plan: --duration 2.4)
        (
            *("--contact", "on", "--sync", "off", "--patient-feet", "on"),
            *("--mode", "path", "--patient-torque", "active", "--duration", "2.4"),
        ),
    ],
    ids=["default", "contact-feet-path"],
)
def test_a_cold_run_with_the_helper_saves_one_signature_per_kernel(tmp_path, options) -> None:
    cache = tmp_path / "cache"
    cache.mkdir()
    cold = _cold_run(cache, tmp_path / "cold.json", *options)
    entries = _index_entries(cache)
    many = {name: n for name, n in entries.items() if n > 1}
    print(f"\n{len(entries)} kernels compiled, {len(many)} with more than one signature")
    assert len(entries) > 30 and not many
    assert list(cache.glob("exo_ctrl-warm-*")), "a completed run marks its features warm"
    # The same run on the filled cache, helper off: the same numbers.
    warm = _cold_run(cache, tmp_path / "warm.json", *options, helper=False)
    for key in ("rms_tracking_error_rad", "peak_drive_torque_Nm", "peak_cuff_force_N"):
        assert cold[key] == warm[key]


def test_the_feature_key_follows_the_types_not_the_values() -> None:
    base = feature_key(SimConfig())
    assert feature_key(SimConfig(duration_s=9.0, gait=GaitParams(period=1.4))) == base
    assert feature_key(SimConfig(controller="ct")) != base
    assert feature_key(SimConfig(contact=ContactParams(enabled=True))) != base


def test_no_helper_when_turned_off_or_marked_or_busy(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr("exo_ctrl.sim.warmup.core_free", lambda: True)
    monkeypatch.setenv(ENV, "0")
    assert Warmup(SimConfig()).process is None
    monkeypatch.setenv(ENV, "1")
    assert Warmup(SimConfig(), enabled=False).process is None
    monkeypatch.setattr("exo_ctrl.sim.warmup.marker_dir", lambda: tmp_path)
    first = Warmup(SimConfig(duration_s=0.01))
    assert first.process is not None
    first.finish(completed=False)  # stopped, not marked
    assert first.process is None and not list(tmp_path.iterdir())
    second = Warmup(SimConfig(duration_s=0.01))
    second.finish(completed=True)
    assert [p.name for p in tmp_path.iterdir()] == [f"exo_ctrl-warm-{feature_key(SimConfig())}"]
    warm = Warmup(SimConfig())
    assert warm.process is None and warm.warm  # marked: warm
    assert not second.warm
    monkeypatch.setattr("exo_ctrl.sim.warmup.core_free", lambda: False)
    monkeypatch.delenv(ENV)
    busy = Warmup(SimConfig(controller="ct"))
    assert busy.process is None and not busy.warm  # not marked, but busy
    busy.finish(completed=True)  # a run without the helper marks its features warm too
    assert Warmup(SimConfig(controller="ct")).warm
    (tmp_path / f"exo_ctrl-warm-{feature_key(SimConfig(controller='ct'))}").unlink()
    monkeypatch.setenv(ENV, "1")  # started whatever the load
    forced = Warmup(SimConfig(controller="ct", duration_s=0.01))
    assert forced.process is not None
    forced.finish(completed=False)
    library = Warmup(SimConfig(controller="qp"), enabled=False)  # simulate()'s default
    assert library.process is None and not library.warm
    library.finish(completed=True)  # a completed library run marks its features warm too
    assert Warmup(SimConfig(controller="qp"), enabled=False).warm


def test_a_core_is_free_below_the_cores_less_a_half(monkeypatch) -> None:
    monkeypatch.setattr("os.sched_getaffinity", lambda pid: {0, 1})
    for load, free in ((0.9, True), (1.49, True), (1.5, False), (3.0, False)):
        monkeypatch.setattr("os.getloadavg", lambda load=load: (load, 0.0, 0.0))
        assert core_free() is free
    monkeypatch.setattr("os.sched_getaffinity", lambda pid: {0})
    monkeypatch.setattr("os.getloadavg", lambda: (0.0, 0.0, 0.0))
    assert core_free() is False  # one core: nothing to share


_PARENT = """
import sys, time
from exo_ctrl import SimConfig
from exo_ctrl.sim.warmup import Warmup
helper = Warmup(SimConfig(duration_s=0.01))
print(helper.process.pid, flush=True)
time.sleep(600)
"""


def test_the_helper_dies_with_its_parent(tmp_path) -> None:
    """A parent killed with SIGKILL takes its helper with it.

    At once (prctl) once the helper has imported the package; killed before
    that, the helper sees its new parent when its imports are done (about a
    second here, longer on a loaded machine) and exits.
    """
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), **{ENV: "1"})
    parent = subprocess.Popen(
        [sys.executable, "-c", _PARENT], env=env, stdout=subprocess.PIPE, text=True
    )
    try:
        pid = int(parent.stdout.readline())
        assert Path(f"/proc/{pid}").exists()
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()
    deadline = time.monotonic() + 30.0
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(pid)


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, dead but not yet reaped by init, is not alive)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def test_the_helpers_build_leaves_the_plans_start_and_the_load_models_to_the_run(
    monkeypatch,
) -> None:
    """The helper's build (start=False) calls neither the plan's start nor the preload.

    Both processes would otherwise compile those kernels at the same moment
    (docs/performance.md, "Start-up and compiling"); the run's own build calls them.
    """

    def refuse(*args):
        raise RuntimeError("called")

    config = SimConfig(contact=ContactParams(enabled=True), duration_s=0.2)
    assert config.synced and config.safety
    monkeypatch.setattr(online, "online_start", refuse)
    monkeypatch.setattr(CuffLoadMonitor, "preload", refuse)
    setup = build(config, start=False)
    runner = Runner(setup, start=False)
    assert runner.cuff_load is not None
    assert not setup.online.record["out"].any()  # row 0 not started
    with pytest.raises(RuntimeError, match="called"):
        build(config)
    monkeypatch.undo()
    setup = build(config)
    assert setup.online.record["out"].any()
    with pytest.raises(RuntimeError, match="called"):
        monkeypatch.setattr(CuffLoadMonitor, "preload", refuse)
        Runner(setup)
