"""The ``exo-ctrl`` command.

Every subcommand validates its input through the library and checks its
output paths before it starts work; an
:class:`~exo_ctrl.exceptions.ExoCtrlError` becomes a one-line message on
stderr and exit code 2, never a traceback.  A file that cannot be written
once the work is done (:class:`~exo_ctrl._io.OutputError`, e.g. a full
disk) is exit code 1, with the same one-line message.  Files are written
whole or not at all (:mod:`exo_ctrl._io`); warnings are printed as one line
each, ``exo-ctrl CMD: warning: ...``.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import signal
import sys
import threading
import warnings
from collections.abc import Callable, Sequence
from typing import Any, TextIO

from ..exceptions import ExoCtrlError, OutputError, Terminated
from . import compare, estimate, export, gait, identify, scenario, simulate, sweep, urdf
from .common import Parser

__all__ = ["DESCRIPTION", "build_parser", "main"]

#: What ``exo-ctrl --help`` says first.
DESCRIPTION = (
    "Plan, simulate and estimate a lower-limb exoskeleton walking a patient on a treadmill. "
    "SI units throughout; 'exo-ctrl CMD --help' lists each option with its unit and default."
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``exo-ctrl``: one subcommand per module of this package."""
    parser = Parser(prog="exo-ctrl", description=DESCRIPTION)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for command in (simulate, compare, scenario, gait, urdf, estimate, export, identify, sweep):
        command.register(sub)
    return parser


def _one_line_warnings(command: str) -> Callable[..., None]:
    """A ``warnings.showwarning`` that prints ``exo-ctrl CMD: warning: message`` only."""

    def show(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        text = " ".join(str(message).split())
        print(f"exo-ctrl {command}: warning: {text}", file=file or sys.stderr)

    return show


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``exo-ctrl``; returns the exit code.

    0 success, 1 the work failed or its output could not be written, 2 bad
    input, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).
    """
    _tolerant_streams()
    parser = build_parser()
    try:
        args = parser.parse_args(argv)  # --help exits 0 here (SystemExit), bad usage 2
    except OSError as exc:  # --help could not be printed (Parser.print_help)
        if exc.errno not in _WRITE_ERRNOS:
            raise
        words = list(sys.argv[1:] if argv is None else argv)
        return _stdout_failed(words[0] if words else "", exc)
    previous = _on_sigterm()
    try:
        code = _run(args)
        try:
            sys.stdout.flush()  # a full device or a closed pipe shows here, not at exit
        except OSError as exc:
            code = _stdout_failed(args.command, exc)
        return code
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


#: Errors of a write that are the output's fault, not the input's: exit 1.
_WRITE_ERRNOS = {errno.EPIPE, errno.ENOSPC, errno.EFBIG, errno.EIO, errno.EDQUOT}


def _tolerant_streams() -> None:
    """Print what the terminal's encoding cannot show (τ in ASCII) as escapes, not a crash."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, ValueError, OSError):
            if (stream.encoding or "").lower().replace("-", "") != "utf8":
                stream.reconfigure(errors="backslashreplace")


def _stdout_failed(command: str, exc: OSError) -> int:
    """One line for standard output that cannot be written (closed pipe, full device); 1.

    Standard output is pointed at /dev/null afterwards, so the interpreter's
    own flush at exit does not fail again.
    """
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    reason = exc.strerror or str(exc)
    prog = f"exo-ctrl {command}" if command and not command.startswith("-") else "exo-ctrl"
    with contextlib.suppress(OSError):
        print(f"{prog}: error: cannot write standard output: {reason}", file=sys.stderr)
    return 1


def _on_sigterm() -> Any:
    """Make SIGTERM end the command as Ctrl-C does (data kept, files whole); the old handler.

    None when this is not the main thread (signals cannot be set there).
    """
    if threading.current_thread() is not threading.main_thread():
        return None

    def terminate(signum: int, frame: Any) -> None:
        raise Terminated("SIGTERM")

    return signal.signal(signal.SIGTERM, terminate)


def _run(args: argparse.Namespace) -> int:
    """The subcommand of ``args``, its errors turned into messages and exit codes."""
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warnings(args.command)
        try:
            return int(args.func(args))
        except OutputError as exc:
            print(f"exo-ctrl {args.command}: error: {exc}", file=sys.stderr)
            return 1
        except ExoCtrlError as exc:
            print(f"exo-ctrl {args.command}: error: {exc}", file=sys.stderr)
            return 2
        except OSError as exc:
            if exc.errno in _WRITE_ERRNOS and exc.filename is None:  # printing failed
                return _stdout_failed(args.command, exc)
            print(f"exo-ctrl {args.command}: error: {exc}", file=sys.stderr)
            return 2
        except Terminated as exc:
            print(f"exo-ctrl {args.command}: {exc}", file=sys.stderr)
            return 143
        except KeyboardInterrupt:
            print(f"exo-ctrl {args.command}: interrupted", file=sys.stderr)
            return 130
