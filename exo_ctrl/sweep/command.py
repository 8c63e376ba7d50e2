"""The ``exo-ctrl sweep`` command: its options and what it runs.

``exo-ctrl sweep --param NAME=V1,V2,... [--param ...] --out PATH.parquet``
runs the sweep (:func:`~exo_ctrl.sweep.run.run_sweep`) on local worker
processes, or on a Dask scheduler with ``--scheduler tcp://HOST:PORT``, then
prints where the table went and the report's worst cases.  The exit code is
0 when done and 130 on Ctrl-C (the finished runs are kept; the same command
resumes).
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import sys
from typing import Any

from ..exceptions import InvalidParameter, MissingDependency, SweepError
from ..sim import CONTROLLERS, SimConfig
from .outputs import SweepPaths
from .parameters import parameter_names
from .run import SweepInterrupted, run_sweep
from .spec import DEFAULT_CYCLES, SweepSpec

__all__ = ["DASK_HINT", "add_sweep_arguments", "run_sweep_command"]

DASK_HINT = 'pip install "exo-ctrl[dask]"'


def add_sweep_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``exo-ctrl sweep`` options to ``parser``."""
    parser.add_argument(
        "--param",
        action="append",
        required=True,
        metavar="NAME=V1,V2,...|NAME=LO:HI:N",
        help="a swept parameter: a list, or N evenly spaced values LO..HI (repeatable); "
        f"names: {', '.join(parameter_names())}",
    )
    parser.add_argument(
        "--samples",
        type=int,
        default=None,
        metavar="N",
        help="N random points, uniform in each parameter's [min, max] (default: the full grid)",
    )
    parser.add_argument(
        "--seed", type=int, default=0, metavar="S", help="seed of --samples (default 0)"
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
        help="local worker processes (default: the CPU count; 1: in this process)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help=f"run on this Dask scheduler instead (needs {DASK_HINT})",
    )
    span = parser.add_mutually_exclusive_group()
    span.add_argument(
        "--cycles",
        type=float,
        default=None,
        metavar="N",
        help=f"gait cycles per run (default {DEFAULT_CYCLES:g})",
    )
    span.add_argument(
        "--duration", type=float, default=None, metavar="SEC", help="simulated time per run [s]"
    )
    parser.add_argument(
        "--controller",
        choices=CONTROLLERS,
        default=None,
        help="controller when not swept (default pd)",
    )
    parser.add_argument(
        "--rate", type=float, default=1000.0, metavar="HZ", help="control rate [Hz] (default 1000)"
    )
    parser.add_argument(
        "--substeps", type=int, default=1, metavar="N", help="plant steps per tick (default 1)"
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


def run_sweep_command(args: argparse.Namespace) -> int:
    """Run ``exo-ctrl sweep``; returns the exit code (0 done, 130 interrupted).

    Bad input raises :class:`~exo_ctrl.exceptions.ExoCtrlError` (the CLI
    prints it in one line and exits 2).
    """
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
    executor, workers, client = None, args.workers, None
    if args.scheduler is not None:
        executor, workers, client = _dask_executor(args.scheduler)
    try:
        table = run_sweep(
            spec, args.out, executor=executor, workers=workers, plots=not args.no_plots
        )
    except SweepInterrupted as exc:
        print(
            f"exo-ctrl sweep: interrupted: {exc.done} runs finished, {exc.remaining} to do; "
            f"{len(exc.table)} rows written to {args.out} (run the same command to resume)",
            file=sys.stderr,
        )
        return 130
    finally:
        if client is not None:
            client.close()
    paths = SweepPaths.for_output(args.out)
    status = table.column("status").to_pylist()
    print(
        f"wrote {len(table)} runs ({status.count('completed')} completed) to {paths.table} "
        f"and {paths.csv}"
    )
    if paths.report.is_file():
        print(f"report: {paths.report}")
        for line in paths.report.read_text(encoding="utf-8").splitlines():
            if line.startswith("worst"):
                print("  " + line)
    return 0
