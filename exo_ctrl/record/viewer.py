"""The rerun viewer that comes with rerun-sdk: finding it and starting it beside a run."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import rerun as rr

__all__ = ["find_viewer", "spawn_viewer"]


def find_viewer() -> Path | None:
    """The rerun viewer executable: the one installed with rerun-sdk, else one on PATH.

    rerun-sdk installs ``rerun`` next to the Python interpreter
    (``.venv/bin/rerun``), which is not on PATH unless the environment is
    activated; that one is looked for first.
    """
    beside = Path(sys.executable).parent / ("rerun.exe" if os.name == "nt" else "rerun")
    if beside.is_file() and os.access(beside, os.X_OK):
        return beside
    found = shutil.which("rerun")
    return Path(found) if found else None


def spawn_viewer(rec: rr.RecordingStream) -> str | None:
    """Start the rerun viewer :func:`find_viewer` finds, listening for ``rec``.

    Returns:
        None when it started, else why not, in one line.

    """
    viewer = find_viewer()
    if viewer is None:
        return (
            f"no rerun viewer found (neither {Path(sys.executable).parent / 'rerun'} nor "
            "'rerun' on PATH; it comes with rerun-sdk)"
        )
    try:
        rr.spawn(connect=False, executable_path=str(viewer), recording=rec)
    except (RuntimeError, OSError) as exc:
        return f"could not start the rerun viewer {viewer}: {' '.join(str(exc).split())}"
    return None
