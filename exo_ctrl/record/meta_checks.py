"""The types of a recording's documents (``raw/meta``, ``raw/outcome``), checked when read.

A recording is a file anyone can write: its JSON documents are checked for
nesting and declared sizes before they are parsed
(:func:`~exo_ctrl._validate.json_depth_problem`, :mod:`.reader`), and each
value the reader uses is checked for its type here, so a hostile or damaged
document is a one-line :class:`~exo_ctrl.exceptions.RecordingError` naming
the document, the key and the value, never a traceback further on.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..exceptions import RecordingError

__all__ = ["meta_number", "meta_text", "outcome_fields"]

#: The outcome's fields by the type each must have: "text", "number" (finite
#: or NaN, as the writer stores it), "count" (an integer >= 0), "texts" (a
#: list of strings), "events" (a list of tables), "table".
OUTCOME_TYPES = {
    "status": "text",
    "error": "text",
    "safety_state": "text",
    "exo_source": "text",
    "patient_source": "text",
    "wall_time_s": "number",
    "belt_speed_mps": "number",
    "timed_ticks": "count",
    "qp_failures": "count",
    "warnings": "texts",
    "notes": "texts",
    "events": "events",
    "energy": "table",
}

#: What each type is, in the message's words.
_ALLOWED = {
    "text": "a string",
    "number": "a number",
    "count": "an integer >= 0",
    "texts": "a list of strings",
    "events": "a list of tables, each with a number t",
    "table": "a table",
}


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _fits(kind: str, value: Any) -> bool:
    """Whether ``value`` has the type ``kind`` of :data:`OUTCOME_TYPES`."""
    if kind == "text":
        return isinstance(value, str)
    if kind == "number":
        return _is_number(value)
    if kind == "count":
        return isinstance(value, int) and not isinstance(value, bool) and value >= 0
    if kind == "texts":
        return isinstance(value, list) and all(isinstance(x, str) for x in value)
    if kind == "events":
        return isinstance(value, list) and all(
            isinstance(e, dict) and _is_number(e.get("t")) for e in value
        )
    return isinstance(value, dict)


def _refuse(path: Path, document: str, key: str, allowed: str, value: Any) -> RecordingError:
    shown = repr(value)
    if len(shown) > 80:
        shown = shown[:60] + "…"
    return RecordingError(
        f"cannot read recording {path}: {document}'s {key} must be {allowed}; got {shown}"
    )


def meta_number(path: Path, meta: dict[str, Any], key: str, default: float) -> float:
    """``raw/meta``'s number ``key`` (``default`` when absent), finite or refused by name."""
    value = meta.get(key, default)
    if not _is_number(value) or not math.isfinite(value):
        raise _refuse(path, "raw/meta", key, "a finite number", value)
    return float(value)


def meta_text(path: Path, meta: dict[str, Any], key: str) -> str:
    """``raw/meta``'s text ``key`` ("" when absent), a string or refused by name."""
    value = meta.get(key, "")
    if not isinstance(value, str):
        raise _refuse(path, "raw/meta", key, "a string", value)
    return value


def outcome_fields(path: Path, outcome: Any, fields: set[str]) -> dict[str, Any]:
    """The fields of ``raw/outcome`` that :class:`~exo_ctrl.sim.SimResult` takes, type-checked.

    Args:
        path: the recording (for messages).
        outcome: the parsed document.
        fields: the result's field names read from it.

    Raises:
        RecordingError: the document is not a table, or a field has the
            wrong type (naming the key and its value).

    """
    if not isinstance(outcome, dict):
        raise RecordingError(
            f"cannot read recording {path}: raw/outcome must be a table; "
            f"got {type(outcome).__name__}"
        )
    taken = {}
    for key, value in outcome.items():
        if key not in fields:
            continue
        kind = OUTCOME_TYPES.get(key)
        if kind is not None and not _fits(kind, value):
            raise _refuse(path, "raw/outcome", key, _ALLOWED[kind], value)
        taken[key] = value
    return taken
