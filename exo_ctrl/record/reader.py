"""Reading a recording back: :func:`read_recording` rebuilds the run from its file.

The file's layout is that of :mod:`.format`.  Every signal comes from the
entities that store it, bit for bit (:mod:`.stored`: the series showing
it, or ``raw/<name>`` in files of version 1); ``t`` is rebuilt as k Δt from
the ``tick`` timeline (exactly as :func:`~exo_ctrl.sim.simulate` computes
it), not from the nanosecond ``sim_time``.  A file cut short by a crash is
read up to what reached the disk (see :func:`read_recording`);
:func:`read_recording_integrity` also says how whole the file was
(:class:`RecordingIntegrity`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import struct
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from rerun.chunk import RrdReader

from .. import _validate as v
from .._io import not_a_file
from ..estimation import EstimateErrorStats
from ..exceptions import ExoCtrlError, RecordingError
from ..model import load_body
from ..sim import RunStats, SimConfig, SimResult
from ..sim.gait_score import gait_score_stats
from ..sim.load_stats import load_stats
from ..sim.plain import from_plain
from ..sim.run_models import components_from_s
from ..sim.summary import contact_stats, drive_limits
from .format import NOT_IN_OUTCOME, RECORDING_FORMAT, TICK, schema_shapes
from .meta_checks import meta_number, meta_text, outcome_fields
from .stored import assemble, scalar_rows, where_stored

__all__ = ["RecordingIntegrity", "read_recording", "read_recording_integrity"]

#: RRD stream framing (rerun 0.2x-0.41): a 12-byte file header starting with
#: b"RRF2", then messages of a 16-byte header (kind, payload length; both
#: little-endian u64) and the payload.  Kind 0 ends the stream.
_RRD_MAGIC = b"RRF2"
_RRD_FILE_HEADER = 12
_RRD_MSG_HEADER = struct.Struct("<QQ")
#: The stream footer after the end marker (rerun 0.41): where the footer is, its checksum.
_RRD_STREAM_FOOTER = 32


@dataclasses.dataclass(frozen=True)
class RecordingIntegrity:
    """How whole a recording file is, as found when reading it.

    Attributes:
        file_bytes: size of the file [bytes].
        cut_at_byte: end of the last complete message when the file's last
            message is cut short (a writer stopped mid-write, a copy cut in
            half; ``rerun rrd verify`` fails on such a file), else None.
        has_end_record: the file holds ``raw/outcome`` (the run finished and
            its end was written).
        ticks_recovered: ticks present in every signal, 0 … N-1.
        ticks_logged: ticks the run reported it logged (``raw/outcome``), or
            None without an end record.
        ticks_planned: ticks the run was configured for.

    """

    file_bytes: int
    cut_at_byte: int | None
    has_end_record: bool
    ticks_recovered: int
    ticks_logged: int | None
    ticks_planned: int

    @property
    def complete(self) -> bool:
        """The end record is there and every tick the run logged was recovered."""
        return self.has_end_record and self.ticks_recovered == self.ticks_logged

    def describe(self) -> str:
        """One line: what is missing, and how many ticks were recovered ("" if complete)."""
        if self.complete:
            return ""
        faults = []
        if self.cut_at_byte is not None:
            faults.append(f"the file is cut short at byte {self.cut_at_byte} of {self.file_bytes}")
        if not self.has_end_record:
            faults.append("it has no end record (the run or its writer stopped early)")
        if self.ticks_logged is None:
            of = f"of the {self.ticks_planned} planned"
        else:
            of = f"of the {self.ticks_logged} the run logged"
            if self.ticks_recovered != self.ticks_logged:
                faults.append("ticks are missing")
        what = " and ".join(faults)
        return f"incomplete recording: {what}; {self.ticks_recovered} ticks {of} recovered"


def read_recording(path: str | os.PathLike[str]) -> SimResult:
    """Rebuild a run's :class:`~exo_ctrl.sim.SimResult` from its recording.

    Every signal comes bit for bit (float64) from the series that show it
    (files of version 1: from ``raw/<name>``; :mod:`.stored`); a signal the
    run left out, a feature that was off (:mod:`.omitted`), is the constant
    ``raw/meta`` gives for it, so the result holds every signal the run
    logged, as it logged it.  ``t`` is ``k Δt`` for the ticks k = 0 … N-1 in
    the file.  Status, error, events,
    wall time and the other plain fields of the result come from
    ``raw/outcome``; a file without it (the process died before the run
    finished) reads as ``"interrupted"`` with the ticks that reached the disk.
    If a crash cut a chunk between signals, only the ticks present in every
    signal are kept.  Every signal of the log schema
    (:data:`exo_ctrl.sim.schema.SIGNALS`, as it is when this is called) is
    in the result: one the file lacks (written before the signal existed) is
    NaN.  The running statistics are rebuilt, so :meth:`SimResult.summary`
    matches the live run.

    Raises:
        RecordingError: the file is missing or unreadable, was not written by
            :class:`~.writer.RerunRecorder`, or its data is inconsistent.

    """
    return read_recording_integrity(path)[0]


def read_recording_integrity(path: str | os.PathLike[str]) -> tuple[SimResult, RecordingIntegrity]:
    """:func:`read_recording`, and how whole the file was.

    Raises:
        RecordingError: as :func:`read_recording`.

    """
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"cannot read recording {p}: {not_a_file(p)}")
    chunks, cut = _read_chunks(p)
    note = f"; the file was cut at byte {cut} of {p.stat().st_size}" if cut is not None else ""

    texts: dict[str, str] = {}
    raw: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}  # entity → its chunks' rows
    for chunk in chunks:
        entity = chunk.entity_path.lstrip("/")
        if not entity.startswith(("raw/", "signals/")):
            continue
        batch = chunk.to_record_batch()
        if entity in ("raw/meta", "raw/outcome"):
            if "TextDocument:text" in batch.schema.names:
                values = batch.column("TextDocument:text").to_pylist()
                if values and values[-1]:
                    texts[entity] = values[-1][-1]
            continue
        if "Scalars:scalars" in batch.schema.names and TICK in batch.schema.names:
            raw.setdefault(entity, []).append(scalar_rows(p, entity, batch))

    if "raw/meta" not in texts:
        raise RecordingError(f"cannot read recording {p}: not written by exo_ctrl (no raw/meta)")
    meta = _loads(p, "raw/meta", texts["raw/meta"])
    if not isinstance(meta, dict) or meta.get("format") != RECORDING_FORMAT:
        raise RecordingError(f"cannot read recording {p}: not an {RECORDING_FORMAT} file")
    config = _config_from_dict(p, meta.get("config", {}))
    shapes = schema_shapes()
    stored = _declared_shapes(p, meta.get("signals") or shapes, raw)
    signals = assemble(p, stored, *where_stored(p, meta, stored), raw)
    n = next(iter(signals.values())).shape[0] if signals else 0

    outcome: dict[str, Any]
    if "raw/outcome" in texts:
        outcome = _loads(p, "raw/outcome", texts["raw/outcome"])
    else:
        message = (
            f"the recording ends at t = {n * config.dt:.4f} s without an end record "
            f"(the process stopped before the run finished{note})"
        )
        outcome = {
            "status": "interrupted",
            "error": message,
            "events": [{"t": n * config.dt, "kind": "interrupted", "message": message}],
        }
    fields = {f.name for f in dataclasses.fields(SimResult)} - set(NOT_IN_OUTCOME)
    plain = {
        "belt_speed_mps": meta_number(p, meta, "belt_speed_mps", config.gait.belt_speed),
        "exo_source": meta_text(p, meta, "exo_source"),
        "patient_source": meta_text(p, meta, "patient_source"),
    }
    plain.update(outcome_fields(p, outcome, fields))
    # Every signal of the schema, in log order; one the file lacks is NaN.
    ordered = {name: signals.pop(name, None) for name in shapes}
    for name, shape in shapes.items():
        if ordered[name] is None:
            ordered[name] = np.full((n, *shape), np.nan)
    ordered.update(signals)  # and what the file holds beyond the schema
    result = SimResult(config=config, t=np.arange(n) * config.dt, signals=ordered, **plain)
    result.stats = _run_stats(config, plain["exo_source"])
    step = min(config.chunk_ticks, max(config.n_ticks, 1))  # the loop's chunks: same sums
    for start in range(0, n, step):
        result.stats.update({name: arr[start : start + step] for name, arr in ordered.items()})
    logged = outcome.get("ticks") if "raw/outcome" in texts else None
    integrity = RecordingIntegrity(
        file_bytes=p.stat().st_size,
        cut_at_byte=cut,
        has_end_record="raw/outcome" in texts,
        ticks_recovered=n,
        ticks_logged=logged if isinstance(logged, int) and not isinstance(logged, bool) else None,
        ticks_planned=int(meta_number(p, meta, "n_ticks_planned", config.n_ticks)),
    )
    return result, integrity


def _loads(p: Path, entity: str, text: str) -> Any:
    """A metadata document's JSON, its nesting checked before Python's parser recurses."""
    deep = v.json_depth_problem(text)
    if deep:
        raise RecordingError(f"cannot read recording {p}: {entity} is {deep}")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise RecordingError(f"cannot read recording {p}: {entity} is not JSON ({exc})") from None


def _declared_shapes(p: Path, declared: Any, raw: dict[str, list]) -> dict[str, tuple[int, ...]]:
    """The signals' shapes raw/meta declares, checked before any array is allocated.

    Each is a list of at most 4 integers ≥ 0; every signal at its shape for
    as many ticks as the file holds rows must fit the 1 GiB memory cap
    (:func:`exo_ctrl._validate.allocation`).
    """
    bad = f"cannot read recording {p}: raw/meta declares"
    if not isinstance(declared, dict):
        raise RecordingError(f"{bad} its signals as {type(declared).__name__}, not a mapping")
    shapes: dict[str, tuple[int, ...]] = {}
    for name, shape in declared.items():
        ok = isinstance(shape, (list, tuple)) and len(shape) <= 4
        if not (ok and all(type(x) is int and x >= 0 for x in shape)):
            raise RecordingError(
                f"{bad} signal {name!r} of shape {str(shape)[:80]}: at most 4 integers >= 0"
            )
        shapes[str(name)] = tuple(shape)
    rows = max((sum(len(t) for t, _ in parts) for parts in raw.values()), default=0)
    per_tick = sum(math.prod(shape) for shape in shapes.values())
    need = max(rows, 1) * 8 * per_tick
    if need > v.MAX_ALLOCATION_BYTES:
        raise RecordingError(
            f"{bad} signals of {per_tick:,} values a tick: {max(rows, 1):,} ticks would need "
            f"{v.format_bytes(need)}, beyond the {v.format_bytes(v.MAX_ALLOCATION_BYTES)} "
            "memory cap"
        )
    return shapes


def _run_stats(config: SimConfig, exo_source: str) -> RunStats:
    """Running statistics as simulate() keeps them, so summary() matches the live run."""
    contact = contact_stats(config)
    try:
        body = load_body(exo_source, name="exoskeleton")
        estimate = EstimateErrorStats(body, config.dt, components_from_s=components_from_s(config))
    except (ExoCtrlError, TypeError):  # the model moved, or an older layout
        estimate = None
    limits = drive_limits(config, estimate.exo.effort_limit) if estimate is not None else None
    stats = RunStats(estimate, contact, limits=limits)
    stats.fills_errors = False  # the recording holds the estimate's errors as logged
    stats.gait = gait_score_stats(config)  # the gait scores (exo_ctrl/sim/gait_score.py)
    if estimate is not None:  # the stance legs' load (exo_ctrl/sim/load_stats.py)
        stats.load = load_stats(config, estimate.exo)
    return stats


def _load_chunks(path: Path) -> list:
    with warnings.catch_warnings():
        # A file without footer (the writer died) is still readable by stream().
        warnings.filterwarnings("ignore", message=".*no footer.*")
        return RrdReader(path).stream().to_chunks()


def _read_chunks(path: Path, attempts: int = 3) -> tuple[list, int | None]:
    """All chunks of the file's recording, and where it was cut if it had to be salvaged.

    A writer stopped in the middle of a message or of the footer (see
    :mod:`.rrd_file`) leaves the file cut short, and rerun then refuses the
    whole file.  In that case the complete messages are copied to a
    temporary file and read from there.  A file still being written (the
    recorder appends to it while the run goes) can look cut and be whole a
    moment later: then it is read again.  A file whose footer alone is cut
    short reads directly (rerun reads forwards), and is reported cut too.
    """
    error: Exception | None = None
    for _ in range(attempts):
        try:  # rerun reads forwards: a footer cut short is still a cut file
            return _load_chunks(path), _complete_prefix(path)
        except (ValueError, RuntimeError, OSError) as exc:
            error = exc
        try:
            end = _complete_prefix(path)
            if end is None:
                continue  # no message is cut (any more): read the file again
            with tempfile.TemporaryDirectory() as tmp:
                copy = Path(tmp) / path.name
                with path.open("rb") as src, copy.open("wb") as dst:
                    _copy_bytes(src, dst, end)
                with contextlib.suppress(ValueError, RuntimeError, OSError):
                    return _load_chunks(copy), end
        except OSError as exc:  # gone or unreadable since (a run that failed at its start)
            raise RecordingError(f"cannot read recording {path}: {exc}") from None
    raise RecordingError(f"cannot read recording {path}: {error}") from None


def _complete_prefix(path: Path) -> int | None:
    """Length of the file's complete messages if the last one is cut short, else None.

    The end marker (the footer) counts as a message: a file cut inside it
    keeps every message before it.
    """
    size = path.stat().st_size
    with path.open("rb") as f:
        if f.read(len(_RRD_MAGIC)) != _RRD_MAGIC:
            return None
        offset = _RRD_FILE_HEADER
        while offset + _RRD_MSG_HEADER.size <= size:
            f.seek(offset)
            header = f.read(_RRD_MSG_HEADER.size)
            if len(header) < _RRD_MSG_HEADER.size:  # cut while this was reading it
                return offset
            kind, length = _RRD_MSG_HEADER.unpack(header)
            end = offset + _RRD_MSG_HEADER.size + length
            if kind == 0:  # the end marker: whole with its stream footer, or cut in it
                return offset if end + _RRD_STREAM_FOOTER > size else None
            if end > size:
                return offset
            offset += _RRD_MSG_HEADER.size + length
    return offset if offset < size else None


def _copy_bytes(src: Any, dst: Any, n: int, block: int = 1 << 20) -> None:
    while n > 0:
        data = src.read(min(block, n))
        if not data:
            break
        dst.write(data)
        n -= len(data)


def _session_sets_belt_speeds(data: dict[str, Any]) -> bool:
    """The recorded session (``asdict`` form) has a segment with a belt speed."""
    session = data.get("session")
    segments = session.get("segments") if isinstance(session, dict) else None
    return isinstance(segments, list) and any(
        isinstance(s, dict) and s.get("belt_speed_mps") is not None for s in segments
    )


def _config_from_dict(path: Path, data: Any) -> SimConfig:
    """The recorded SimConfig; a value of the wrong type is refused by its key path."""
    if not isinstance(data, dict):
        raise RecordingError(
            f"cannot read recording {path}: its config must be a table of SimConfig; "
            f"got {type(data).__name__}"
        )
    if data.get("speed_profile") is not None and _session_sets_belt_speeds(data):
        # SimConfig derives the speed profile from the session's belt speeds
        # and refuses one given beside them: the session rebuilds it.
        data = {key: value for key, value in data.items() if key != "speed_profile"}
    try:
        return from_plain(SimConfig, data, typed=True)
    except (ExoCtrlError, TypeError, ValueError) as exc:
        raise RecordingError(
            f"cannot read recording {path}: its config is invalid ({exc})"
        ) from None
