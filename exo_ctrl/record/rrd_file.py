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
the default run writing about 5 MB per 2000-tick chunk (format version 1;
3 MB now) and simulating a chunk in 30-40 ms, a kill at a random moment
landed in a write 4 times in 30.  So a regular file is written by a small
process of its own (:mod:`.write_process`, in its own session): it carries
a write out only once the whole request has arrived, and completes it even
if the recording process is gone.  The bytes reach it through a buffer both
map (a memfd, on Linux), not through the pipe, which carries the request.
A SIGKILL of the recording process therefore never cuts a write (none in
30 random kills); what can still cut one is killing the
writer process itself, or the machine losing power, both of which leave
the file readable up to its last complete append.  A special file
(``/dev/null``, a FIFO) cannot be rewritten in place: it is written
directly, the messages as they come and the footer once, at
:meth:`RrdFile.close` (opened without blocking forever:
:func:`exo_ctrl._io.open_special`).

Nothing lost.  A regular file is written as ``NAME.partial.rrd`` beside
``NAME.rrd`` (:func:`exo_ctrl._io.partial_path`), locked while it is written
(:func:`exo_ctrl._io.claim_partial`: a second process writing the same path
fails at its start), and renamed over ``NAME.rrd`` by :meth:`RrdFile.close`
when the run is to be published: a previous recording at ``NAME.rrd`` stays
whole until then, and a killed run leaves it as it was beside a readable
``NAME.partial.rrd``.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import mmap
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

from .._io import claim_partial, is_special, open_special, partial_path
from ..exceptions import RecordingError
from .rrd_footer import HEADER_SIZE, Manifests, end_of_stream, split_stream
from .write_process import ANSWER, REQUEST

__all__ = ["RrdFile", "signals_held"]

#: Longest wait for the writer process to end after the file is closed [s].
WRITER_EXIT_TIMEOUT_S = 10.0


