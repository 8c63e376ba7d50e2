"""The process that writes a recording's file for :class:`~.rrd_file.RrdFile`.

Run as a script by its own interpreter (``python -I -S write_process.py
FD``, standard library only, so it starts in milliseconds), with the file
open as descriptor FD.  It reads requests from its standard input and
answers each on its standard output:

    request   u64 offset, u64 length (little-endian), then ``length`` bytes
    action    cut the file at ``offset``, write the bytes there
    answer    i32: 0, or the errno of the failed call

A request is carried out only once all its bytes have arrived: if the
recording process dies in the middle of sending one (SIGKILL), the write
never starts, and once a request has arrived this process completes it
even if the recording process is gone.  So a kill of the recording process
never leaves a write cut short.  It ends when its standard input ends
(the recording process closed the file, or died); it ignores SIGINT and
SIGTERM, which a terminal or ``kill`` sends to the whole process group,
so that the recording process can finish the file after Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import os
import signal
import struct
import sys

__all__ = ["ANSWER", "REQUEST", "main"]

#: A request's header: file offset, length of the bytes that follow.
REQUEST = struct.Struct("<QQ")
#: The answer: 0 or an errno.
ANSWER = struct.Struct("<i")


def _read_exact(fd: int, n: int) -> bytearray | None:
    """``n`` bytes from ``fd`` (read in place, no copy), or None if it ends first."""
    data = bytearray(n)
    view, got = memoryview(data), 0
    while got < n:
        read = os.readv(fd, [view[got:]])
        if not read:
            return None
        got += read
    return data


def main(argv: list[str]) -> int:
    """Serve requests on stdin for the file open as descriptor ``argv[1]``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    fd = int(argv[1])
    while True:
        header = _read_exact(0, REQUEST.size)
        if header is None:
            return 0
        offset, length = REQUEST.unpack(header)
        data = _read_exact(0, length)
        if data is None:
            return 0  # the recording process died while sending: nothing written
        error = 0
        try:
            os.ftruncate(fd, offset)
            view, done = memoryview(data), 0
            while done < length:
                done += os.pwrite(fd, view[done:], offset + done)
        except OSError as exc:
            error = exc.errno or -1
        try:
            os.write(1, ANSWER.pack(error))
        except OSError:
            return 0  # nobody is listening any more


if __name__ == "__main__":
    sys.exit(main(sys.argv))
