"""``exo-ctrl compare``: controllers on one scenario, or existing recordings, side by side.

Two forms::

    exo-ctrl compare --controllers pd,ct,qp [SCENARIO.toml | --preset NAME] [--set K=V]
                     --out DIR [--cycles N | --duration SEC]
    exo-ctrl compare A.rrd B.rrd ... --out DIR [--allow-different]

Prints the table in Markdown (:meth:`~exo_ctrl.comparison.CompareTable.markdown`)
and writes ``DIR/compare.csv``, ``DIR/compare.json`` and ``DIR/compare.png``
(each whole or not at all).  Before any run: ``DIR`` must be a directory
whose three files can be written (a new one is made in an existing
directory, and removed again if the command fails), and matplotlib must be
installed.
A progress line per run on stderr.  Exit 0; 1 when a compared run did not
complete (the table is written all the same); 2 bad input (runs whose
configurations differ beyond the controller and its gains, without ``--allow-different``);
130 Ctrl-C.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Callable
from pathlib import Path

from .._io import DerivedOutput
from ..comparison import (
    CompareRow,
    CompareTable,
    compare,
    require_matplotlib,
    write_compare_png,
)
from ..comparison.recordings import compare_recordings
from ..exceptions import InvalidParameter
from ..scenario import DEFAULT_PRESET, PRESETS, load_scenario
from ..sim import CONTROLLERS
from .common import check_outputs, import_from_cwd

__all__ = ["OUTPUT_FILES", "register", "run"]

#: The files written into ``--out DIR``: attribute of the parsed options → file name.
OUTPUT_FILES = {"csv_file": "compare.csv", "json_file": "compare.json", "png_file": "compare.png"}


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``compare`` subcommand."""
    p = sub.add_parser(
        "compare",
        help="controllers on one scenario, or recordings, side by side: a table and a figure",
        description="Compare controllers on one scenario (--controllers pd,ct,qp), or existing "
        "recordings (A.rrd B.rrd ...): prints a Markdown table of each run's figures (tracking "
        "error, drive torque and current, cuff forces and their estimate, the belt's slip and "
        "touchdowns, energy, safety events, real-time factor) and writes DIR/compare.csv, "
        "DIR/compare.json and DIR/compare.png (the last full gait cycle, the runs overlaid).",
    )
    p.add_argument(
        "inputs",
        nargs="*",
        metavar="RUN.rrd",
        help="recordings to compare (exo-ctrl simulate --out RUN.rrd); with --controllers: "
        f"at most one scenario file, SCENARIO.toml ({DEFAULT_PRESET} when none is given)",
    )
    p.add_argument(
        "--preset",
        default=None,
        metavar="NAME",
        help="with --controllers: a shipped scenario instead of a file: "
        + ", ".join(PRESETS)
        + f" (default: none; with no file either, {DEFAULT_PRESET})",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="with --controllers: override one key of the scenario, e.g. --set gait.period=1.1 "
        "(repeatable) (default: none)",
    )
    p.add_argument(
        "--controllers",
        default=None,
        metavar="LIST",
        help=f"controllers to run and compare, comma-separated, from {','.join(CONTROLLERS)} "
        "or your own as MODULE:CLASS (docs/controllers.md) (default: none: the recordings "
        "given are compared)",
    )
    p.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help="the directory for compare.csv, compare.json and compare.png (made if new, "
        "in an existing directory) (default: none, required)",
    )
    length = p.add_mutually_exclusive_group()
    length.add_argument(
        "--cycles",
        type=float,
        default=None,
        metavar="N",
        help="with --controllers: gait cycles at full speed after the ramp-in [cycles] "
        "(default: the scenario's duration, 3.6 s: the ramp-in and 2 cycles)",
    )
    length.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="SEC",
        help="with --controllers: simulated time [s], ramps included "
        "(default: the scenario's, 3.6 s)",
    )
    p.add_argument(
        "--allow-different",
        action="store_true",
        help="compare runs whose configurations differ in more than the controller and its gains "
        "(default: refused, naming the differing keys)",
    )
    p.set_defaults(func=run)


