"""Limits a URDF file must meet before any parser builds a model from it.

Pinocchio 4.1's URDF parser ends the process with a segmentation fault on a
file of about 6,000 chained fixed joints (1.3 MB; 3,000 pass): nothing can
be caught in Python afterwards.  :func:`prescan_urdf` reads the file once
as a stream of XML events (``xml.etree.ElementTree.iterparse``, nothing
built) and refuses it by its size, its element nesting or its count of
links and joints, each far above any leg model's (the default exoskeleton:
5 kB, 11 links, 10 joints, nesting 4; example-robot-data's human: 25 kB,
37 links, 36 joints) and far below what crashes.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

from .._validate import format_bytes
from ..exceptions import InvalidModel

__all__ = [
    "MAX_URDF_BYTES",
    "MAX_URDF_DEPTH",
    "MAX_URDF_PARTS",
    "c_stderr",
    "parser_reason",
    "prescan_urdf",
]

#: The largest URDF file read [bytes]: 8 MiB.
MAX_URDF_BYTES = 8 << 20
#: The deepest element nesting allowed (``<robot><link><inertial><mass>`` is 4).
MAX_URDF_DEPTH = 32
#: The most links, and the most joints, a URDF may have.
MAX_URDF_PARTS = 1000


def prescan_urdf(src: str, path: str | os.PathLike[str]) -> None:
    """Refuse a URDF beyond the limits (module docstring) before it is parsed.

    Args:
        src: the file as the messages name it.
        path: the file (a regular file: the caller checked it exists).

    Raises:
        InvalidModel: the file is larger than :data:`MAX_URDF_BYTES`, nests
            elements deeper than :data:`MAX_URDF_DEPTH` or has more than
            :data:`MAX_URDF_PARTS` links or joints.  Malformed XML is left
            to the full check, which names its line and column.

    """
    size = Path(path).stat().st_size
    if size > MAX_URDF_BYTES:
        raise InvalidModel(
            src,
            "",
            f"the file is {format_bytes(size)}; a URDF is read up to "
            f"{format_bytes(MAX_URDF_BYTES)} (a leg model is a few kB)",
        )
    depth = 0
    counts = {"link": 0, "joint": 0}
    try:
        for event, element in ET.iterparse(path, events=("start", "end")):
            if event == "end":
                depth -= 1
                if depth == 1:
                    element.clear()  # keep nothing of the robot's parts
                continue
            depth += 1
            if depth > MAX_URDF_DEPTH:
                raise InvalidModel(
                    src,
                    "",
                    f"elements nested more than {MAX_URDF_DEPTH} deep (at <{element.tag}>); "
                    "a URDF nests about 5",
                )
            if depth == 2 and element.tag in counts:
                counts[element.tag] += 1
                if counts[element.tag] > MAX_URDF_PARTS:
                    raise InvalidModel(
                        src,
                        "",
                        f"more than {MAX_URDF_PARTS} {element.tag}s; a URDF may have at most "
                        f"{MAX_URDF_PARTS} (Pinocchio's parser crashes on about 6000 chained "
                        "joints)",
                    )
    except ET.ParseError:
        return


@contextlib.contextmanager
def c_stderr() -> Iterator[list[str]]:
    """Capture what C and C++ code writes to file descriptor 2 while the block runs.

    urdfdom (inside Pinocchio's parser) prints its reasons there over several
    lines ("Error: ... at line 274 in /project/urdfdom/..."), before Python
    sees an exception.  The lines are in the yielded list once the block has
    ended; nothing of them reaches the terminal.
    """
    lines: list[str] = []
    with contextlib.suppress(OSError, ValueError, AttributeError):
        sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no descriptor 2 to redirect: let it be
        yield lines
        return
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines.extend(sink.read(1 << 16).decode("utf-8", "replace").splitlines())


def parser_reason(lines: list[str]) -> str:
    """Urdfdom's first error as one line ("" if none), its source location dropped."""
    text = " ".join(line.strip() for line in lines if line.strip())
    found = re.search(r"Error:\s*(.*?)(?:\s+at line \d+ in \S+|$)", text)
    return found.group(1).strip() if found else ""
