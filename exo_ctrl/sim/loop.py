"""The closed loop: run a configuration's ticks, chunk by chunk, into a result.

The loop writes its signals into chunk buffers of ``chunk_ticks`` rows
(:class:`~exo_ctrl.sim.tick.Runner`).  Each full chunk is handed to the
observers (the recorder) and, unless ``keep_history`` is off, copied into
the result; so a long run that is only recorded holds one chunk in memory.
A run that diverges or is interrupted (Ctrl-C) ends with the ticks done so
far, its status and its error: nothing is lost.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from .._progress import Progress
from ..estimation import EstimateErrorStats
from ..exceptions import SimulationDiverged, Terminated
from ..model import JOINT_NAMES
from .config import SimConfig
from .gait_score import gait_score_stats
from .interaction import interaction_stats
from .load_stats import load_stats
from .result import SimObserver, SimResult
from .run_models import components_from_s
from .schema import signal_shapes
from .setup import Setup, build
from .summary import RunStats, contact_stats, drive_limits
from .tick import UNTIMED_TICKS, Runner
from .warmup import Warmup

__all__ = ["STARTING", "end_result", "new_result", "simulate"]

#: The progress line of a start-up over a second, by whether the kernels are
#: known compiled for these features (:attr:`Warmup.warm <.warmup.Warmup.warm>`):
#: loading them can take a second on a loaded machine too.
STARTING = {
    False: "compiling kernels, first run only (about 10-30 s; later runs load them) ...",
    True: "loading the compiled kernels ...",
}


def simulate(
    config: SimConfig,
    observers: Sequence[SimObserver] = (),
    progress: bool = False,
    keep_history: bool = True,
    warmup: bool = False,
) -> SimResult:
    """Run the closed loop.

    Args:
        config: the run.
        observers: watchers called per chunk (see :class:`SimObserver`).
        progress: draw a progress bar on stderr (for runs over ~2 s of wall time).
        keep_history: keep every signal in the result (off: only the
            statistics and the chunk being written are held, for long
            recorded runs; ``result.t`` is then empty).
        warmup: on the first run of these features after an install, compile
            the tick's kernels in two processes (:mod:`exo_ctrl.sim.warmup`;
            the CLI's choice; results are the same either way).  Once a run of
            these features has completed, the tick is fused where the
            configuration allows (:mod:`exo_ctrl.sim.fused`; the same, bit for bit).

    Returns:
        The result; ``status`` says whether it completed.  A divergence or
        Ctrl-C ends the run early with the ticks done so far.  Any other
        error (an observer's, say) is recorded as status ``"error"``, every
        observer still gets :meth:`SimObserver.finish`, and then it is raised.

    """
    if keep_history:
        config.check_history()  # before anything is built
    helper = Warmup(config, enabled=warmup)
    result = None
    try:
        # The first run of these features goes stage by stage: composing the fused tick's
        # calls (sim/fused.py) compiles for 1-3 s more; its helper compiles them last.
        fuse = helper.warm
        result = _run(config, observers, progress, keep_history, STARTING[helper.warm], fuse)
    finally:
        helper.finish(result is not None and result.status == "completed")
    return result


def _run(
    config: SimConfig,
    observers: Sequence[SimObserver],
    progress: bool,
    keep_history: bool,
    starting: str,
    fuse: bool = True,
) -> SimResult:
    """:func:`simulate`'s run, the helper left out; ``starting``: the start-up's notice.

    ``fuse``: the tick fused where the configuration allows (:mod:`exo_ctrl.sim.fused`).
    """
    setup = build(config)
    runner = Runner(setup, fuse=fuse)
    n = config.n_ticks
    hist_n = n if keep_history else 0
    result = new_result(setup, hist_n)
    history = result.signals
    for obs in observers:
        obs.start(result)
    bar = Progress(n, "simulate", enabled=progress)
    bar.notice_after(1.0, starting)
    chunk = runner.chunk
    chunk_start = 0
    row = 0
    k = 0

    def flush(start: int, rows: int) -> None:
        runner.fill_plan(start, rows)
        view = {name: arr[:rows] for name, arr in runner.buf.items()}
        result.stats.update(view)
        if keep_history:
            for name, arr in view.items():
                history[name][start : start + rows] = arr
        first: Exception | None = None
        for obs in observers:  # every observer gets the chunk, whoever fails
            try:
                obs.chunk(result, start, view)
            except Exception as exc:
                first = first or exc
        if first is not None:
            raise first

    def fail(status: str, t: float, message: str) -> None:
        if result.status == "completed":
            result.status = status
            result.error = message
            result.events.append({"t": t, "kind": status, "message": message})

    error: Exception | None = None
    result.stats.preload(runner.buf)
    start_wall = time.perf_counter()
    try:
        for k in range(n):
            runner.tick(k, row)
            if k == UNTIMED_TICKS - 1:
                start_wall = time.perf_counter()
                bar.restart(UNTIMED_TICKS)
            row += 1
            if row == chunk:
                start, row = chunk_start, 0
                chunk_start += chunk
                flush(start, chunk)
                bar.update(chunk_start)
        k = n
    except SimulationDiverged as exc:
        fail("diverged", exc.time, str(exc))
    except KeyboardInterrupt as exc:
        who = f"terminated by {exc.signal_name}" if isinstance(exc, Terminated) else "interrupted"
        by = "" if isinstance(exc, Terminated) else " by the user"
        fail("interrupted", k * config.dt, f"{who}{by} at t = {k * config.dt:.4f} s")
    except Exception as exc:  # recorded, the observers finish, then it propagates
        fail("error", k * config.dt, f"{type(exc).__name__}: {exc}")
        error = exc
    result.wall_time_s = time.perf_counter() - start_wall
    done = chunk_start + row
    result.timed_ticks = max(done - UNTIMED_TICKS, 0)
    if row:
        try:
            flush(chunk_start, row)
        except Exception as exc:
            fail("error", done * config.dt, f"{type(exc).__name__}: {exc}")
            error = error or exc
    bar.close(done)
    end_result(result, runner)
    if keep_history and done < n:
        result.t = result.t[:done]
        result.signals = {name: arr[:done] for name, arr in history.items()}
    for obs in observers:
        try:
            obs.finish(result)
        except Exception as exc:
            error = error or exc
    if error is not None:
        raise error
    return result


def new_result(setup: Setup, hist_n: int) -> SimResult:
    """A run's result before its first tick: its statistics ready, ``hist_n`` rows of history.

    Args:
        setup: the run's pieces (:func:`~exo_ctrl.sim.setup.build`).
        hist_n: rows of history kept (the run's ticks, or 0: none).

    """
    config = setup.config
    history = {name: np.zeros((hist_n, *shape)) for name, shape in signal_shapes().items()}
    result = SimResult(
        config=config,
        t=np.arange(hist_n) * config.dt,
        signals=history,
        belt_speed_mps=config.gait.belt_speed,
        exo_source=setup.exo.source,
        patient_source=setup.patient.source,
        warnings=list(setup.warnings),
        notes=list(setup.notes),
        stats=RunStats(
            EstimateErrorStats(setup.exo, config.dt, components_from_s=components_from_s(config)),
            contact_stats(config),
            interaction_stats(config, setup.controller, setup.plan, setup.exo),
            drive_limits(config, setup.exo.effort_limit),
        ),
    )
    result.stats.gait = gait_score_stats(config)
    result.stats.load = load_stats(config, setup.exo)
    if config.mode == "aan":  # the support level per cycle, for the interaction block
        result.stats.support = setup.controller.support_history
    return result


def end_result(result: SimResult, runner: Runner) -> None:
    """Fill a result's end from its runner: QP fallbacks, energy, events (in time order), safety."""
    setup = runner.setup
    result.qp_failures = int(runner._records[3][0]["failures"])
    controller_record = runner._records[3]
    if "margin_peak" in (controller_record.dtype.names or ()):
        result.cuff_bound_margin_N = controller_record["margin_peak"][0].copy()
    if setup.plant.motors is not None:
        result.energy = setup.plant.motors.energy(JOINT_NAMES)
    if runner.faults is not None:
        result.events.extend(runner.faults.events)
    result.events.extend(getattr(setup.controller, "events", ()))  # a session's switches
    if runner.supervisor is not None:
        result.events.extend(runner.supervisor.events)
        result.safety_state = runner.supervisor.state
    result.events.sort(key=lambda e: e["t"])  # in time order, the run's end last
