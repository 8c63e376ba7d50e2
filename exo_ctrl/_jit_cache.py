"""Stale compiled kernels removed: numba's cache knows a kernel's own file, not its callees'.

numba's ``cache=True`` keys a cached kernel on its own source file (its
contents).  A kernel that calls a kernel of another module has the callee
compiled into it, and when only the callee's module changes (an edit, an
upgrade that rewrites some files) numba still loads the caller's old machine
code: the run computes with the old callee, silently.

So at import the project's Python sources are hashed together, and when the
hash differs from the one recorded with the cache every cached kernel of the
package (``*.nbi`` index and ``*.nbc`` data files) is deleted before any is
loaded, with the warm markers of the old sources (:data:`WARM_MARKERS`,
:mod:`exo_ctrl.sim.warmup`: one empty file per feature set, named by a hash
with the sources, that would otherwise pile up with every edit), and the new
hash recorded: the next calls compile afresh.  Hashing the ~100 source files
takes about 2 ms.

Where numba keeps the kernels (:func:`cache_folders`): by default in the
package's ``__pycache__`` folders, the hash recorded there
(:data:`STAMP_NAME`); with ``NUMBA_CACHE_DIR`` set, in that folder, one
subfolder per source folder named as numba names it (the folder's name and
the SHA-1 of its absolute path), the hash recorded in the cache folder under
a name of its own per package location (:func:`stamp_path`), so that two
checkouts can share one.  Where nothing can be written (a read-only install
without ``NUMBA_CACHE_DIR``) nothing is deleted; numba then caches in its
user cache folder, which this does not refresh.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

__all__ = [
    "STAMP_NAME",
    "WARM_MARKERS",
    "cache_folders",
    "refresh",
    "source_hash",
    "stamp_path",
]

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


def cache_folders(root: Path, cache_dir: str | None = None) -> list[Path]:
    """The folders in which numba keeps the compiled kernels of the package at ``root``.

    Args:
        root: the package folder, absolute, as the package is imported
            (numba names its cache subfolders by that path).
        cache_dir: ``numba.config.CACHE_DIR`` (None or empty: not set).

    Returns:
        Without ``cache_dir``: ``__pycache__`` of every folder of the package
        holding Python sources; with it, ``cache_dir/<folder name>_<SHA-1 of
        the folder's absolute path>`` for each (numba's layout for a
        user-provided cache folder).

    """
    folders = sorted({p.parent for p in root.rglob("*.py") if "__pycache__" not in p.parts})
    if not cache_dir:
        return [f / "__pycache__" for f in folders]
    base = Path(cache_dir)
    return [base / f"{f.name}_{hashlib.sha1(str(f).encode()).hexdigest()}" for f in folders]


def stamp_path(root: Path, cache_dir: str | None = None) -> Path:
    """The file recording the source hash the cache of the package at ``root`` was made with."""
    if not cache_dir:
        return root / "__pycache__" / STAMP_NAME
    key = hashlib.sha1(str(root).encode()).hexdigest()[:16]
    return Path(cache_dir) / f"{Path(STAMP_NAME).stem}-{key}.sha256"


def refresh(root: Path, cache_dir: str | None = None) -> int:
    """Delete the cached kernels of the package at ``root`` if its sources changed since.

    Args:
        root: the package folder, absolute, as imported.
        cache_dir: ``numba.config.CACHE_DIR`` (None or empty: not set; the
            kernels are in the package's ``__pycache__`` folders).

    Returns:
        The number of cache files and warm markers deleted (0 when the
        sources are unchanged, or nothing could be written).

    """
    stamp = stamp_path(root, cache_dir)
    current = source_hash(root)
    try:
        if stamp.read_text() == current:
            return 0
    except OSError:
        pass
    targets = [
        (folder, pattern)
        for folder in cache_folders(root, cache_dir)
        for pattern in ("*.nbi", "*.nbc")
    ]
    targets.append((stamp.parent, WARM_MARKERS))  # where sim.warmup.marker_dir puts them
    deleted = 0
    for folder, pattern in targets:
        for path in folder.glob(pattern):
            try:
                path.unlink()
                deleted += 1
            except OSError:  # another process got there first, or read-only
                pass
    try:
        stamp.parent.mkdir(parents=True, exist_ok=True)
        partial = stamp.with_name(f"{stamp.name}.{os.getpid()}.tmp")
        partial.write_text(current)
        partial.replace(stamp)
    except OSError:
        return deleted
    return deleted
