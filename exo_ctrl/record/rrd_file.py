"""An ``.rrd`` file written by the recorder itself from rerun's in-memory encoding.

Rerun encodes the recording into memory (a ``BinaryStream``); every
:meth:`RrdFile.append` takes what rerun encoded since the last one (a
complete RRD stream: header, messages, end marker with its footer, stream
footer; :mod:`.rrd_footer`) and writes its messages to the file followed by
a footer for *the whole file so far* (:class:`~.rrd_footer.Manifests`).  So
after every append the file is a complete recording that ``rerun rrd
verify`` accepts, and a write error (a full disk) is an ``OSError`` raised
where it happens; rerun never owns a file that failed.

Crash safety.  Each append is one write at the offset where the previous
footer began (the file is cut there first, then the new messages and the
new footer follow).  A kill in the middle of that write would leave the
file ending in a cut message (every earlier append still readable by
:func:`~.reader.read_recording`, but ``rerun rrd verify`` rejects it): with
the default run writing about 5 MB per 2000-tick chunk and simulating a
chunk in 30-40 ms, a kill at a random moment landed in a write 4 times in
30.  So a regular file is written by a small process of its own
(:mod:`.write_process`, in its own session): it carries a write out only
once the whole request has arrived, and completes it even if the recording
process is gone.  A SIGKILL of the recording process therefore never cuts a
write (none in 30 random kills); what can still cut one is killing the
writer process itself, or the machine losing power, both of which leave
the file readable up to its last complete append.  A special file
(``/dev/null``, a FIFO) cannot be rewritten in place: it is written
directly, the messages as they come and the footer once, at
:meth:`RrdFile.close`.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

from .._io import is_special
from ..exceptions import RecordingError
from .rrd_footer import HEADER_SIZE, Manifests, end_of_stream, split_stream
from .write_process import ANSWER, REQUEST

__all__ = ["RrdFile", "signals_held"]

#: Longest wait for the writer process to end after the file is closed [s].
WRITER_EXIT_TIMEOUT_S = 10.0


class RrdFile:
    """An ``.rrd`` file the recorder writes: whole messages, a footer after every append.

    Args:
        path: the file (created or truncated; a special file is opened as it is).

    Raises:
        OSError: the file cannot be opened.

    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.special = is_special(self.path)
        flags = os.O_WRONLY | (0 if self.special else os.O_CREAT | os.O_TRUNC)
        self._fd: int | None = os.open(self.path, flags | os.O_CLOEXEC, 0o666)
        self._writer: subprocess.Popen | None = None
        if not self.special:
            with contextlib.suppress(OSError):  # no interpreter to run it: write in place here
                self._writer = _start_writer(self._fd)
        self._header: bytes | None = None
        self._end = 0  # end of the messages written so far
        self._tail = b""  # the footer at _end, as last written
        self._manifests = Manifests()

    @property
    def bytes_written(self) -> int:
        """Bytes of messages in the file (the footer not counted)."""
        return self._end

    def append(self, data: bytes | None) -> None:
        """Write the messages of one complete RRD stream, then the footer of the whole file.

        After a failed append the file is to be closed (:meth:`abandon`),
        not appended to again: the merged footer already holds that stream.

        Raises:
            OSError: writing failed (disk full); a regular file is then put
                back as it was before the call (every earlier append, whole,
                with its footer).
            RecordingError: the stream's layout is unknown (another rerun).

        """
        if not data:
            return
        with signals_held():
            self._append(data)

    def _append(self, data: bytes) -> None:
        """:meth:`append` with SIGINT and SIGTERM held (the footer's state and the file agree)."""
        parts = split_stream(data)
        if self._header is not None and parts.header != self._header:
            raise RecordingError("rerun changed its stream header between two chunks")
        head = parts.header if self._header is None else b""  # the file's header, once
        base = self._end if self._header is not None else HEADER_SIZE
        self._manifests.add(parts.footer, base - HEADER_SIZE)
        start, end = base - len(head), base + len(parts.body)
        tail = b"" if self.special else end_of_stream(self._manifests.encode(), end)
        try:
            self._write([head, parts.body, tail], start)
        except OSError:
            self._restore()
            raise
        self._header = self._header or parts.header
        self._end, self._tail = end, tail

    def close(self) -> None:
        """Finish the file (a special file gets its footer now) and close it; idempotent.

        Raises:
            OSError: writing the footer failed.

        """
        if self._fd is None:
            return
        try:
            if self.special and self._header is not None:
                self._write([end_of_stream(self._manifests.encode(), self._end)], self._end)
        finally:
            self.abandon()

    def abandon(self) -> None:
        """Close the file without writing anything more (after a failed write)."""
        fd, self._fd = self._fd, None
        writer, self._writer = self._writer, None
        if writer is not None:
            _stop_writer(writer)
        if fd is not None:
            with contextlib.suppress(OSError):
                os.close(fd)

    def _restore(self) -> None:
        """After a failed write, put the last footer back: the file is as before the call.

        The old footer's bytes go where the file had blocks a moment ago, so
        rewriting them needs no new space on a full disk.
        """
        if self._fd is None or not self._tail:
            return
        with contextlib.suppress(OSError):
            self._write([self._tail], self._end)

    def _write(self, pieces: list, offset: int) -> None:
        """Write ``pieces`` (bytes-like) one after the other at ``offset``.

        A regular file is first cut at ``offset`` (the old footer goes), then
        written, by the writer process (module docstring), or here if it
        could not be started (no interpreter at ``sys.executable``: then a
        kill of this process during the write can cut it); a special file is
        written here, in one ``writev``.
        """
        if self._fd is None:
            raise RecordingError(f"recording {self.path} is closed")
        views = [memoryview(p).cast("B") for p in pieces if len(p)]
        if self._writer is None:
            if not self.special:
                os.ftruncate(self._fd, offset)
            _write_all(self._fd, views, None if self.special else offset)
            return
        total = sum(len(v) for v in views)
        stdin, stdout = self._writer.stdin, self._writer.stdout
        if stdin is None or stdout is None:
            raise RecordingError(f"recording {self.path}: its writer process has no pipes")
        try:
            _write_all(stdin.fileno(), [memoryview(REQUEST.pack(offset, total)), *views])
            answer = _read_exact(stdout.fileno(), ANSWER.size)
        except BrokenPipeError:
            answer = None
        if answer is None:
            raise OSError(errno.EPIPE, "the recording's writer process ended")
        (error,) = ANSWER.unpack(answer)
        if error:
            raise OSError(error, os.strerror(error))


