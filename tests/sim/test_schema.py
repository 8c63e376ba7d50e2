"""One declared log schema: the tick writes every signal, and a new one needs one entry.

The throwaway signal is appended to the schema in the test only: it appears
in the run's log and result, in the recording and in read_recording's
result, with its shape, without another file touched.
"""

from __future__ import annotations

import numpy as np

from exo_ctrl.estimation import EstimateErrorStats
from exo_ctrl.record import RerunRecorder, read_recording
from exo_ctrl.sim import schema, simulate
from exo_ctrl.sim.config import SimConfig
from exo_ctrl.sim.setup import build
from exo_ctrl.sim.summary import RunStats
from exo_ctrl.sim.tick import Runner


def test_the_tick_writes_every_declared_signal() -> None:
    """Log rows start as NaN; after ticks and the plan fill every field of every row is set.

    The estimate's per-tick errors are the run's statistics' (schema.FROM_STATISTICS): the
    chunk's error statistics fill them when it is handed over, as simulate() does.
    """
    for controller in ("pd", "qp"):
        setup = build(SimConfig(controller=controller, duration_s=0.05))
        runner = Runner(setup)
        for name in runner.log.dtype.names:
            runner.log[name] = np.nan
        for k in range(runner.chunk):
            runner.tick(k, k)
        runner.fill_plan(0, runner.chunk)
        unset = [n for n in runner.log.dtype.names if not np.all(np.isfinite(runner.log[n]))]
        assert set(unset) == set(schema.FROM_STATISTICS), (controller, unset)
        RunStats(EstimateErrorStats(setup.exo, setup.config.dt)).update(runner.buf)
        unset = [n for n in runner.log.dtype.names if not np.all(np.isfinite(runner.log[n]))]
        assert not unset, (controller, unset)
        assert set(runner.log.dtype.names) == {s.name for s in schema.SIGNALS}


def test_a_new_signal_is_one_schema_entry(tmp_path, monkeypatch) -> None:
    extra = schema.Signal("throwaway_test_signal", (3,), "m", "a signal of this test only")
    monkeypatch.setattr(schema, "SIGNALS", [*schema.SIGNALS, extra])
    path = tmp_path / "run.rrd"
    config = SimConfig(duration_s=0.05)
    result = simulate(config, observers=[RerunRecorder(path)])
    assert result.signals[extra.name].shape == (config.n_ticks, 3)
    back = read_recording(path)
    assert back.signals[extra.name].shape == (config.n_ticks, 3)
    np.testing.assert_array_equal(back.signals[extra.name], result.signals[extra.name])
    np.testing.assert_array_equal(back.signals["q"], result.signals["q"])