class RrdFile:
    """An ``.rrd`` file the recorder writes: whole messages, a footer after every append.

    Args:
        path: the file; a regular file is written as its partial file
            (:attr:`partial`, created or emptied, locked) and renamed over
            ``path`` by :meth:`close`; a special file is opened as it is.

    Attributes:
        partial: the file being written (None for a special file).
        written: where the recording is: :attr:`partial` until it is
            renamed over ``path``, then ``path``.

    Raises:
        OSError: the file cannot be opened; ``EBUSY`` when another process
            is writing the same path.

    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.special = is_special(self.path)
        self.partial: Path | None = None if self.special else partial_path(self.path)
        self._fd: int | None = open_special(self.path) if self.special else claim_partial(path)
        self.written: Path = self.partial or self.path
        self._writer: subprocess.Popen | None = None
        self._shared: _Shared | None = None
        if not self.special:
            with contextlib.suppress(OSError, AttributeError):  # not Linux: through the pipe
                self._shared = _Shared()
            with contextlib.suppress(OSError):  # no interpreter to run it: write in place here
                self._writer = _start_writer(self._fd, self._shared)
        self._header: bytes | None = None
        self._end = 0  # end of the messages written so far
        self._tail = b""  # the footer at _end, as last written
        self._manifests = Manifests()
        self._awaiting = False  # a request was sent, its answer not yet read
        self._pending: tuple[bytes, int, bytes] | None = None  # header, end, tail once written

    def reserve(self, size: int) -> None:
        """Make room ahead for appends of up to ``size`` bytes (the writer's shared buffer)."""
        if self._shared is not None:
            self._shared.reserve(size)

    @property
    def bytes_written(self) -> int:
        """Bytes of messages in the file (the footer not counted)."""
        return self._end

    def append(self, data: bytes | None, wait: bool = True) -> None:
        """Write the messages of one complete RRD stream, then the footer of the whole file.

        After a failed append the file is to be closed (:meth:`abandon`),
        not appended to again: the merged footer already holds that stream.

        Args:
            data: the stream (rerun's encoding since the last append).
            wait: wait for the writer process's answer; with False, return
                once the request is handed over (the write then completes
                whatever happens to this process) and let :meth:`wait`
                read the answer, in another thread (the write-behind
                thread then takes the interpreter lock once less: each time
                it takes it back from a busy loop cost that loop 1-3 ms
                here, on a loaded machine).

        Raises:
            OSError: writing failed (disk full); a regular file is then put
                back as it was before the call (every earlier append, whole,
                with its footer).
            RecordingError: the stream's layout is unknown (another rerun).

        """
        if not data:
            return
        with signals_held():
            self._append(data, wait)

    def wait(self) -> None:
        """Wait for the answer to the last append's write, if it was not waited for.

        Raises:
            OSError: that write failed; the file is put back as it was before it.

        """
        if not self._awaiting:
            return
        with signals_held():
            try:
                self._answer()
            except OSError:
                self._pending = None
                self._restore()
                raise
            self._commit()

    def _append(self, data: bytes, wait: bool) -> None:
        """:meth:`append` with SIGINT and SIGTERM held (the footer's state and the file agree)."""
        self.wait()  # the previous write's answer first (one request at a time)
        parts = split_stream(data)
        if self._header is not None and parts.header != self._header:
            raise RecordingError("rerun changed its stream header between two chunks")
        head = parts.header if self._header is None else b""  # the file's header, once
        base = self._end if self._header is not None else HEADER_SIZE
        self._manifests.add(parts.footer, base - HEADER_SIZE)
        start, end = base - len(head), base + len(parts.body)
        tail = b"" if self.special else end_of_stream(self._manifests.encode(), end)
        self._pending = (parts.header, end, tail)
        try:
            self._write([head, parts.body, tail], start, wait)
        except OSError:
            self._pending = None
            self._restore()
            raise
        if not self._awaiting:
            self._commit()

    def _commit(self) -> None:
        """The pending append is on disk: the file's state follows."""
        if self._pending is not None:
            header, end, tail = self._pending
            self._pending = None
            self._header = self._header or header
            self._end, self._tail = end, tail

    def close(self, publish: bool = True) -> None:
        """Finish the file (a special file gets its footer now) and close it; idempotent.

        Args:
            publish: rename the partial file over the path (else it stays,
                whole, as :attr:`partial`: an interrupted run).  The rename
                comes before the lock is released.

        Raises:
            OSError: writing the footer or renaming failed.

        """
        if self._fd is None:
            return
        try:
            self.wait()
            if self.special and self._header is not None:
                self._write([end_of_stream(self._manifests.encode(), self._end)], self._end)
            elif publish and self.partial is not None:
                os.replace(self.partial, self.path)
                self.written = self.path
        finally:
            self.abandon()

    def abandon(self) -> None:
        """Close the file without writing anything more (after a failed write).

        A partial file left empty (nothing was written) is removed.
        """
        fd, self._fd = self._fd, None
        writer, self._writer = self._writer, None
        if writer is not None:
            _stop_writer(writer)
        shared, self._shared = self._shared, None
        if shared is not None:
            shared.close()
        if fd is not None and self.partial is not None and self.written == self.partial:
            with contextlib.suppress(OSError):
                st = os.fstat(fd)
                if st.st_size == 0 and os.path.samestat(st, os.lstat(self.partial)):
                    os.unlink(self.partial)
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

    def _write(self, pieces: list, offset: int, wait: bool = True) -> None:
        """Write ``pieces`` (bytes-like) one after the other at ``offset``.

        A regular file is first cut at ``offset`` (the old footer goes), then
        written, by the writer process (module docstring; ``wait``: for its
        answer, else :meth:`wait` reads it), or here if it could not be
        started (no interpreter at ``sys.executable``: then a kill of this
        process during the write can cut it); a special file is written
        here, in one ``writev``.
        """
        if self._fd is None:
            raise RecordingError(f"recording {self.path} is closed")
        if self._awaiting:  # one request at a time: the shared buffer is the writer's till then
            self._answer()
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
        shared = self._shared is not None and self._shared.fill(views, total)
        if shared:  # the bytes are in the shared buffer, not in the pipe
            views = []
        try:
            _write_all(stdin.fileno(), [memoryview(REQUEST.pack(offset, total, shared)), *views])
        except BrokenPipeError:
            raise OSError(errno.EPIPE, "the recording's writer process ended") from None
        self._awaiting = True
        if wait:
            self._answer()

    def _answer(self) -> None:
        """Read the writer process's answer to the request sent last.

        Raises:
            OSError: the write failed (its errno), or the writer process ended.

        """
        self._awaiting = False
        stdout = self._writer.stdout if self._writer is not None else None
        answer = _read_exact(stdout.fileno(), ANSWER.size) if stdout is not None else None
        if answer is None:
            raise OSError(errno.EPIPE, "the recording's writer process ended")
        (error,) = ANSWER.unpack(answer)
        if error:
            raise OSError(error, os.strerror(error))


class _Shared:
    """The buffer the writer process reads a request's bytes from: a memfd both map.

    It grows to the largest request (a quarter more, whole pages; or ahead,
    :meth:`reserve`); it is filled only while the writer process waits for a
    request (the protocol is one request, one answer), so the two never
    touch it at once.

    Raises:
        OSError, AttributeError: no memfd (not Linux).

    """

    def __init__(self) -> None:
        self.fd = os.memfd_create("exo-ctrl-rrd", os.MFD_CLOEXEC)
        self._map: mmap.mmap | None = None

    def reserve(self, total: int) -> bool:
        """Grow the buffer to hold ``total`` bytes and a quarter more, its pages touched.

        False if it cannot grow (the file-size limit, ``RLIMIT_FSIZE``, holds
        for it too).  New pages cost a fault each on first touch (2-3 ms for
        the 3 MB of a default chunk here): touched ahead, before the run.
        """
        if self._map is not None and len(self._map) >= total:
            return True
        size = -(-(total + total // 4) // mmap.PAGESIZE) * mmap.PAGESIZE
        try:
            os.ftruncate(self.fd, size)
            grown = mmap.mmap(self.fd, size)
        except OSError:
            return False
        if self._map is not None:
            self._map.close()
        self._map = grown
        grown[:: mmap.PAGESIZE] = bytes(size // mmap.PAGESIZE)
        return True

    def fill(self, views: list[memoryview], total: int) -> bool:
        """Copy ``views``, one after the other, to the buffer's start (``total`` bytes).

        Returns False, the buffer unchanged, if it cannot grow to ``total``
        (the file-size limit, ``RLIMIT_FSIZE``, holds for it too): the bytes
        then go through the pipe.
        """
        if not self.reserve(total) or self._map is None:
            return False
        at = 0
        for view in views:
            self._map[at : at + len(view)] = view
            at += len(view)
        return True

    def close(self) -> None:
        if self._map is not None:
            self._map.close()
            self._map = None
        with contextlib.suppress(OSError):
            os.close(self.fd)


def _start_writer(fd: int, shared: _Shared | None = None) -> subprocess.Popen:
    """The writer process for the file open as ``fd`` (its own session: see the module)."""
    script = Path(__file__).with_name("write_process.py")
    fds = (fd,) if shared is None else (fd, shared.fd)
    writer = subprocess.Popen(
        [sys.executable, "-I", "-S", str(script), *map(str, fds)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        pass_fds=fds,
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
