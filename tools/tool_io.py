"""The tools' JSON outputs: checked before the work, written whole or not at all."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl._io import atomic_write, check_output
from exo_ctrl.exceptions import ExoCtrlError


def json_output(path: str | Path | None, tool: str) -> bool:
    """Whether ``path`` (``--json``; None: not asked for) can be written.

    Checked before a run of minutes; if it cannot, the reason is printed as
    ``tool``'s error (the caller exits 2).
    """
    if path is None:
        return True
    try:
        check_output(path, "--json")
    except ExoCtrlError as exc:
        print(f"{tool}: {exc}", file=sys.stderr)
        return False
    return True


def write_json(path: str | Path | None, data: Any, indent: int = 1) -> None:
    """``data`` as JSON to ``path``, whole or not at all (None: nothing asked)."""
    if path is not None:
        with atomic_write(path) as f:
            f.write(json.dumps(data, indent=indent) + "\n")
