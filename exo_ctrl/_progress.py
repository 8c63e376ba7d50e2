"""A dependency-free progress bar on stderr."""

from __future__ import annotations

import sys
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
        self._last = 0.0
        self._drawn = False

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
        if self.enabled and self._drawn:
            self._draw(done, time.perf_counter() - self._start, note)
            sys.stderr.write("\n")
            sys.stderr.flush()

    def _draw(self, done: int, elapsed: float, note: str) -> None:
        frac = min(done / self.total, 1.0)
        width = 30
        fill = int(frac * width)
        eta = f"{elapsed * (1 - frac) / frac:5.1f} s" if frac > 0 else "  -- s"
        extra = f" {note}" if note else ""
        sys.stderr.write(
            f"\r{self.label} [{'#' * fill}{'.' * (width - fill)}] {100 * frac:5.1f}% "
            f"{elapsed:5.1f} s elapsed, ETA {eta}{extra}  "
        )
        sys.stderr.flush()
        self._drawn = True
