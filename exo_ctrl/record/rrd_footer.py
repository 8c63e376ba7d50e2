"""Rerun's RRD stream framing and footer, as far as the recorder writes them itself.

Layout of an RRD stream (rerun 0.41; :func:`split_stream` checks each piece
and refuses a stream it does not know)::

    header        12 B: b"RRF2", version, options
    message       16 B header (kind, payload length; little-endian u64) + payload
    ...
    end message   kind 0; its payload is the RrdFooter (protobuf)
    stream footer 32 B: footer offset, footer length (u64), xxh32 of the
                  footer (seed 7850921, u32), b"RRF2FOOT", entries (u32 = 1)

The RrdFooter holds one RrdManifest per store (the recording, its
blueprint): the store id, the store's Sorbet schema (Arrow IPC), the
schema's SHA-256, and a table with one row per chunk (id, entity, byte
offset and size in the file, time ranges per timeline and component),
LZ4-compressed Arrow IPC.  :class:`Manifests` merges the manifests of
several streams whose messages are written one after the other into one
file: their rows with the byte offsets moved to where the messages now
sit, the union of their columns (a column a part lacks is ``false`` for
``…:has_static_data``, 0 for ``…:num_rows``, null otherwise, as rerun fills
them; in rerun's column order) and of their schemas.  For the same data the
result equals the footer rerun's own file sink writes, but for chunk ids,
byte offsets and the wall-clock ``log_time`` (tests/record/test_rrd_file.py).
The schema's SHA-256 is rerun's own value when the merged schema is that
of one stream; otherwise it is computed the way rerun defines it (SHA-256
of the schema with its fields sorted by name and without top-level
metadata, as Arrow IPC) with pyarrow's IPC writer, whose bytes may differ
from the arrow-rs bytes rerun hashes.  Rerun 0.41 does not check this hash
when reading (``rerun rrd verify``, ``RrdReader``); nothing here relies on it.
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from .._jit import kernel
from ..exceptions import RecordingError

__all__ = [
    "CRC_SEED",
    "HEADER_SIZE",
    "Manifests",
    "StreamParts",
    "end_of_stream",
    "split_stream",
    "xxh32",
]


_MAGIC = b"RRF2"
#: Size of the stream header [B].
HEADER_SIZE = _HEADER = 12
_MSG = struct.Struct("<QQ")
_END = 0
#: Stream footer: footer offset, footer length, xxh32; then b"RRF2FOOT" and the entry count.
_TRAILER = struct.Struct("<QQI")
_TRAILER_TAIL = b"RRF2FOOT" + struct.pack("<I", 1)
_TRAILER_SIZE = _TRAILER.size + len(_TRAILER_TAIL)
#: Seed of the stream footer's xxh32 ("RERUN" in base 26), rerun's StreamFooter::CRC_SEED.
CRC_SEED = 7850921
#: RrdManifest fields (protobuf numbers, rerun's log_msg.proto).
_M_STORE, _M_SCHEMA, _M_SHA, _M_DATA = 1, 2, 3, 4
#: DataframePart fields: encoder version, payload, compression, uncompressed size.
_D_VERSION, _D_PAYLOAD, _D_COMPRESSION, _D_SIZE = 1, 2, 3, 4
_LZ4 = 2

#: XXH32's five primes and its 32-bit mask (the xxHash specification, Y. Collet).
_P1, _P2, _P3, _P4, _P5 = 2654435761, 2246822519, 3266489917, 668265263, 374761393
_MASK = 0xFFFFFFFF


# --------------------------------------------------------------------------- xxh32


@kernel
def _xxh32_kernel(data, words, seed):  # pragma: no cover - compiled
    """xxHash32 of ``data`` (uint8); ``words`` is its first 4·⌊n/4⌋ bytes as little-endian u32."""
    p1, p2, p3, p4, p5 = (np.uint64(_P1), np.uint64(_P2), np.uint64(_P3), np.uint64(_P4),
                          np.uint64(_P5))  # fmt: skip
    m = np.uint64(_MASK)
    n = data.shape[0]
    s = np.uint64(seed)
    i = 0
    if n >= 16:
        v = np.empty(4, dtype=np.uint64)
        v[0] = (s + p1 + p2) & m
        v[1] = (s + p2) & m
        v[2] = s
        v[3] = (s - p1) & m
        while i + 16 <= n:
            for lane in range(4):
                acc = (v[lane] + np.uint64(words[i // 4 + lane]) * p2) & m
                acc = ((acc << np.uint64(13)) | (acc >> np.uint64(19))) & m
                v[lane] = (acc * p1) & m
            i += 16
        h = np.uint64(0)
        for lane in range(4):
            r = np.uint64((1, 7, 12, 18)[lane])
            x = v[lane]
            h = (h + (((x << r) | (x >> (np.uint64(32) - r))) & m)) & m
    else:
        h = (s + p5) & m
    h = (h + np.uint64(n)) & m
    while i + 4 <= n:
        h = (h + np.uint64(words[i // 4]) * p3) & m
        h = (((h << np.uint64(17)) | (h >> np.uint64(15))) & m) * p4 & m
        i += 4
    while i < n:
        h = (h + np.uint64(data[i]) * p5) & m
        h = (((h << np.uint64(11)) | (h >> np.uint64(21))) & m) * p1 & m
        i += 1
    h ^= h >> np.uint64(15)
    h = (h * p2) & m
    h ^= h >> np.uint64(13)
    h = (h * p3) & m
    h ^= h >> np.uint64(16)
    return h


def xxh32(data: bytes, seed: int = 0) -> int:
    """xxHash32 of ``data`` with ``seed`` (the stream footer's checksum)."""
    raw = np.frombuffer(data, dtype=np.uint8)
    words = raw[: raw.shape[0] // 4 * 4].view("<u4")
    return int(_xxh32_kernel(raw, words, np.uint32(seed)))


# --------------------------------------------------------------------------- protobuf


def _varint(buf: bytes, i: int) -> tuple[int, int]:
    value, shift = 0, 0
    while True:
        byte = buf[i]
        i += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, i


def _pb_fields(buf: bytes) -> list[tuple[int, int | bytes]]:
    """(field number, value) of a protobuf message: varints as int, length-delimited as bytes."""
    out: list[tuple[int, int | bytes]] = []
    i = 0
    while i < len(buf):
        key, i = _varint(buf, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = _varint(buf, i)
            out.append((number, value))
        elif wire == 2:
            size, i = _varint(buf, i)
            out.append((number, buf[i : i + size]))
            i += size
        else:  # not used by the footer messages
            raise RecordingError(f"unexpected protobuf wire type {wire} in rerun's footer")
    return out


def _pb_varint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte, value = value & 0x7F, value >> 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def _pb(number: int, value: int | bytes) -> bytes:
    """One protobuf field: a varint (int) or length-delimited (bytes)."""
    if isinstance(value, int):
        return _pb_varint(number << 3) + _pb_varint(value)
    return _pb_varint(number << 3 | 2) + _pb_varint(len(value)) + value


# --------------------------------------------------------------------------- streams


@dataclass(frozen=True)
class StreamParts:
    """A complete RRD stream cut into its pieces.

    Attributes:
        header: the 12-byte stream header.
        body: every message before the end marker (headers and payloads), a
            view of the stream's bytes (not a copy).
        footer: the end marker's payload (an RrdFooter, protobuf).

    """

    header: bytes
    body: memoryview
    footer: bytes


def split_stream(data: bytes) -> StreamParts:
    """Cut one complete RRD stream (what rerun's BinaryStream returns) into its pieces.

    Raises:
        RecordingError: the bytes are not the one-stream layout of the
            module docstring (another rerun-sdk version's framing).

    """

    def refuse(why: str) -> RecordingError:
        return RecordingError(f"rerun's encoded stream has an unknown layout: {why}")

    if len(data) < _HEADER or data[:4] != _MAGIC:
        raise refuse("no RRF2 stream header")
    offset = _HEADER
    while True:
        if offset + _MSG.size > len(data):
            raise refuse("no end marker")
        kind, length = _MSG.unpack_from(data, offset)
        if kind == _END:
            break
        offset += _MSG.size + length
    start = offset + _MSG.size
    footer = data[start : start + length]
    trailer = data[start + length :]
    if len(footer) != length or len(trailer) != _TRAILER_SIZE:
        raise refuse(f"{len(trailer)} bytes after the footer, not {_TRAILER_SIZE}")
    at, size, crc = _TRAILER.unpack_from(trailer)
    if trailer[_TRAILER.size :] != _TRAILER_TAIL or (at, size) != (start, length):
        raise refuse("the stream footer does not point at the end marker's payload")
    if crc != xxh32(footer, CRC_SEED):
        raise refuse("the footer's checksum is not xxh32 with rerun's seed")
    return StreamParts(data[:_HEADER], memoryview(data)[_HEADER:offset], footer)


# --------------------------------------------------------------------------- manifests


_SUFFIXES = {"start": 0, "end": 1, "num_rows": 2}


def _column_key(name: str) -> tuple:
    """Sort key of a manifest column, in rerun's order.

    The chunk columns, ``…:has_static_data`` by name, the timelines'
    ``…:start``/``…:end``, then per timeline and component.
    """
    head, _, suffix = name.rpartition(":")
    if not head:
        return (0,)
    if suffix == "has_static_data":
        return (1, head)
    index, _, component = head.partition(":")
    return (3 if component else 2, index, component, _SUFFIXES.get(suffix, 3), suffix)


def _fill(name: str, field_: pa.Field, rows: int) -> pa.Array:
    """The values of a manifest column for rows of chunks that do not have it."""
    if name.endswith(":has_static_data"):
        return pa.array(np.zeros(rows, dtype=bool), type=field_.type)
    if name.endswith(":num_rows"):
        return pa.array(np.zeros(rows, dtype=np.uint64), type=field_.type)
    return pa.nulls(rows, type=field_.type)


@dataclass
class _Store:
    """The merged manifest of one store (recording or blueprint)."""

    store_id: bytes
    encoder_version: int
    fields: dict[str, pa.Field] = field(default_factory=dict)
    metadata: dict[bytes, bytes] | None = None
    columns: dict[str, pa.Field] = field(default_factory=dict)
    parts: list[pa.Table] = field(default_factory=list)
    known_sha: dict[frozenset[str], bytes] = field(default_factory=dict)
    #: The encoded schema message with its hash, and the whole manifest, as last encoded.
    _schema: bytes = b""
    _encoded: bytes = b""

    def add(self, schema: pa.Schema, sha: bytes | None, table: pa.Table) -> None:
        if any(f.name not in self.fields for f in schema):
            self._schema = b""
        for f in schema:
            self.fields.setdefault(f.name, f)
        if self.metadata is None:
            self.metadata = schema.metadata
        if sha is not None:
            self.known_sha[frozenset(schema.names)] = sha
        if any(name not in self.columns for name in table.schema.names):
            merged = {**self.columns, **{f.name: f for f in table.schema}}
            order = sorted(merged, key=lambda n: (_column_key(n), list(merged).index(n)))
            self.columns = {n: self.columns.get(n, merged[n]) for n in order}
        self.parts.append(table)
        self._encoded = b""

    def encode(self) -> bytes:
        """The store's RrdManifest (protobuf)."""
        if not self._encoded:
            self._encoded = _pb(_M_STORE, self.store_id) + self._schema_fields() + self._data()
        return self._encoded

    def _schema_fields(self) -> bytes:
        """The Sorbet schema and its SHA-256, as RrdManifest fields."""
        if not self._schema:
            schema = pa.schema(list(self.fields.values()), metadata=self.metadata)
            sha = self.known_sha.get(frozenset(self.fields))
            if sha is None:
                bare = pa.schema(sorted(schema, key=lambda f: f.name))
                sha = hashlib.sha256(bare.serialize().to_pybytes()).digest()
            self._schema = _pb(_M_SCHEMA, _pb(1, schema.serialize().to_pybytes())) + _pb(
                _M_SHA, sha
            )
        return self._schema

    def _data(self) -> bytes:
        """One row per chunk of every part, as the RrdManifest's data field."""
        columns = self.columns
        for i, part in enumerate(self.parts):  # bring every part to the merged columns
            if part.schema.names != list(columns):
                arrays = [
                    part.column(name) if name in part.schema.names else _fill(name, f, len(part))
                    for name, f in columns.items()
                ]
                merged = pa.schema(list(columns.values()))
                self.parts[i] = pa.Table.from_arrays(arrays, schema=merged)
        table = pa.concat_tables(self.parts).combine_chunks()
        self.parts = [table]
        sink = pa.BufferOutputStream()
        with pa.ipc.new_stream(sink, table.schema) as ipc:
            ipc.write_table(table)
        data = sink.getvalue()
        packed = pa.compress(data, codec="lz4_raw", asbytes=True)
        part = (
            _pb(_D_VERSION, self.encoder_version)
            + _pb(_D_PAYLOAD, packed)
            + _pb(_D_COMPRESSION, _LZ4)
            + _pb(_D_SIZE, data.size)
        )
        return _pb(_M_DATA, part)


def _blob(fields: dict[int, int | bytes], number: int) -> bytes:
    """Length-delimited field ``number`` of a decoded message."""
    value = fields.get(number)
    if not isinstance(value, bytes):
        raise RecordingError(f"rerun's footer lacks field {number} where this writer expects it")
    return value


class Manifests:
    """The manifests of every store, merged over the appended streams (module docstring)."""

    def __init__(self) -> None:
        self._stores: dict[bytes, _Store] = {}

    def add(self, footer: bytes, shift: int) -> None:
        """Merge a stream's RrdFooter whose messages now sit ``shift`` bytes further on."""
        for number, manifest in _pb_fields(footer):
            if number != 1 or not isinstance(manifest, bytes):
                continue
            parts = dict(_pb_fields(manifest))
            store_id, sha = _blob(parts, _M_STORE), parts.get(_M_SHA)
            schema_ipc = _blob(dict(_pb_fields(_blob(parts, _M_SCHEMA))), 1)
            schema = pa.ipc.read_schema(pa.py_buffer(schema_ipc))
            frame = dict(_pb_fields(_blob(parts, _M_DATA)))
            size = frame.get(_D_SIZE)
            if frame.get(_D_COMPRESSION) != _LZ4 or not isinstance(size, int):
                raise RecordingError("rerun's footer is not LZ4-compressed as expected")
            raw = pa.decompress(_blob(frame, _D_PAYLOAD), decompressed_size=size, codec="lz4_raw")
            table = pa.ipc.open_stream(raw).read_all()
            at = table.schema.get_field_index("chunk_byte_offset")
            moved = pc.add(table.column(at), pa.scalar(shift, type=pa.uint64()))
            table = table.set_column(at, table.schema.field(at), moved)
            store = self._stores.get(store_id)
            if store is None:
                store = self._stores[store_id] = _Store(store_id, int(frame.get(_D_VERSION, 1)))
            store.add(schema, sha if isinstance(sha, bytes) else None, table)

    def encode(self) -> bytes:
        """The RrdFooter of every store (protobuf)."""
        return b"".join(_pb(1, store.encode()) for store in self._stores.values())


def end_of_stream(footer: bytes, messages_end: int) -> bytes:
    """The end marker holding ``footer``, then the stream footer pointing at it.

    ``messages_end`` is where the messages before it end, in the stream [B].
    """
    start = messages_end + _MSG.size
    crc = xxh32(footer, CRC_SEED)
    return (
        _MSG.pack(_END, len(footer))
        + footer
        + _TRAILER.pack(start, len(footer), crc)
        + _TRAILER_TAIL
    )
