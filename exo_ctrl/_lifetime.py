"""A child process that ends with its parent (sweep workers, the first run's compile helper).

A child that holds pipes of its own is not ended by its parent's death
(SIGKILL included).  On Linux the kernel sends it SIGKILL when the parent
exits (``prctl(PR_SET_PDEATHSIG)``); everywhere a daemon thread ends it once
its parent is no longer the one it was started by (also if that was before
this ran).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time

__all__ = ["die_with_parent"]

_PR_SET_PDEATHSIG = 1  # prctl(2) option: the signal a process gets when its parent dies
_PARENT_POLL_S = 0.5  # how often the child checks that its parent is alive [s]


def die_with_parent(parent_pid: int) -> None:
    """End this process when its parent, ``parent_pid``, ends (module docstring)."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True).start()


def _watch_parent(parent_pid: int) -> None:
    """End this process at once when its parent is no longer ``parent_pid``."""
    while os.getppid() == parent_pid:
        time.sleep(_PARENT_POLL_S)
    os._exit(1)
