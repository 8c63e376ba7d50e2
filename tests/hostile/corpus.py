"""The hostile-input corpus: files a careless user or a hostile one would give, made by code.

Nothing large is stored: each function writes its case into a directory the
test gives (``tmp_path``) and returns the path.  The tests in this folder
run every case and a sibling of it through the real command line and assert
the exact message and exit code, and that no file it should not touch moved.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from exo_ctrl.estimation.csvlog import write_csv_log
from exo_ctrl.model import default_urdf_path

#: The installed command (a real process where the process is the point).
EXO_CTRL = Path(sys.executable).parent / "exo-ctrl"
#: A short run without a recording (a simulate case that must get past the checks).
SHORT_RUN = ["--duration", "0.05", "--no-record"]


def exo_ctrl(
    argv: list[str], cwd: Path, env: dict[str, str] | None = None, timeout: float = 120.0
) -> subprocess.CompletedProcess:
    """Run ``exo-ctrl ARGV`` in ``cwd``; text output (bytes decoded as UTF-8, replaced)."""
    return subprocess.run(
        [str(EXO_CTRL), *argv],
        cwd=cwd,
        env={**os.environ, **(env or {})},
        capture_output=True,
        timeout=timeout,
        text=True,
        errors="replace",
    )


def exo_urdf_text() -> str:
    """The default exoskeleton URDF's text (what the variants edit)."""
    return default_urdf_path("exo").read_text()


def edited_urdf(directory: Path, name: str, old: str, new: str, count: int = 1) -> Path:
    """The default exoskeleton with ``old`` replaced by ``new`` (``count`` times; must occur)."""
    text = exo_urdf_text()
    assert text.count(old) >= count, old
    path = directory / name
    path.write_text(text.replace(old, new, count))
    return path


def chained_urdf(directory: Path, joints: int, name: str = "chain.urdf") -> Path:
    """A URDF of ``joints`` fixed joints in one chain (each link the child of the one before)."""
    link = '<link name="l{i}"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" \
iyy="1" iyz="0" izz="1"/></inertial></link>\n'
    joint = '<joint name="j{i}" type="fixed"><parent link="l{p}"/><child link="l{i}"/></joint>\n'
    parts = ['<?xml version="1.0"?>\n<robot name="chain">\n', link.format(i=0)]
    for i in range(1, joints + 1):
        parts.append(link.format(i=i))
        parts.append(joint.format(i=i, p=i - 1))
    parts.append("</robot>\n")
    path = directory / name
    path.write_text("".join(parts))
    return path


def nested_xml_urdf(directory: Path, depth: int, name: str = "deep.urdf") -> Path:
    """The default exoskeleton with an element nested ``depth`` levels deep in a link."""
    inner = "<a>" * depth + "</a>" * depth
    return edited_urdf(directory, name, "</robot>", f"<extra>{inner}</extra></robot>")


def nested_json(directory: Path, depth: int, name: str = "deep.json") -> Path:
    """A JSON list nested ``depth`` levels deep."""
    path = directory / name
    path.write_text("[" * depth + "]" * depth)
    return path


def csv_log(
    directory: Path,
    name: str = "log.csv",
    n: int = 2000,
    dt: float = 0.001,
    scale_q: float = 1.0,
    edit: dict[tuple[int, str], float] | None = None,
    gap: tuple[int, float] | None = None,
) -> Path:
    """A plausible walking log (hip ±0.3 rad, knee 0.1-1.1 rad at 1 Hz), edited where asked.

    Args:
        directory: where to write it.
        name: its file name.
        n: rows.
        dt: time step [s].
        scale_q: factor on the angles and speeds (180/π: degrees).
        edit: (row, column) → value, e.g. ``{(10, "right_hip_dq"): 40.0}``.
        gap: (row, seconds): every time from that row on shifted by the gap.

    """
    t = np.arange(n) * dt
    w = 2 * math.pi
    if gap is not None:
        t = t.copy()
        t[gap[0] :] += gap[1]
    hip = 0.3 * np.sin(w * t)
    knee = 0.6 - 0.5 * np.cos(w * t)
    q = np.stack([hip, knee, -hip, knee[::-1]], axis=1) * scale_q
    dq = np.gradient(q, dt, axis=0)
    tau = np.stack([5 * np.sin(w * t)] * 4, axis=1)
    path = directory / name
    write_csv_log(path, t, q, dq, tau)
    if edit:
        lines = path.read_text().splitlines()
        header = lines[0].split(",")
        for (row, column), value in edit.items():
            fields = lines[row + 1].split(",")
            fields[header.index(column)] = repr(value)
            lines[row + 1] = ",".join(fields)
        path.write_text("\n".join(lines) + "\n")
    return path


def meta_rrd(
    directory: Path, meta_text: str, name: str = "meta.rrd", outcome_text: str | None = None
) -> Path:
    """A recording holding only ``raw/meta`` (and ``raw/outcome``) with the given texts."""
    import rerun as rr

    path = directory / name
    rec = rr.RecordingStream("exo_ctrl_hostile")
    rec.save(str(path))
    rec.log("raw/meta", rr.TextDocument(meta_text), static=True)
    if outcome_text is not None:
        rec.log("raw/outcome", rr.TextDocument(outcome_text), static=True)
    rec.disconnect()
    return path


def valid_meta(**changes: object) -> dict:
    """A recording's metadata as the recorder writes it for SimConfig(), with ``changes``."""
    from exo_ctrl.record.format import RECORDING_FORMAT
    from exo_ctrl.sim import SimConfig

    meta = {"format": RECORDING_FORMAT, "config": SimConfig().to_dict(), "signals": {"q": [4]}}
    meta.update(changes)
    return meta


def write_all(directory: Path) -> dict[str, Path]:
    """Write one file of each hostile kind into ``directory`` (for trying them by hand).

    ``python tests/hostile/corpus.py DIR`` runs this; the tests make the same
    files one at a time in their own temporary directories.  Returns name →
    path, e.g. ``chain_6000.urdf`` (segfaulted Pinocchio 4.1's parser).
    """
    import json

    directory.mkdir(parents=True, exist_ok=True)
    made = {
        "chain_6000.urdf": chained_urdf(directory, 6000, "chain_6000.urdf"),
        "nested_40.urdf": nested_xml_urdf(directory, 40, "nested_40.urdf"),
        "session_5000_deep.json": nested_json(directory, 5000, "session_5000_deep.json"),
        "log_degrees.csv": csv_log(directory, "log_degrees.csv", scale_q=180 / math.pi),
        "log_hours.csv": csv_log(directory, "log_hours.csv", dt=0.001 / 3600),
        "log_gap.csv": csv_log(directory, "log_gap.csv", gap=(500, 1e6)),
        "meta_5000_deep.rrd": meta_rrd(directory, "[" * 5000 + "]" * 5000, "meta_5000_deep.rrd"),
        "meta_huge_signal.rrd": meta_rrd(
            directory,
            json.dumps(valid_meta(signals={"q": [4], "huge": [1_000_000, 3_000_000]})),
            "meta_huge_signal.rrd",
        ),
        "meta_config_int.rrd": meta_rrd(
            directory, json.dumps(valid_meta(config=5)), "meta_config_int.rrd"
        ),
    }
    return made


if __name__ == "__main__":
    for made_path in write_all(Path(sys.argv[1] if len(sys.argv) > 1 else "hostile")).values():
        print(made_path)
