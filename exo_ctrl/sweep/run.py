"""Running a sweep: one closed-loop run per point, on an Executor, journalled as it goes.

A sweep runs the closed loop (:func:`exo_ctrl.sim.simulate`) once per point
of a :class:`~exo_ctrl.sweep.spec.SweepSpec` and writes one table of the
inputs and the figures that size the drives and the cuffs (peak and RMS
drive torque, peak power, peak current per joint; peak force per cuff;
tracking error; status).  The runs go to any
:class:`concurrent.futures.Executor`: a local spawn process pool (by
default), this process (one worker), or a Dask cluster
(``Client.get_executor()``).  Finished runs are journalled
(:mod:`~exo_ctrl.sweep.journal`) and not run again by a later sweep at the
same output; the files are listed in :mod:`~exo_ctrl.sweep.outputs`.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import dataclasses
import hashlib
import multiprocessing
import os
import signal
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from .._io import DerivedOutput
from .._lifetime import die_with_parent
from .._progress import Progress
from ..control import controller_name
from ..control.builtin import built_in_name
from ..exceptions import ExoCtrlError, InvalidParameter, SweepError
from ..model import BodyParams, urdf_xml, write_urdf
from ..sim import SimConfig, simulate
from ..sim.belief import PAPER_PATIENT
from .journal import FINISHED_STATUSES, Journal, read_previous
from .outputs import SweepPaths, empty_outputs, flatten
from .parameters import PARAMETERS, default_exo, default_patient
from .report import (
    PLOTS_HINT,
    build_table,
    pyarrow,
    require,
    write_plots,
    write_report,
    write_table,
)
from .spec import SweepSpec, SweepTask

__all__ = [
    "InlineExecutor",
    "SweepInterrupted",
    "config_for",
    "local_pool",
    "run_point",
    "run_sweep",
    "stop_pool",
]

_TABLE_EVERY_S = 30.0  # rewrite the table at least this often during a sweep [s]


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep; the finished runs are kept and the table written.

    Attributes:
        table: the table of the finished runs (pyarrow.Table).
        done: runs finished in this call.
        remaining: runs of the sweep still to do (a rerun resumes them).
        signal_name: ``"SIGTERM"`` when a signal ended it (:class:`Terminated`),
            "" for Ctrl-C.

    """

    def __init__(self, table: Any, done: int, remaining: int, signal_name: str = "") -> None:
        super().__init__(f"sweep interrupted: {done} runs finished, {remaining} to do")
        self.table = table
        self.done = done
        self.remaining = remaining
        self.signal_name = signal_name


def _body_urdf(kind: str, body: dict[str, float], cache_dir: str) -> str | None:
    """The URDF of a generated ``kind`` (patient or exo) with ``body``'s values (None: default).

    A link whose length changes keeps its cuff at its fraction of the link
    while the cuff is at its default position.  Written once into ``cache_dir``, named by
    its content's hash.
    """
    default = default_patient() if kind == "patient" else default_exo()
    if all(getattr(default, k) == v for k, v in body.items()):
        return None
    changes = dict(body)
    for seg in ("thigh", "shank"):  # a cuff left at its default keeps its fraction of its link
        length = changes.get(f"{seg}_length")
        cuff = changes.get(f"{seg}_cuff", getattr(default, f"{seg}_cuff"))
        if length is not None and cuff == getattr(default, f"{seg}_cuff"):
            ref = getattr(default, f"{seg}_length")
            changes[f"{seg}_cuff"] = getattr(default, f"{seg}_cuff") / ref * length
    make = BodyParams.patient_default if kind == "patient" else BodyParams.exo_default
    params = make(**changes)
    digest = hashlib.sha256(urdf_xml(params).encode("utf-8")).hexdigest()[:16]
    for folder in (Path(cache_dir), Path(tempfile.gettempdir()) / "exo_ctrl_sweep"):
        path = folder / f"{kind}-{digest}.urdf"
        if path.is_file():
            return str(path)
        with contextlib.suppress(OSError):  # e.g. a remote worker without the folder
            folder.mkdir(parents=True, exist_ok=True)
            return str(write_urdf(params, path))
    raise SweepError(f"cannot write the {kind} URDF into {cache_dir}")


