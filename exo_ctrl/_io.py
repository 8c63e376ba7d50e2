"""Output files: checked before a run starts, written whole or not at all.

Every output the command line writes goes through two functions:

- :func:`check_output` (before any work): the path is not a directory, its
  directory exists and is writable (no directory is ever created), and an
  existing file is writable.  The message names the user's path.
- :func:`atomic_write` (at the end): a new path or an existing regular file
  is written to a temporary file beside it, which then replaces it by a
  rename, so a failure leaves the old file (or none) and never a half-written
  one.  The temporary file gets the mode ``open()`` would have given: ``0o666
  & ~umask`` for a new file, the old file's mode for a replaced one.  An
  existing path that is not a regular file (a device such as ``/dev/full`` or
  ``/dev/null``, a FIFO, a symbolic link such as ``/dev/stdout``) is opened
  and written directly: a rename would replace the special file itself.
  Every write error is an :class:`OutputError` naming the user's path (never
  the temporary name).
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from .exceptions import ExoCtrlError, InvalidParameter, OutputError

__all__ = [
    "OUTPUT_ALLOWED",
    "atomic_write",
    "check_output",
    "is_special",
    "new_file_mode",
    "output_problem",
]

#: What an output path must be, in the words of :func:`check_output`'s message.
OUTPUT_ALLOWED = "a writable file in an existing directory"


def is_special(path: str | os.PathLike[str]) -> bool:
    """True if ``path`` exists and is not a regular file (device, FIFO, link, socket).

    A directory counts as special too; :func:`check_output` refuses it.
    """
    try:
        return not stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def output_problem(path: str | os.PathLike[str]) -> str | None:
    """Why ``path`` cannot be written as an output, or None if it can.

    Nothing is created: the checks are ``stat`` and ``access`` calls.
    """
    target = Path(path)
    if str(path) == "":
        return "the path is empty"
    if target.is_dir():
        return f"{target} is a directory"
    if is_special(target) and target.exists():
        if not os.access(target, os.W_OK):
            return f"permission denied on {target}"
        return None  # a device or FIFO, written directly
    parent = target.parent
    if not parent.exists():
        return f"directory {parent} does not exist"
    if not parent.is_dir():
        return f"{parent} is not a directory"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"permission denied on {parent}"
    if target.exists() and not os.access(target, os.W_OK):
        return f"permission denied on {target}"
    return None


def check_output(path: str | os.PathLike[str], name: str) -> Path:
    """Check, before any work, that ``path`` can be written; returns it as a Path.

    Args:
        path: the output path as the user gave it.
        name: the option or parameter that gave it (``--summary``).

    Raises:
        InvalidParameter: the path is a directory, its directory is missing,
            not a directory or not writable, or the file is read-only.

    """
    problem = output_problem(path)
    if problem is not None:
        raise InvalidParameter(name, str(path), OUTPUT_ALLOWED, problem)
    return Path(path)


def _umask() -> int:
    """The process's umask, read without changing it where the system allows."""
    with contextlib.suppress(OSError, ValueError):
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def new_file_mode(path: str | os.PathLike[str]) -> int:
    """The mode ``open(path, "w")`` leaves: the old file's, or ``0o666 & ~umask``."""
    with contextlib.suppress(OSError):
        return stat.S_IMODE(os.stat(path).st_mode)
    return 0o666 & ~_umask()


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO]:
    """Open ``path`` for writing so that a failure never leaves it half-written.

    A new path or a regular file is written through a temporary file beside
    it that replaces it on success (module docstring); on any exception the
    temporary file is removed and ``path`` is left as it was.  A special file
    (device, FIFO, symbolic link) is opened and written directly.  Text modes
    write UTF-8, lines ended as the caller writes them.

    Args:
        path: the output file.
        mode: ``"w"`` (text) or ``"wb"`` (bytes).

    Raises:
        OutputError: creating, writing or renaming failed (the message names
            ``path``).

    """
    target = Path(path)
    text = "b" not in mode
    options = {"encoding": "utf-8", "newline": ""} if text else {}
    if is_special(target):
        try:
            with open(target, mode, **options) as handle:
                yield handle
        except OSError as exc:
            raise OutputError(path, _reason(exc)) from None
        return
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise OutputError(path, _reason(exc)) from None
    try:
        with os.fdopen(fd, mode, **options) as handle:
            yield handle
        os.chmod(tmp, new_file_mode(target))
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, ExoCtrlError):
            raise OutputError(path, _reason(exc)) from None
        raise
