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
  the temporary name).  A special file is opened without blocking
  (:func:`open_special`): a FIFO nobody reads fails after
  :data:`FIFO_OPEN_TIMEOUT_S` instead of hanging.

Outputs never replace inputs: :func:`same_file_key` names a file by its
device and inode (``os.stat``'s ``st_dev``, ``st_ino``), so a hard link or a
symbolic link to an input counts as the input.  A path the user did not name
(:class:`DefaultOutput`, e.g. ``exo_run.rrd``; :class:`DerivedOutput`, e.g.
``DIR/compare.csv`` or a sweep's ``NAME.report.txt``) is never followed
through a symbolic link: the check refuses it, and a link planted after the
check is replaced by the rename, its target left alone.  A recording is
written to :func:`partial_path` beside its destination, locked there
(:func:`claim_partial`) so that a second run writing the same path refuses
at its start.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import stat
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from .exceptions import ExoCtrlError, InvalidParameter, OutputError

__all__ = [
    "FIFO_OPEN_TIMEOUT_S",
    "OUTPUT_ALLOWED",
    "DefaultOutput",
    "DerivedOutput",
    "atomic_write",
    "check_output",
    "claim_partial",
    "is_special",
    "new_file_mode",
    "not_a_file",
    "open_special",
    "output_problem",
    "partial_in_use",
    "partial_path",
    "same_file_key",
]

#: Longest wait for a reader when an output is a FIFO nobody has open [s].
FIFO_OPEN_TIMEOUT_S = 10.0
#: Poll period while waiting for a FIFO's reader [s].
_FIFO_POLL_S = 0.05


class DefaultOutput(str):
    """An output path the user did not name (an option's default such as ``exo_run.rrd``).

    :func:`check_output` (:func:`output_problem`) refuses it if it is a
    symbolic link: in a shared directory someone else may have planted it,
    and only a path the user named is written through a link.
    :func:`atomic_write` replaces such a link itself, never its target.
    """

    #: How the check's message describes the path.
    how = "the default"


class DerivedOutput(DefaultOutput):
    """An output the command names inside or beside a path the user gave.

    ``DIR/compare.csv`` for ``compare --out DIR``, ``NAME.report.txt`` for
    ``sweep --out NAME.parquet``, a cohort's ``DIR/patient_s0_000.urdf``:
    never followed through a symbolic link, as :class:`DefaultOutput`.
    """

    how = "named by the command"


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

    Nothing is created: the checks are ``stat`` and ``access`` calls.  A
    :class:`DefaultOutput` (or :class:`DerivedOutput`) that is a symbolic
    link, a FIFO or a device is refused.
    """
    target = Path(path)
    if str(path) == "":
        return "the path is empty"
    if isinstance(path, DefaultOutput) and os.path.islink(path):
        return (
            f"{path}, {path.how}, is a symbolic link to {os.readlink(path)}; a link is "
            "followed only when named"
        )
    if isinstance(path, DefaultOutput) and is_special(path) and not target.is_dir():
        return (
            f"{path}, {path.how}, is not a regular file (a FIFO or a device); only a path "
            "you name is written to one"
        )
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


def not_a_file(path: str | os.PathLike[str]) -> str:
    """Why an input ``path`` that is not a regular file cannot be read, in words.

    An input is read only from a regular file: a FIFO or a device could
    block or never end.
    """
    if not os.path.exists(path):
        return "file not found"
    if os.path.isdir(path):
        return "a directory, not a file"
    return "not a regular file (a FIFO or a device is not read: it may never end)"


def check_output(path: str | os.PathLike[str], name: str) -> Path:
    """Check, before any work, that ``path`` can be written; returns it as a Path.

    Args:
        path: the output path as the user gave it.
        name: the option or parameter that gave it (``--summary``).

    Raises:
        InvalidParameter: the path is a directory, its directory is missing,
            not a directory or not writable, the file is read-only, or a
            path the user did not name is a symbolic link.

    """
    problem = output_problem(path)
    if problem is None and os.path.islink(partial_path(path)):
        problem = f"{partial_path(path)} is a symbolic link; the recording is written there first"
    if problem is None and partial_in_use(path):
        problem = f"{partial_path(path)} is locked: another exo-ctrl process is writing {path}"
    if problem is not None:
        raise InvalidParameter(name, str(path), OUTPUT_ALLOWED, problem)
    return Path(path)


def same_file_key(path: str | os.PathLike[str]) -> tuple:
    """A key equal for two paths naming one file: device and inode, links followed.

    A path that does not exist yet is keyed by its resolved path (two
    outputs to one new file).
    """
    try:
        st = os.stat(path)
    except OSError:
        return ("path", os.path.realpath(path))
    return ("inode", st.st_dev, st.st_ino)


def open_special(
    path: str | os.PathLike[str], flags: int = os.O_WRONLY, timeout_s: float | None = None
) -> int:
    """Open a special file (device, FIFO, link to one) for writing without blocking forever.

    The file is opened with ``O_NONBLOCK``: a FIFO without a reader fails at
    once with ``ENXIO`` and is tried again every 50 ms up to ``timeout_s``
    (default :data:`FIFO_OPEN_TIMEOUT_S`); once open, the descriptor is made
    blocking again, so writes wait for a slow reader as usual.

    Returns:
        The descriptor (close-on-exec).

    Raises:
        OSError: the open failed; ``ETIMEDOUT`` with the reason "no process
            opened the FIFO for reading within N s" when no reader came.

    """
    wait = FIFO_OPEN_TIMEOUT_S if timeout_s is None else timeout_s
    deadline = time.monotonic() + wait
    while True:
        try:
            fd = os.open(path, flags | os.O_NONBLOCK | os.O_CLOEXEC)
            break
        except OSError as exc:
            if exc.errno != errno.ENXIO or time.monotonic() >= deadline:
                if exc.errno == errno.ENXIO:
                    reason = f"no process opened the FIFO for reading within {wait:g} s"
                    raise OSError(errno.ETIMEDOUT, reason) from None
                raise
            time.sleep(_FIFO_POLL_S)
    fcntl.fcntl(fd, fcntl.F_SETFL, fcntl.fcntl(fd, fcntl.F_GETFL) & ~os.O_NONBLOCK)
    return fd


def partial_path(path: str | os.PathLike[str]) -> Path:
    """Where an output is written before it is whole: ``NAME.partial.rrd`` for ``NAME.rrd``."""
    target = Path(path)
    suffix = target.suffix or ".rrd"
    return target.with_name(f"{target.stem if target.suffix else target.name}.partial{suffix}")


def partial_in_use(path: str | os.PathLike[str]) -> bool:
    """True if another process holds the lock of ``path``'s partial file (:func:`claim_partial`)."""
    try:
        fd = os.open(partial_path(path), os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        os.close(fd)
    return False


def claim_partial(path: str | os.PathLike[str]) -> int:
    """Create, lock and empty ``path``'s partial file; its descriptor (read-write, locked).

    The lock (``flock``, exclusive) lasts as long as the descriptor, and any
    copy of it, stays open: a second process claiming the same path fails.
    The partial file is never followed through a symbolic link, and one
    with other hard links is unlinked (its other names keep their data)
    and created anew, so claiming it never touches another file.  A stale
    partial file of an ended run is emptied.

    Raises:
        OSError: the file cannot be created; ``EBUSY`` when another process
            is writing it, ``ELOOP`` when it is a symbolic link.

    """
    partial = partial_path(path)
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
    for _ in range(10):
        try:
            fd = os.open(partial, flags, new_file_mode(path))
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise OSError(errno.ELOOP, f"{partial} is a symbolic link") from None
            raise
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            reason = f"{partial} is locked: another exo-ctrl process is writing {path}"
            raise OSError(errno.EBUSY, reason) from None
        st = os.fstat(fd)
        try:
            now = os.lstat(partial)
        except FileNotFoundError:
            now = None
        if now is None or (now.st_dev, now.st_ino) != (st.st_dev, st.st_ino):
            os.close(fd)  # renamed away by the run that held it: try the new name
            continue
        if st.st_nlink != 1 or not stat.S_ISREG(st.st_mode):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(partial)
            os.close(fd)
            continue
        os.ftruncate(fd, 0)
        return fd
    raise OSError(errno.EBUSY, f"{partial} kept changing while it was claimed")


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
    (device, FIFO, symbolic link) is opened and written directly, except a
    symbolic link at a path the user did not name (:class:`DefaultOutput`),
    which the rename replaces (its target is never written).  Text modes
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
    unnamed_link = isinstance(path, DefaultOutput) and os.path.islink(path)
    if is_special(target) and not unnamed_link:
        try:
            with os.fdopen(open_special(target), mode, **options) as handle:
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
        os.chmod(tmp, 0o666 & ~_umask() if unnamed_link else new_file_mode(target))
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, ExoCtrlError):
            raise OutputError(path, _reason(exc)) from None
        raise