def config_for(base: SimConfig, values: dict[str, Any], cache_dir: str) -> SimConfig:
    """The :class:`SimConfig` of a run: ``base`` with ``values`` (:meth:`SweepSpec.resolve`).

    Generates the patient's (the exoskeleton's) URDF into ``cache_dir`` when
    patient (exo) values differ from the default's.  A base holding a
    :class:`~exo_ctrl.control.PD` or ``CT`` object is its name with the
    object's gains (so that a sweep of the gains, or of the controller,
    starts from them).

    Raises:
        ExoCtrlError: a value or combination the library rejects.

    """
    name = built_in_name(base.controller)
    if name is not None:
        base = dataclasses.replace(base, controller=name, gains=base.controller.gains)
    groups: dict[str, dict[str, Any]] = {
        "gait": {},
        "patient": {},
        "exo": {},
        "motor": {},
        "cuffs": {},
        "gains": {},
    }
    for name, value in values.items():
        info = PARAMETERS.get(name)
        if info is not None:
            groups[info.target][info.attribute] = value
    patient, belief = base.patient, base.belief
    if base.patient is None and groups["patient"]:
        patient = _body_urdf("patient", groups["patient"], cache_dir)
        if patient is not None and belief.patient == "nominal":
            # The swept patients vary the paper's patient's segments: the
            # clinic's stature and body mass stay the paper's unless given.
            belief = dataclasses.replace(
                belief,
                patient_height_m=belief.patient_height_m or PAPER_PATIENT["height_m"],
                patient_mass_kg=belief.patient_mass_kg or PAPER_PATIENT["mass_kg"],
            )
    exo = base.exo
    if base.exo is None and groups["exo"]:
        exo = _body_urdf("exo", groups["exo"], cache_dir)
    return dataclasses.replace(
        base,
        exo=exo,
        belief=belief,
        gait=dataclasses.replace(base.gait, **groups["gait"]),
        patient=patient,
        controller=_controller(base, values.get("controller")),
        motor=dataclasses.replace(base.motor, **groups["motor"]),
        cuffs=dataclasses.replace(base.cuffs, **groups["cuffs"]),
        gains=dataclasses.replace(base.gains, **groups["gains"]),
        duration_s=values.get("duration_s", base.duration_s),
    )


def _controller(base: SimConfig, name: str | None) -> Any:
    """The run's controller: the base's own (a user's object too) when ``name`` is its name."""
    if name is None or name == controller_name(base.controller):
        return base.controller
    return name


def run_point(
    base: SimConfig, values: dict[str, Any], cache_dir: str, label: str = ""
) -> dict[str, Any]:
    """Run one point; never raises for a bad run (runs in a worker).

    Args:
        base: the sweep's base run.
        values: the point's resolved values (:meth:`SweepSpec.resolve`).
        cache_dir: folder for generated patient URDFs.
        label: the point in words, appended to an error message.

    Returns:
        The output columns (:data:`~exo_ctrl.sweep.outputs.OUTPUT_COLUMNS`).  ``status`` is the
        simulation's (``completed``, ``diverged``, ``interrupted``),
        ``failed`` when the library rejects the configuration
        (:class:`~exo_ctrl.exceptions.ExoCtrlError`, e.g. an unreachable
        foot path), or ``error`` for any other exception; ``error`` then
        holds ``<exception type>: <message> [<point>]``.  ``wall_time_s`` is
        the whole run's wall-clock time [s], model building included.

    """
    start = time.perf_counter()
    out = empty_outputs()
    try:
        result = simulate(config_for(base, values, cache_dir), keep_history=False)
        out.update(flatten(result.summary()))
        out["status"], out["error"] = result.status, result.error
    except ExoCtrlError as exc:
        out["status"], out["error"] = "failed", f"{type(exc).__name__}: {exc}"
    except Exception as exc:
        out["status"], out["error"] = "error", f"{type(exc).__name__}: {exc}"
    if out["error"] and label:
        out["error"] += f" [{label}]"
    out["wall_time_s"] = time.perf_counter() - start
    return out


