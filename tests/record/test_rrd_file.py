"""Tests of exo_ctrl.record.rrd_file: the file the recorder writes from rerun's encoding.

The reference is rerun itself: the same data written by rerun's own file
sink (``RecordingStream.save``) must give the same footer (schema, manifest
columns, one row per chunk with the same contents) as the file
:class:`RrdFile` writes from rerun's in-memory stream, and every
intermediate file must pass ``rerun rrd verify`` and read back through
rerun's ``RrdReader`` (which jumps to the footer).
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from exo_ctrl.exceptions import RecordingError
from exo_ctrl.record.rrd_file import RrdFile
from exo_ctrl.record.rrd_footer import CRC_SEED, _pb_fields, split_stream, xxh32

#: Manifest columns that differ between two writes of the same data: ids, places, wall time.
VARYING = ("chunk_id", "chunk_byte_offset", "chunk_byte_size", "chunk_byte_size_uncompressed")


def test_xxh32_matches_the_published_test_vectors():
    # xxHash's reference values (seed 0), and the lengths around the 16-byte stripes.
    assert xxh32(b"", 0) == 0x02CC5D05
    assert xxh32(b"a", 0) == 0x550D7456
    assert xxh32(b"abc", 0) == 0x32D153FF
    assert xxh32(b"Nobody inspects the spammish repetition", 0) == 0xE2293B2F
    assert xxh32(b"", 1) != xxh32(b"", 0)


def _log_part(rec: rr.RecordingStream, part: int) -> None:
    """Part 0: static data; then temporal scalars and points; part 3 adds a text log."""
    if part == 0:
        rec.log("params", rr.TextDocument("# run"), static=True)
        rec.log("signals/a", rr.SeriesLines(names=["x", "y"]), static=True)
        return
    n, t0 = 50, 50 * (part - 1)
    ticks = rr.TimeColumn("tick", sequence=np.arange(t0, t0 + n))
    times = rr.TimeColumn("sim_time", duration=np.arange(t0, t0 + n) * 1e-3)
    values = np.arange(2 * n, dtype=float).reshape(n, 2) + part
    rec.send_columns(
        "signals/a", indexes=[ticks, times], columns=rr.Scalars.columns(scalars=values)
    )
    rec.set_time("tick", sequence=t0)
    rec.log("world/p", rr.Points3D([[part, 0.0, 0.0]]))
    if part == 3:
        rec.log("events", rr.TextLog("done", level="INFO"))


def _footer(path: Path) -> dict[str, tuple[pa.Schema, pa.Table]]:
    """The file's manifests by store kind: (Sorbet schema, manifest table)."""
    data = path.read_bytes()
    offset, size, crc = struct.unpack_from("<QQI", data, len(data) - 32)
    assert data[-12:] == b"RRF2FOOT" + struct.pack("<I", 1)
    assert crc == xxh32(data[offset : offset + size], CRC_SEED)  # rerun's checksum too
    out = {}
    for _, manifest in _pb_fields(data[offset : offset + size]):
        fields = dict(_pb_fields(manifest))
        schema = pa.ipc.read_schema(pa.py_buffer(dict(_pb_fields(fields[2]))[1]))
        frame = dict(_pb_fields(fields[4]))
        raw = pa.decompress(frame[2], decompressed_size=frame[4], codec="lz4_raw")
        table = pa.ipc.open_stream(raw).read_all()
        entities = table.column("chunk_entity_path").to_pylist()
        kind = "blueprint" if any(e.startswith("/viewport") for e in entities) else "recording"
        out[kind] = (schema, table)
    return out


def _rows(table: pa.Table) -> list[tuple]:
    """The manifest's rows without the columns that vary between writes, sorted."""
    keep = [c for c in table.schema.names if c not in VARYING]
    rows = []
    for i in range(table.num_rows):
        rows.append(tuple((c, str(table.column(c)[i])) for c in keep))
    return sorted(rows)


