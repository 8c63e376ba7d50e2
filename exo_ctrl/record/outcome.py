"""The end of a recording: the run's events, its final status and its outcome document.

Logged once the run has ended (:meth:`~.writer.RerunRecorder.finish`): the
per-cycle biofeedback figures (:mod:`.biofeedback`), every event of the run
and a line with its status under ``events`` (a TextLog at the event's time,
on both timelines), and ``raw/outcome``, the JSON of the result's plain
fields that :func:`~.reader.read_recording` reads back.
"""

from __future__ import annotations

import dataclasses
import math

import rerun as rr

from ..sim import SimResult
from .biofeedback import log_biofeedback
from .format import NOT_IN_OUTCOME, TICK, TIME, dumps

__all__ = ["log_outcome"]

#: TextLog level of an event or final status by kind.
_LEVELS = {
    "completed": "INFO",
    "diverged": "ERROR",
    "interrupted": "WARN",
    "error": "ERROR",
    "violation": "WARN",
    "estop": "WARN",
    "warning": "WARN",
    "state": "INFO",
}


def log_outcome(rec: rr.RecordingStream, result: SimResult, ticks: int, dt: float) -> None:
    """Log the end of a run of which ``ticks`` ticks were recorded (Δt = ``dt`` [s])."""
    log_biofeedback(rec, result)  # the per-cycle figures (exo_ctrl/record/biofeedback.py)
    events = [dict(ev) for ev in result.events]
    for ev in events:
        kind = str(ev.get("kind", "event"))
        t = ev.get("t")
        if not (isinstance(t, (int, float)) and math.isfinite(t)):
            t = ticks * dt
        text = f"{kind}: {ev.get('message', '')}"
        _log_event(rec, t, dt, text, str(ev.get("level", _LEVELS.get(kind, "INFO"))))
    text = f"run {result.status}: {ticks} of {result.config.n_ticks} ticks recorded"
    text += f", t = {ticks * dt:.4f} s" + (f"; {result.error}" if result.error else "")
    _log_event(rec, ticks * dt, dt, text, _LEVELS.get(result.status, "ERROR"))
    outcome = {
        f.name: getattr(result, f.name)
        for f in dataclasses.fields(result)
        if f.name not in NOT_IN_OUTCOME
    }
    outcome.update(events=events, ticks=ticks)
    document = rr.TextDocument(dumps(outcome), media_type=rr.MediaType.TEXT)
    rec.log("raw/outcome", document, static=True, strict=True)


def _log_event(rec: rr.RecordingStream, t: float, dt: float, text: str, level: str) -> None:
    rec.set_time(TIME, duration=t)
    rec.set_time(TICK, sequence=max(0, round(t / dt)))
    rec.log("events", rr.TextLog(text, level=level), strict=True)