def _start_writer(fd: int) -> subprocess.Popen:
    """The writer process for the file open as ``fd`` (its own session: see the module)."""
    script = Path(__file__).with_name("write_process.py")
    writer = subprocess.Popen(
        [sys.executable, "-I", "-S", str(script), str(fd)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        pass_fds=(fd,),
        start_new_session=True,
    )
    if writer.stdin is not None:  # fewer round trips for a chunk of a few MB (Linux)
        with contextlib.suppress(OSError, AttributeError):
            fcntl.fcntl(writer.stdin.fileno(), fcntl.F_SETPIPE_SZ, 1 << 20)
    return writer


def _stop_writer(writer: subprocess.Popen) -> None:
    """Close the writer's input (it then ends) and wait for it; kill it if it hangs."""
    for pipe in (writer.stdin, writer.stdout):
        if pipe is not None:
            with contextlib.suppress(OSError):
                pipe.close()
    try:
        writer.wait(timeout=WRITER_EXIT_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        writer.kill()
        writer.wait()


def _write_all(fd: int, views: list[memoryview], offset: int | None = None) -> None:
    """``writev`` (``pwritev`` at ``offset``) until every byte of ``views`` is written."""
    done = 0
    while views:
        n = os.writev(fd, views) if offset is None else os.pwritev(fd, views, offset + done)
        done += n
        while views and n >= len(views[0]):
            n -= len(views[0])
            views.pop(0)
        if views and n:
            views[0] = views[0][n:]


def _read_exact(fd: int, n: int) -> bytes | None:
    """``n`` bytes from ``fd``, or None if it ends first."""
    data = b""
    while len(data) < n:
        block = os.read(fd, n - len(data))
        if not block:
            return None
        data += block
    return data


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM in the main thread while a write and its footer state change.

    The CLI turns both into exceptions raised wherever the main thread is
    (``Terminated``, ``KeyboardInterrupt``); raised between the merged
    footer's update and the write it describes, the next footer would name
    bytes the file does not hold (``rerun rrd verify``: corrupt manifest).
    Held, they are delivered as soon as the append is whole.  Elsewhere than
    the main thread (the write-behind thread) no signal handler runs.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
