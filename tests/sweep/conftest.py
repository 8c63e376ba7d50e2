"""Helpers of the sweep tests: short specs, serial sweeps, table comparison, run counting."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import exo_ctrl.sweep.run as run_module
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sweep import SweepSpec, run_sweep

DURATION = 0.4  # simulated time per run [s]: short, but past the start-up transient


def _spec(*params: str, **kw) -> SweepSpec:
    kw.setdefault("duration_s", DURATION)
    return SweepSpec.parse(list(params), **kw)


def _serial(spec: SweepSpec, out: Path, **kw):
    kw.setdefault("plots", False)
    kw.setdefault("report", False)
    return run_sweep(spec, out, workers=1, progress=False, **kw)


def _same(a, b) -> bool:
    """Equal values, NaN equal to NaN."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    return a == b


def _assert_tables_equal(a, b, skip=("wall_time_s",)) -> None:
    assert a.column_names == b.column_names
    assert len(a) == len(b)
    for name in a.column_names:
        if name in skip:
            continue
        va, vb = a.column(name).to_pylist(), b.column(name).to_pylist()
        bad = [i for i, (x, y) in enumerate(zip(va, vb, strict=True)) if not _same(x, y)]
        assert not bad, f"column {name} differs in rows {bad}: {va} vs {vb}"


@pytest.fixture
def duration() -> float:
    """Simulated time per run of :func:`make_spec`'s specs [s]."""
    return DURATION


@pytest.fixture
def make_spec() -> Callable[..., SweepSpec]:
    """``SweepSpec.parse`` of ``--param`` texts, runs of :data:`DURATION` by default."""
    return _spec


@pytest.fixture
def serial() -> Callable[..., Any]:
    """Run a sweep in this process, without progress bar, plots or report (by default)."""
    return _serial


@pytest.fixture
def assert_tables_equal() -> Callable[..., None]:
    """Assert two sweep tables are equal column by column (NaN equal to NaN)."""
    return _assert_tables_equal


@pytest.fixture
def count_runs(monkeypatch) -> list[SimConfig]:
    """Count the simulations run in this process (serial sweeps)."""
    calls = []

    def counting(config, *args, **kwargs):
        calls.append(config)
        return simulate(config, *args, **kwargs)

    monkeypatch.setattr(run_module, "simulate", counting)
    return calls
