"""The ``exo-ctrl`` command.

Every subcommand validates its input through the library; an
:class:`~exo_ctrl.exceptions.ExoCtrlError` becomes a one-line message on
stderr and exit code 2, never a traceback.  Files are written atomically.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from ..exceptions import ExoCtrlError
from . import estimate, gait, simulate, sweep, urdf
from .common import Parser

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``exo-ctrl``: one subcommand per module of this package."""
    parser = Parser(prog="exo-ctrl", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for command in (gait, urdf, simulate, estimate, sweep):
        command.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``exo-ctrl``; returns the exit code (0 success, 2 bad input, 130 interrupted)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except ExoCtrlError as exc:
        print(f"exo-ctrl {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"exo-ctrl {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"exo-ctrl {args.command}: interrupted", file=sys.stderr)
        return 130