def _init_worker(parent_pid: int) -> None:
    """Pool worker initializer: Ctrl-C is the parent's to handle; die with the parent.

    A worker holds both ends of the pool's pipes itself, so the parent's death
    (SIGKILL) never ends it without :func:`~exo_ctrl._lifetime.die_with_parent`.

    Args:
        parent_pid: the process id of the sweep that owns the pool.

    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent_pid)


class InlineExecutor(cf.Executor):
    """Runs each submitted call at once in this process (``workers = 1``)."""

    def submit(self, fn, /, *args, **kwargs):
        """Run ``fn(*args, **kwargs)`` now; its result or exception in a done future."""
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as exc:
            future.set_exception(exc)
        return future


def local_pool(workers: int) -> cf.ProcessPoolExecutor:
    """A local process pool of ``workers`` spawned interpreters."""
    # spawn: a clean interpreter per worker (fork after pyarrow/rerun threads
    # exist can deadlock); workers ignore Ctrl-C, the parent handles it, and
    # die with the parent.
    return cf.ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_init_worker,
        initargs=(os.getpid(),),
    )


def stop_pool(pool: cf.Executor, now: bool) -> None:
    """Shut an owned pool down; ``now``: cancel queued runs and kill running ones."""
    if not now:
        pool.shutdown(wait=True)
        return
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        with contextlib.suppress(Exception):
            proc.terminate()
    for proc in procs:
        with contextlib.suppress(Exception):
            proc.join(timeout=5)


def _outputs_of(future: cf.Future) -> dict[str, Any]:
    """A finished run's outputs; ``error`` outputs when the worker itself failed."""
    try:
        return future.result()
    except Exception as exc:  # the worker itself was lost (e.g. killed)
        out = empty_outputs()
        out["error"] = f"{type(exc).__name__}: {exc}"
        return out


def run_sweep(
    spec: SweepSpec,
    out_path: str | os.PathLike[str],
    executor: cf.Executor | None = None,
    workers: int | None = None,
    progress: bool = True,
    *,
    plots: bool = True,
    report: bool = True,
) -> Any:
    """Run a sweep, resuming from the files of an earlier one at ``out_path``.

    Args:
        spec: what to sweep.
        out_path: the output table, ``DIR/NAME.parquet``; the CSV, journal,
            report, plots and URDF cache go beside it
            (:class:`~exo_ctrl.sweep.outputs.SweepPaths`).
        executor: where to run (any :class:`concurrent.futures.Executor`,
            e.g. a Dask ``Client.get_executor()``); not shut down here.
            None: a local process pool of ``workers`` (one worker: in this
            process); its first run is made in this process before the
            workers start theirs, so that they load its compiled kernels
            rather than compile them at the same time.
        workers: pool size (default ``os.cpu_count()``); with an
            ``executor``, the number of its workers (at most 2 × workers runs
            are queued at a time; None: all at once).
        progress: draw a progress bar (done, failed, ETA) on stderr.
        plots: write the load diagrams (needs matplotlib).
        report: write the text report.

    Returns:
        The table (pyarrow.Table), one row per run in run order: ``run_index``,
        ``run_id``, the swept parameters, then :data:`~exo_ctrl.sweep.outputs.OUTPUT_COLUMNS`.

    Raises:
        SweepInterrupted: on Ctrl-C, after writing the table of the runs
            finished so far (a rerun resumes).
        MissingDependency: pyarrow, or matplotlib for plots, is missing.

    """
    pyarrow()
    if plots:
        require("matplotlib", f"the load plots need matplotlib: {PLOTS_HINT}")
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise InvalidParameter("workers", workers, "an integer >= 1")
    paths = SweepPaths.for_output(out_path)
    tasks = spec.tasks()
    results = read_previous(paths)
    todo = [t for t in tasks if results.get(t.run_id, {}).get("status") not in FINISHED_STATUSES]
    owned = None
    if executor is None and todo:
        n = min(workers or os.cpu_count() or 1, len(todo))
        executor = owned = InlineExecutor() if n == 1 else local_pool(n)
        workers = n
    window = 2 * workers if workers else max(len(todo), 1)
    if progress:
        where = "in this process" if isinstance(executor, InlineExecutor) else "on "
        if where == "on ":
            where += f"{workers} workers" if workers else "the given executor"
        print(
            f"sweep: {len(tasks)} runs, {len(tasks) - len(todo)} already done "
            f"({paths.journal.name}), {len(todo)} to run {where}",
            file=sys.stderr,
        )
    state = _State(spec, tasks, paths, results, len(todo), progress)
    interrupted: KeyboardInterrupt | None = None
    clean = False
    try:
        if executor is not None:
            if owned is not None and not isinstance(owned, InlineExecutor):
                # The first run in this process, before the pool's workers run any:
                # they then load its compiled kernels from numba's cache instead of
                # compiling them side by side (numba's cache index is not safe
                # against two processes saving different signatures of one kernel
                # at once; a sweep's points can differ in their kernels' types).
                state.drive(InlineExecutor(), todo[:1], 1)
                todo = todo[1:]
            state.drive(executor, todo, window)
        clean = True
    except KeyboardInterrupt as exc:
        interrupted = exc
    finally:
        state.journal.close()
        if owned is not None:
            stop_pool(owned, now=not clean)
        state.bar.close(state.done, state.note())
        table = state.save_table()
    if interrupted is not None:  # state.total: every run to do, the in-process first one too
        name = getattr(interrupted, "signal_name", "")
        raise SweepInterrupted(table, state.done, state.total - state.done, name)
    if report:
        write_report(table, spec, DerivedOutput(paths.report))
    if plots:
        write_plots(table, spec, paths)
    return table


