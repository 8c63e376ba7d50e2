"""Stale compiled kernels removed: numba's cache knows a kernel's own file, not its callees'.

numba's ``cache=True`` keys a cached kernel on its own source file's time
stamp and size.  A kernel that calls a kernel of another module has the
callee compiled into it, and when only the callee's module changes (an edit,
an upgrade that rewrites some files) numba still loads the caller's old
machine code: the run computes with the old callee, silently.

So at import the project's Python sources are hashed together, and when the
hash differs from the one recorded with the cache (:data:`STAMP_NAME` in the
package's ``__pycache__``) every cached kernel of the package (``*.nbi``
index and ``*.nbc`` data files in its ``__pycache__`` folders) is deleted
before any is loaded, with the warm markers of the old sources
(:data:`WARM_MARKERS`, :mod:`exo_ctrl.sim.warmup`: one empty file per
feature set, named by a hash with the sources, that would otherwise pile
up with every edit), and the new hash recorded: the next calls compile
afresh.  Hashing the ~100 source files takes about 2 ms.  Where the package
cannot be written (a read-only install) nothing is deleted; numba then caches
elsewhere (its user cache folder), keyed the same way.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

__all__ = ["STAMP_NAME", "WARM_MARKERS", "refresh", "source_hash"]

#: The file, in the package's ``__pycache__``, that records the hash the cache was made with.
STAMP_NAME = "exo_ctrl_sources.sha256"

#: The names of the warm markers (:mod:`exo_ctrl.sim.warmup`), a glob pattern.
WARM_MARKERS = "exo_ctrl-warm-*"


def source_hash(root: Path) -> str:
    """SHA-256 of every ``.py`` file under ``root``: their paths and contents, in sorted order."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()


def refresh(root: Path) -> int:
    """Delete the cached kernels under ``root`` if its sources changed since they were made.

    Args:
        root: the package folder.

    Returns:
        The number of cache files and warm markers deleted (0 when the
        sources are unchanged, or nothing could be written).

    """
    stamp = root / "__pycache__" / STAMP_NAME
    current = source_hash(root)
    try:
        if stamp.read_text() == current:
            return 0
    except OSError:
        pass
    deleted = 0
    for pattern in ("*.nbi", "*.nbc", WARM_MARKERS):
        for path in root.rglob(f"__pycache__/{pattern}"):
            try:
                path.unlink()
                deleted += 1
            except OSError:  # another process got there first, or read-only
                pass
    try:
        stamp.parent.mkdir(exist_ok=True)
        partial = stamp.with_name(f"{STAMP_NAME}.{os.getpid()}.tmp")
        partial.write_text(current)
        partial.replace(stamp)
    except OSError:
        return deleted
    return deleted
