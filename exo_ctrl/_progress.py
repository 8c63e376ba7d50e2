"""A dependency-free progress bar on stderr."""

from __future__ import annotations

import sys
import threading
import time

__all__ = ["Progress"]


class Progress:
    """Progress bar drawn at most every 0.2 s, only after the first second.

    Args:
        total: number of units of work.
        label: what is being done.
        enabled: draw at all (off in library calls by default).

    """

    def __init__(self, total: int, label: str, enabled: bool = True) -> None:
        self.total = max(int(total), 1)
        self.label = label
        self.enabled = enabled
        self._start = time.perf_counter()
        self._base = 0
        self._last = 0.0
        self._drawn = False
        self._timer: threading.Timer | None = None

    def notice_after(self, seconds: float, text: str) -> None:
        """Write ``text`` on a line of its own if :meth:`restart` has not come within ``seconds``.

        For a start-up of unknown length (loading or compiling the kernels):
        nothing is said when it is quick.
        """
        if not self.enabled:
            return

        def say() -> None:
            sys.stderr.write(f"{self.label}: {text}\n")
            sys.stderr.flush()

        self._timer = threading.Timer(seconds, say)
        self._timer.daemon = True
        self._timer.start()

    def restart(self, done: int) -> None:
        """Start timing here, with ``done`` units behind: the ETA leaves the start-up out."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._start = time.perf_counter()
        self._base = done

    def update(self, done: int, note: str = "") -> None:
        """Report ``done`` units finished."""
        if not self.enabled:
            return
        now = time.perf_counter()
        elapsed = now - self._start
        if elapsed < 1.0 or now - self._last < 0.2:
            return
        self._last = now
        self._draw(done, elapsed, note)

    def close(self, done: int, note: str = "") -> None:
        """Draw the final state (if anything was drawn) and end the line."""
        if self._timer is not None:
            self._timer.cancel()
        if self.enabled and self._drawn:
            self._draw(done, time.perf_counter() - self._start, note)
            sys.stderr.write("\n")
            sys.stderr.flush()

    def _draw(self, done: int, elapsed: float, note: str) -> None:
        frac = min(done / self.total, 1.0)
        width = 30
        fill = int(frac * width)
        timed = (done - self._base) / max(self.total - self._base, 1)
        eta = f"{elapsed * (1 - timed) / timed:5.1f} s" if timed > 0 else "  -- s"
        extra = f" {note}" if note else ""
        sys.stderr.write(
            f"\r{self.label} [{'#' * fill}{'.' * (width - fill)}] {100 * frac:5.1f}% "
            f"{elapsed:5.1f} s elapsed, ETA {eta}{extra}  "
        )
        sys.stderr.flush()
        self._drawn = True
