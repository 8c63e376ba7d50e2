"""The ``exo-ctrl sweep`` command: its options and what it runs.

``exo-ctrl sweep --param NAME=V1,V2,... [--param ...] --out PATH.parquet``
runs the sweep (:func:`~exo_ctrl.sweep.run.run_sweep`) on local worker
processes, or on a Dask scheduler with ``--scheduler tcp://HOST:PORT``, then
prints where the table went, how many runs completed and failed, and the
report's worst cases.  Exit codes: 0 when at least one run completed, 1 when
none did (the table, with every run's error, is still written), 2 for bad
input, 130 on Ctrl-C (the finished runs are kept; the same command resumes).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import os
import sys
from collections.abc import Sequence
from typing import Any

from .._io import OUTPUT_ALLOWED, DerivedOutput, output_problem
from .._plugin import import_from_cwd
from ..exceptions import InvalidParameter, MissingDependency, SweepError
from ..sim import SimConfig
from .outputs import SweepPaths
from .parameters import parameter_listing
from .run import SweepInterrupted, run_sweep
from .spec import DEFAULT_CYCLES, SweepSpec

__all__ = ["DASK_HINT", "add_sweep_arguments", "check_sweep_outputs", "run_sweep_command"]

DASK_HINT = '.venv/bin/pip install -e ".[dask]"'


def add_sweep_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``exo-ctrl sweep`` options to ``parser``."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = parameter_listing()
    parser.add_argument(
        "--param",
        action="append",
        required=True,
        metavar="NAME=V1,V2,...|NAME=LO:HI:N",
        help="a swept parameter: a list, or N evenly spaced values LO..HI (repeatable); "
        "names, units, accepted values and defaults: below",
    )
    parser.add_argument(
        "--samples",
        type=int,
        default=None,
        metavar="N",
        help="number of random points, no unit, uniform in each parameter's [min, max] "
        "(default: none, the full grid)",
    )
    parser.add_argument(
        "--seed", type=int, default=0, metavar="S", help="seed of --samples, no unit (default 0)"
    )
    parser.add_argument(
        "--out",
        required=True,
        metavar="PATH.parquet",
        help="output table; PATH.csv, PATH.journal.jsonl (resume), PATH.report.txt and "
        "PATH.load_*.png go beside it",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local worker processes, no unit "
        f"(default: the CPU count, {os.cpu_count()} here; 1 runs in this process)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help="run on this Dask scheduler instead "
        f"(default: none, local worker processes; needs {DASK_HINT})",
    )
    span = parser.add_mutually_exclusive_group()
    span.add_argument(
        "--cycles",
        type=float,
        default=None,
        metavar="N",
        help=f"gait cycles at full speed per run, after the ramp-in [cycles] (default "
        f"{DEFAULT_CYCLES:g})",
    )
    span.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="SEC",
        help=f"simulated time per run [s] (default: a one-period ramp-in and {DEFAULT_CYCLES:g} "
        f"gait cycles, {(DEFAULT_CYCLES + 1) * SimConfig().gait.period:g} s at the default period)",
    )
    parser.add_argument(
        "--controller",
        default=None,
        metavar="NAME",
        help="controller when not swept: pd, ct, qp or your own as MODULE:CLASS "
        "(docs/controllers.md) (default pd)",
    )
    parser.add_argument(
        "--rate", type=float, default=1000.0, metavar="HZ", help="control rate [Hz] (default 1000)"
    )
    parser.add_argument(
        "--substeps",
        type=int,
        default=1,
        metavar="N",
        help="plant steps per tick, no unit (default 1)",
    )
    parser.add_argument("--no-plots", action="store_true", help="do not write the load diagrams")


def _dask_executor(address: str) -> tuple[cf.Executor, int, Any]:
    """(executor, worker threads, client) of the Dask scheduler at ``address``."""
    try:
        from distributed import Client
    except ImportError:
        raise MissingDependency(f"--scheduler needs Dask: {DASK_HINT}") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise SweepError(f"cannot connect to the Dask scheduler at {address}: {exc}") from None
    workers = max(sum(client.nthreads().values()), 1)
    return client.get_executor(pure=False), workers, client


def check_sweep_outputs(out: str, names: Sequence[str] = ()) -> SweepPaths:
    """The files of a sweep to ``out``, each checked as an output.

    ``names``: the swept parameters whose load diagrams will be written
    (``DIR/NAME.load_PARAM.png``), checked too.

    Raises:
        InvalidParameter: ``out`` does not end in .parquet, or one of the
            files cannot be written (the message names ``--out`` and the file).

    """
    try:
        paths = SweepPaths.for_output(out)
    except InvalidParameter as exc:
        raise InvalidParameter("--out", out, exc.allowed) from None
    plots = [paths.plot(name) for name in names if name != "controller"]
    derived = [DerivedOutput(p) for p in (paths.csv, paths.journal, paths.report, *plots)]
    for path in (paths.table, *derived):  # the files beside --out: never through a link
        problem = output_problem(path)
        if problem is not None:
            raise InvalidParameter("--out", out, OUTPUT_ALLOWED, problem)
    if os.path.islink(paths.cache):  # generated URDFs go in there: never through a link
        problem = (
            f"{paths.cache}, named by the command, is a symbolic link to "
            f"{os.readlink(paths.cache)}; a link is followed only when named"
        )
        raise InvalidParameter("--out", out, OUTPUT_ALLOWED, problem)
    return paths


def run_sweep_command(args: argparse.Namespace) -> int:
    """Run ``exo-ctrl sweep``; returns the exit code (module docstring).

    Bad input raises :class:`~exo_ctrl.exceptions.ExoCtrlError` (the CLI
    prints it in one line and exits 2), an output that cannot be written
    among them (:func:`exo_ctrl._io.check_output` of each file beside
    ``--out``), before any run starts.
    """
    import_from_cwd()  # a user's controller given as module:Class
    names = [p.partition("=")[0].strip() for p in args.param]
    if args.controller is not None and "controller" in names:
        raise InvalidParameter(
            "controller", args.controller, "given once: --controller or --param controller=..."
        )
    if args.scheduler is not None and args.workers is not None:
        raise InvalidParameter("workers", args.workers, "unset with --scheduler")
    base = SimConfig(
        controller=args.controller or "pd",
        control_rate_hz=args.rate,
        plant_substeps=args.substeps,
    )
    spec = SweepSpec.parse(
        args.param,
        samples=args.samples,
        seed=args.seed,
        duration_s=args.duration,
        cycles=args.cycles,
        base=base,
    )
    names = () if args.no_plots else spec.names  # their load diagrams' files too
    paths = check_sweep_outputs(args.out, names)  # before any run: never after a long sweep
    executor, workers, client = None, args.workers, None
    if args.scheduler is not None:
        executor, workers, client = _dask_executor(args.scheduler)
    try:
        table = run_sweep(
            spec, args.out, executor=executor, workers=workers, plots=not args.no_plots
        )
    except SweepInterrupted as exc:
        how = f"terminated by {exc.signal_name}" if exc.signal_name else "interrupted"
        print(
            f"exo-ctrl sweep: {how}: {exc.done} runs finished, {exc.remaining} to do; "
            f"{len(exc.table)} rows written to {args.out} (run the same command to resume)",
            file=sys.stderr,
        )
        return 143 if exc.signal_name == "SIGTERM" else 130
    finally:
        if client is not None:
            client.close()
    status = table.column("status").to_pylist()
    completed = status.count("completed")
    failed = len(status) - completed
    print(
        f"wrote {len(table)} runs ({completed} completed, {failed} failed) to {paths.table} "
        f"and {paths.csv}"
    )
    if paths.report.is_file():
        print(f"report: {paths.report}")
        for line in paths.report.read_text(encoding="utf-8").splitlines():
            if line.startswith("worst"):
                print("  " + line)
    if completed == 0 and status:
        errors = [e for e in table.column("error").to_pylist() if e]
        first = f"; the first error: {errors[0].splitlines()[0]}" if errors else ""
        print(
            f"exo-ctrl sweep: none of the {len(status)} runs completed{first}",
            file=sys.stderr,
        )
        return 1
    return 0