class _State:
    """A sweep in progress: results by run id, the journal, the progress bar."""

    def __init__(
        self,
        spec: SweepSpec,
        tasks: list[SweepTask],
        paths: SweepPaths,
        results: dict[str, dict[str, Any]],
        total: int,
        progress: bool,
    ) -> None:
        self.spec, self.tasks, self.paths, self.results = spec, tasks, paths, results
        self.total = total
        self.done = self.failed = 0
        self.journal = Journal(paths.journal)
        self.bar = Progress(total, "sweep", enabled=progress)
        self._pending: dict[cf.Future, SweepTask] = {}

    def note(self) -> str:
        """Progress note: done and failed runs."""
        return f"{self.done}/{self.total} done, {self.failed} failed"

    def save_table(self) -> Any:
        """Write (atomically) and return the table of the results so far."""
        table = build_table(self.spec, self.tasks, self.results)
        write_table(table, self.paths)
        return table

    def drive(self, executor: cf.Executor, todo: list[SweepTask], window: int) -> None:
        """Submit ``todo`` (at most ``window`` in flight); journal results as they come.

        On Ctrl-C: keep the runs already finished, cancel the rest, re-raise.
        """
        queue = iter(todo)
        pending = self._pending
        cache = str(self.paths.cache)
        last_write = time.monotonic()
        try:
            while True:
                while len(pending) < window and (task := next(queue, None)) is not None:
                    future = executor.submit(
                        run_point, self.spec.base, task.values, cache, task.label
                    )
                    pending[future] = task
                if not pending:
                    return
                done, _ = cf.wait(pending, timeout=1.0, return_when=cf.FIRST_COMPLETED)
                for future in done:
                    self._take(future)
                self.bar.update(self.done, self.note())
                if time.monotonic() - last_write > _TABLE_EVERY_S:
                    self.save_table()
                    last_write = time.monotonic()
        except KeyboardInterrupt:
            for future in list(pending):
                if future.done() and not future.cancelled() and future.exception() is None:
                    with contextlib.suppress(KeyboardInterrupt):
                        self._take(future)
                else:
                    future.cancel()
            raise

    def _take(self, future: cf.Future) -> None:
        """Record a finished run: results, journal, counts (Ctrl-C in a run re-raises)."""
        task = self._pending.pop(future)
        outputs = _outputs_of(future)
        if outputs["status"] == "interrupted":  # Ctrl-C inside an in-process run
            raise KeyboardInterrupt
        self.results[task.run_id] = outputs
        self.journal.write(task, outputs)
        self.done += 1
        self.failed += outputs["status"] != "completed"
