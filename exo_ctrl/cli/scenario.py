"""``exo-ctrl scenario``: list the presets, write a scenario file to edit, or a run's own.

``--preset NAME --out FILE.toml`` writes the preset as a complete, commented
file (every key with its default, unit and meaning); ``--from RUN.rrd --out
FILE.toml`` writes the scenario a recording was made with, which
``exo-ctrl simulate FILE.toml`` runs again to the same summary.
"""

from __future__ import annotations

import argparse

from .._io import atomic_write
from ..exceptions import InvalidParameter
from ..record import read_recording
from ..scenario import PRESETS, Scenario, preset_description, scenario_template
from .common import check_outputs

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``scenario`` subcommand."""
    p = sub.add_parser(
        "scenario",
        help="list the presets, or write a scenario file (a preset's, or a recording's)",
        description="Write a complete, commented scenario file to edit and run with "
        "'exo-ctrl simulate FILE.toml'.",
    )
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--list", action="store_true", help="list the presets, one line each")
    which.add_argument(
        "--preset",
        metavar="NAME",
        help="the preset: " + ", ".join(PRESETS) + " (default: none)",
    )
    which.add_argument(
        "--from",
        dest="recording",
        metavar="RUN.rrd",
        help="the scenario a recording was made with (its summary is reproduced) (default: none)",
    )
    p.add_argument("--out", metavar="FILE.toml", help="the scenario file to write (default: none)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """List the presets or write the scenario file; 0 on success."""
    if args.list:
        width = max(len(name) for name in PRESETS)
        for name in PRESETS:
            print(f"{name:<{width}}  {preset_description(name)}")
        return 0
    if args.out is None:
        raise InvalidParameter("--out", None, "a path for the scenario file (FILE.toml)")
    reads = {"the recording": args.recording} if args.recording else None
    check_outputs(args, reads=reads, out="--out")
    if args.recording is not None:
        back = read_recording(args.recording)
        header = (
            f"exo_ctrl scenario of the recording {args.recording}.\n"
            "exo-ctrl simulate THIS_FILE.toml runs it again (same seeds, same summary)."
        )
        text = Scenario(back.config).to_toml(comments=True, header=header)
    else:
        text = scenario_template(args.preset)
    with atomic_write(args.out) as handle:
        handle.write(text)
    print(f"scenario: {args.out} (run it: exo-ctrl simulate {args.out})")
    return 0