def _two_writes(tmp_path: Path) -> tuple[Path, Path, list[int]]:
    """The same four parts through rerun's file sink and through RrdFile; sizes after each."""
    own = tmp_path / "rerun.rrd"
    rec = rr.RecordingStream("exo_ctrl_test", recording_id="same")
    rec.save(own)
    for part in range(4):
        _log_part(rec, part)
        rec.flush()
    rec.disconnect()

    ours = tmp_path / "ours.rrd"
    rec = rr.RecordingStream("exo_ctrl_test", recording_id="same")
    stream = rr.binary_stream(recording=rec)
    rec.set_sinks(stream)
    file = RrdFile(ours)
    sizes = []
    for part in range(4):
        _log_part(rec, part)
        file.append(stream.read(flush=True))
        assert file.written == tmp_path / "ours.partial.rrd"  # renamed over ours at close
        sizes.append(file.written.stat().st_size)
        assert _verify(file.written) == 0, f"not a whole file after part {part}"
    file.close()
    assert file.written == ours and not (tmp_path / "ours.partial.rrd").exists()
    rec.disconnect()
    return own, ours, sizes


def _verify(path: Path) -> int:
    rerun = Path(sys.executable).with_name("rerun")
    return subprocess.run([str(rerun), "rrd", "verify", str(path)], capture_output=True).returncode


def test_the_merged_footer_is_the_one_rerun_writes(tmp_path):
    own, ours, _ = _two_writes(tmp_path)
    (s_own, t_own), (s_ours, t_ours) = _footer(own)["recording"], _footer(ours)["recording"]
    # The recording's schema: the same fields, metadata included (order is rerun's hash order).
    assert sorted(s_own.names) == sorted(s_ours.names)
    for name in s_own.names:
        assert s_own.field(name).equals(s_ours.field(name), check_metadata=True), name
    assert s_own.metadata == s_ours.metadata
    # The manifest: the same columns in the same order, one row per chunk, the same rows
    # (entity, static, row count, time ranges per timeline and component) but for ids and
    # places, and log_time (the wall clock of each log call).
    assert t_own.schema.names == t_ours.schema.names
    assert t_own.schema.equals(t_ours.schema, check_metadata=True)
    wall = [c for c in t_own.schema.names if c.startswith("log_time")]
    assert _rows(t_own.drop_columns(wall)) == _rows(t_ours.drop_columns(wall))
    # The recording's properties, 2 static chunks, 3 x (scalars, points), the text log.
    assert t_ours.num_rows == 10
    offsets = t_ours.column("chunk_byte_offset").to_numpy()
    assert np.all(np.diff(np.sort(offsets)) > 0)


def test_every_chunk_sits_where_the_footer_says(tmp_path):
    """Each manifest row's offset holds that chunk's message (rrd verify checks this too)."""
    _, ours, sizes = _two_writes(tmp_path)
    assert sizes == sorted(sizes)
    data = ours.read_bytes()
    _, table = _footer(ours)["recording"]
    for offset, size in zip(
        table.column("chunk_byte_offset").to_pylist(),
        table.column("chunk_byte_size").to_pylist(),
        strict=True,
    ):
        kind, length = struct.unpack_from("<QQ", data, offset - 16)
        assert (kind, length) == (2, size)  # an Arrow message of exactly that size
    reader = RrdReader(ours)  # reads through the footer
    chunks = reader.stream().to_chunks()
    ticks = [
        t
        for c in chunks
        if c.entity_path == "/signals/a" and "tick" in c.timeline_names
        for t in c.to_record_batch().column("tick").to_pylist()
    ]
    assert ticks == list(range(150))


