"""Shared pieces of the recording tests: a recorded run, its reference, and file readers.

Exactness: rerun stores scalars as float64, so every signal must come back
bit for bit (``np.array_equal``), and ``t`` too (rebuilt as k Δt).  3-D
points are float32 in rerun, so they are compared to Pinocchio within 1e-6 m.
The raw rerun reader (``rerun.chunk.RrdReader``) is used to look at entities
directly, independently of :func:`read_recording`.

The helpers are fixtures (``entity_columns``, ``ticks_by_entity``, ``assert_same_run``,
``verify``, ``raise_observer``) as test modules cannot import each other.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from exo_ctrl.record import RerunRecorder
from exo_ctrl.record.reader import _read_chunks
from exo_ctrl.sim import SimConfig, SimResult, simulate
from exo_ctrl.sim.schema import signal_shapes

#: A short run; 70-tick chunks so the last chunk (300 = 4 x 70 + 20) is partial.
SHORT = SimConfig(duration_s=0.3, chunk_ticks=70)


def _rerun_cli() -> list[str]:
    exe = Path(sys.executable).with_name("rerun")
    if exe.is_file():
        return [str(exe)]
    found = shutil.which("rerun")
    return [found] if found else [sys.executable, "-m", "rerun"]


def _verify(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*_rerun_cli(), "rrd", "verify", str(path)], capture_output=True, text=True, timeout=60
    )


def _entity_columns(path: Path, entity: str, column: str) -> tuple[np.ndarray, list]:
    """(ticks, values) of one component of one entity, straight from the file, by tick.

    Static entities have no ticks: an empty tick array and the values as stored.
    """
    ticks, values = [], []
    # As read_recording reads: a crashed writer's last message may be cut short.
    chunks, _ = _read_chunks(path)
    for chunk in chunks:
        if chunk.entity_path != "/" + entity:
            continue
        batch = chunk.to_record_batch()
        if column not in batch.schema.names:
            continue
        if "tick" in batch.schema.names:
            ticks += batch.column("tick").to_pylist()
        values += batch.column(column).to_pylist()
    if not ticks:
        return np.zeros(0, dtype=np.int64), values
    order = np.argsort(ticks, kind="stable")
    return np.asarray(ticks)[order], [values[i] for i in order]


def _ticks_by_entity(path: Path) -> dict[str, list[int]]:
    """Entity path → the ticks stored for it, straight from the file (static entities absent)."""
    ticks: dict[str, list[int]] = {}
    for chunk in RrdReader(str(path)).stream().to_chunks():
        batch = chunk.to_record_batch()
        if "tick" in batch.schema.names:
            ticks.setdefault(chunk.entity_path, []).extend(batch.column("tick").to_pylist())
    return ticks


def _assert_same_run(back: SimResult, ref: SimResult, n: int | None = None) -> None:
    """Every signal and t exactly equal (the first n ticks of ref when n is given)."""
    n = ref.t.shape[0] if n is None else n
    assert back.t.shape == (n,)
    assert np.array_equal(back.t, ref.t[:n])
    shapes = signal_shapes()
    assert set(back.signals) == set(shapes)
    for name, shape in shapes.items():
        assert back.signals[name].shape == (n, *shape), name
        assert back.signals[name].dtype == np.float64, name
        assert np.array_equal(back.signals[name], ref.signals[name][:n]), name


class Raise:
    """An observer that raises ``exc`` (once, or every time) from chunk() at tick >= at."""

    def __init__(self, exc: BaseException, at: int, once: bool = True) -> None:
        self.exc, self.at, self.once, self.raised = exc, at, once, 0

    def start(self, result: SimResult) -> None:
        pass

    def chunk(self, result: SimResult, start: int, rows: dict) -> None:
        if start >= self.at and not (self.once and self.raised):
            self.raised += 1
            raise self.exc

    def finish(self, result: SimResult) -> None:
        pass


@pytest.fixture(scope="session")
def short_config() -> SimConfig:
    """The short run's configuration (300 ticks in 70-tick chunks)."""
    return SHORT


@pytest.fixture(scope="session")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[SimResult, Path]:
    """The short run, recorded: its result and its file."""
    path = tmp_path_factory.mktemp("rec") / "short.rrd"
    result = simulate(SHORT, observers=[RerunRecorder(path)])
    assert result.status == "completed"
    return result, path


@pytest.fixture(scope="session")
def reference() -> SimResult:
    """The short run without observers (the loop is deterministic)."""
    return simulate(SHORT)


@pytest.fixture(scope="session")
def entity_columns() -> Callable[[Path, str, str], tuple[np.ndarray, list]]:
    """``entity_columns(path, entity, column)``: (ticks, values) straight from the file."""
    return _entity_columns


@pytest.fixture(scope="session")
def ticks_by_entity() -> Callable[[Path], dict[str, list[int]]]:
    """``ticks_by_entity(path)``: entity path → its stored ticks, straight from the file."""
    return _ticks_by_entity


@pytest.fixture(scope="session")
def assert_same_run() -> Callable[..., None]:
    """``assert_same_run(back, ref, n=None)``: every signal and t exactly equal."""
    return _assert_same_run


@pytest.fixture(scope="session")
def verify() -> Callable[[Path], subprocess.CompletedProcess]:
    """``verify(path)``: ``rerun rrd verify`` of the file."""
    return _verify


@pytest.fixture(scope="session")
def raise_observer() -> type[Raise]:
    """The observer class that raises from chunk() (see :class:`Raise`)."""
    return Raise