def _check_args(args: argparse.Namespace, check_files: bool = True) -> None:
    """The form's options and the output directory, before any work.

    ``check_files`` False: not the files in ``--out`` (a directory not made yet).

    Raises:
        InvalidParameter: a form mixed up, or ``--out`` neither a directory nor a
            new one in an existing directory.

    """
    if args.controllers is None:
        if not args.inputs:
            raise InvalidParameter(
                "--controllers", None, "given (pd,ct,qp), or recordings RUN.rrd as arguments"
            )
        given = (
            ("--cycles", args.cycles),
            ("--duration", args.duration),
            ("--preset", args.preset),
            ("--set", args.set or None),
        )
        for option, value in given:
            if value is not None:
                raise InvalidParameter(option, value, "given only with --controllers")
    elif len(args.inputs) > 1:
        raise InvalidParameter(
            "SCENARIO", args.inputs, "at most one scenario with --controllers (no recordings)"
        )
    parent = os.path.dirname(os.path.abspath(args.out))
    if not os.path.isdir(args.out) and (os.path.lexists(args.out) or not os.path.isdir(parent)):
        raise InvalidParameter(
            "--out", args.out, "a directory, existing or new in an existing directory"
        )
    if not check_files:
        return
    for attribute, name in OUTPUT_FILES.items():
        setattr(args, attribute, DerivedOutput(Path(args.out) / name))  # never through a link
    reads = (
        dict(zip(["the scenario file"], args.inputs, strict=False))
        if args.controllers is not None
        else {f"input {p}": p for p in args.inputs}
    )
    check_outputs(args, reads=reads, **dict.fromkeys(OUTPUT_FILES, "--out"))


def _notice(verb: str) -> Callable[[int, int, CompareRow], None]:
    """The progress line printed after each run (or recording read): ``verb`` names it."""

    def say(i: int, n: int, row: CompareRow) -> None:
        s = row.summary
        print(
            f"exo-ctrl compare: {verb} {i}/{n} ({row.label}): {row.status}, "
            f"{s.get('duration_s', 0.0):.3f} s simulated, "
            f"real-time factor {s.get('real_time_factor', 0.0):.2f}",
            file=sys.stderr,
            flush=True,
        )

    return say


def run(args: argparse.Namespace) -> int:
    """Compare, print the table, write the files; 0, or 1 when a compared run did not complete.

    A new ``--out`` directory is made after the other checks, and removed
    again (if still empty) when the command fails.
    """
    import_from_cwd()  # a user's controller given as module:Class
    created = not os.path.isdir(args.out)
    if created:
        require_matplotlib()  # before anything is made
        _check_args(args, check_files=False)
        os.mkdir(args.out)
    try:
        return _run(args)
    except BaseException:
        if created:
            with contextlib.suppress(OSError):
                os.rmdir(args.out)  # only if nothing was written
        raise


def _run(args: argparse.Namespace) -> int:
    """The command once ``--out`` is a directory."""
    _check_args(args)
    require_matplotlib()
    table: CompareTable
    if args.controllers is not None:
        path = args.inputs[0] if args.inputs else None
        scenario = load_scenario(path, args.preset, args.set)
        table = compare(
            scenario,
            args.controllers,
            cycles=args.cycles,
            duration_s=args.duration,
            allow_different=args.allow_different,
            on_run=_notice("run"),
            progress=True,
            warmup=True,
        )
    else:
        table = compare_recordings(
            args.inputs, allow_different=args.allow_different, on_run=_notice("read")
        )
    table.to_csv(args.csv_file)
    table.to_json(args.json_file)
    write_compare_png(table, args.png_file)
    print(table.markdown())
    if table.differences:
        differ = ", ".join(table.differences)
        print(f"\nthe runs differ in: {differ}")
    print(f"\nwritten: {args.csv_file}, {args.json_file}, {args.png_file}")
    failed = [row.label for row in table if row.status != "completed"]
    if failed and args.controllers is not None:
        print(f"exo-ctrl compare: error: not completed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0