def test_a_fifo_gets_the_messages_then_one_footer(tmp_path):
    """A special file cannot be rewritten in place: messages as they come, the footer at close."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    received = bytearray()

    def drain() -> None:
        with fifo.open("rb") as src:
            while block := src.read(1 << 16):
                received.extend(block)

    reader = threading.Thread(target=drain)
    reader.start()
    rec = rr.RecordingStream("exo_ctrl_test")
    stream = rr.binary_stream(recording=rec)
    rec.set_sinks(stream)
    file = RrdFile(fifo)
    assert file.special
    for part in range(4):
        _log_part(rec, part)
        file.append(stream.read(flush=True))
    file.close()
    rec.disconnect()
    reader.join(timeout=30)
    copy = tmp_path / "copy.rrd"
    copy.write_bytes(bytes(received))
    assert _verify(copy) == 0
    assert received.count(b"RRF2FOOT") == 1
    _, table = _footer(copy)["recording"]
    assert table.num_rows == 10  # as in test_the_merged_footer_is_the_one_rerun_writes


def test_unknown_stream_layouts_are_refused():
    with pytest.raises(RecordingError, match="unknown layout: no RRF2 stream header"):
        split_stream(b"RRF1" + bytes(40))
    rec = rr.RecordingStream("exo_ctrl_test")
    stream = rr.binary_stream(recording=rec)
    rec.set_sinks(stream)
    _log_part(rec, 1)
    data = stream.read(flush=True)
    rec.disconnect()
    parts = split_stream(data)
    assert parts.header == data[:12] and len(parts.body) + len(parts.footer) + 12 + 16 + 32 == len(
        data
    )
    with pytest.raises(RecordingError, match="checksum is not xxh32"):
        split_stream(data[:-40] + bytes([data[-40] ^ 1]) + data[-39:])  # a footer bit flipped
    with pytest.raises(RecordingError, match="bytes after the footer"):
        split_stream(data + b"\0")


def test_a_shifted_offset_column_is_moved_by_the_file_position(tmp_path):
    """Appends after the first: rows move by where their messages now sit."""
    rec = rr.RecordingStream("exo_ctrl_test")
    stream = rr.binary_stream(recording=rec)
    rec.set_sinks(stream)
    path = tmp_path / "two.rrd"
    file = RrdFile(path)
    _log_part(rec, 1)
    first = stream.read(flush=True)
    file.append(first)
    _log_part(rec, 2)
    second = stream.read(flush=True)
    file.append(second)
    file.close()
    rec.disconnect()
    _, table = _footer(path)["recording"]
    ((_, manifest),) = _pb_fields(split_stream(second).footer)  # the second stream's own rows
    frame = dict(_pb_fields(dict(_pb_fields(manifest))[4]))
    raw = pa.decompress(frame[2], decompressed_size=frame[4], codec="lz4_raw")
    alone = pa.ipc.open_stream(raw).read_all()
    shift = len(split_stream(first).body)  # its messages follow the first stream's
    ids = pa.array(alone.column("chunk_id").to_pylist(), alone.schema.field("chunk_id").type)
    moved = table.filter(pc.is_in(table.column("chunk_id"), value_set=ids))
    expected = [o + shift for o in alone.column("chunk_byte_offset").to_pylist()]
    assert sorted(moved.column("chunk_byte_offset").to_pylist()) == sorted(expected)


SHARED_LIMIT_CHILD = """
import os, resource, sys
from exo_ctrl.record.rrd_file import RrdFile
path, size, limit = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))  # the memfd's limit too
file = RrdFile(path)
assert file._writer is not None and file._shared is not None  # Linux: the shared buffer
data = bytes(range(256)) * (size // 256)
file._write([data[: size // 3], data[size // 3 :]], 0)  # in two pieces
file._write([data[:4096]], len(data))  # a small one through the shared buffer again
file.abandon()
print(len(data))
"""


@pytest.mark.skipif(not hasattr(os, "memfd_create"), reason="no memfd: bytes go by the pipe")
def test_bytes_go_through_the_pipe_when_the_shared_buffer_cannot_grow(tmp_path):
    """Under a file-size limit the shared buffer (a request and a quarter) cannot reach.

    The write of 900 kB fits a 1 MB limit; the buffer would need 1.1 MB: the
    request carries its bytes through the pipe instead, and the file holds
    them exactly; the next, small request uses the buffer.
    """
    path = tmp_path / "limited.bin"
    size, limit = 900 * 1024, 1 << 20
    args = [sys.executable, "-c", SHARED_LIMIT_CHILD, str(path), str(size), str(limit)]
    proc = subprocess.run(args, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    n = int(proc.stdout)
    data = bytes(range(256)) * (size // 256)
    assert not path.exists()  # abandoned: the partial file stays, never renamed
    assert (tmp_path / "limited.partial.bin").read_bytes() == data + data[:4096]
    assert n == len(data)
