"""Stale compiled kernels are deleted when any of the package's sources changed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from exo_ctrl import _jit_cache


def _package(tmp_path: Path) -> Path:
    root = tmp_path / "pkg"
    (root / "sub" / "__pycache__").mkdir(parents=True)
    (root / "__pycache__").mkdir()
    (root / "a.py").write_text("x = 1\n")
    (root / "sub" / "b.py").write_text("y = 2\n")
    return root


def _caches(root: Path) -> list[Path]:
    paths = []
    for folder in (root / "__pycache__", root / "sub" / "__pycache__"):
        for name in ("k.f-1.py311.nbi", "k.f-1.py311.1.nbc"):
            path = folder / name
            path.write_bytes(b"cached")
            paths.append(path)
    return paths


def test_unchanged_sources_keep_the_cache(tmp_path: Path) -> None:
    root = _package(tmp_path)
    assert _jit_cache.refresh(root) == 0  # first import: nothing cached yet, the stamp written
    caches = _caches(root)
    assert _jit_cache.refresh(root) == 0
    assert all(p.exists() for p in caches)


def test_a_changed_callee_module_deletes_every_cached_kernel(tmp_path: Path) -> None:
    root = _package(tmp_path)
    _jit_cache.refresh(root)
    caches = _caches(root)
    (root / "sub" / "b.py").write_text("y = 3\n")  # only the callee's module changes
    assert _jit_cache.refresh(root) == len(caches)
    assert not any(p.exists() for p in caches)
    assert (root / "__pycache__" / _jit_cache.STAMP_NAME).read_text() == _jit_cache.source_hash(
        root
    )
    (root / "sub" / "__pycache__" / "other.pyc").write_bytes(b"")  # not a kernel cache: kept
    (root / "c.py").write_text("z = 0\n")  # a new module changes the hash too
    assert _jit_cache.refresh(root) == 0
    assert (root / "sub" / "__pycache__" / "other.pyc").exists()


def test_the_hash_covers_paths_and_contents(tmp_path: Path) -> None:
    root = _package(tmp_path)
    before = _jit_cache.source_hash(root)
    (root / "a.py").rename(root / "c.py")
    assert _jit_cache.source_hash(root) != before


def test_changed_sources_delete_the_warm_markers_of_the_old_ones(tmp_path: Path) -> None:
    # a marker says a feature set's kernels are compiled (exo_ctrl/sim/warmup.py); named
    # by a hash with the sources, the old ones would pile up with every edit
    root = _package(tmp_path)
    _jit_cache.refresh(root)
    marker = root / "__pycache__" / _jit_cache.WARM_MARKERS.replace("*", "0123abcd")
    marker.write_bytes(b"")
    assert _jit_cache.refresh(root) == 0  # unchanged sources: kept
    assert marker.exists()
    (root / "a.py").write_text("x = 2\n")
    assert _jit_cache.refresh(root) == 1
    assert not marker.exists()


def test_the_cache_folders_with_numba_cache_dir_are_numbas_own(tmp_path: Path) -> None:
    # numba, in a process of its own with NUMBA_CACHE_DIR set, caches a kernel of
    # the package's sub-folder: in the folder cache_folders names for it
    root = _package(tmp_path)
    (root / "sub" / "k.py").write_text(
        "import numba\n\n@numba.njit(cache=True)\ndef f(x):\n    return x + 1\n"
    )
    cache = tmp_path / "cache"
    code = f"import sys; sys.path.insert(0, {str(root / 'sub')!r}); import k; k.f(1)"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    subprocess.run([sys.executable, "-c", code], env=env, check=True)
    made = {p.parent for p in cache.rglob("*.nbi")}
    folders = _jit_cache.cache_folders(root, str(cache))
    assert made == {root_sub for root_sub in folders if root_sub.name.startswith("sub_")}
    assert len(made) == 1 and len(folders) == 2  # the package's folder and sub/
    assert _jit_cache.cache_folders(root) == [root / "__pycache__", root / "sub" / "__pycache__"]


def test_a_changed_source_deletes_the_kernels_in_numba_cache_dir(tmp_path: Path) -> None:
    root, cache = _package(tmp_path), str(tmp_path / "cache")
    assert _jit_cache.refresh(root, cache) == 0  # the stamp written in the cache folder
    stamp = _jit_cache.stamp_path(root, cache)
    assert stamp.parent == tmp_path / "cache" and stamp.read_text() == _jit_cache.source_hash(root)
    in_tree = _caches(root)  # not numba's cache while NUMBA_CACHE_DIR is set: left alone
    kernels = []
    for folder in _jit_cache.cache_folders(root, cache):
        folder.mkdir(parents=True)
        for name in ("k.f-1.py311.nbi", "k.f-1.py311.1.nbc"):
            (folder / name).write_bytes(b"cached")
            kernels.append(folder / name)
    marker = stamp.parent / _jit_cache.WARM_MARKERS.replace("*", "0123abcd")
    marker.write_bytes(b"")
    assert _jit_cache.refresh(root, cache) == 0
    (root / "sub" / "b.py").write_text("y = 3\n")
    assert _jit_cache.refresh(root, cache) == len(kernels) + 1
    assert not any(p.exists() for p in [*kernels, marker])
    assert all(p.exists() for p in in_tree)
    # another checkout sharing the cache folder keeps a stamp of its own
    other = _package(tmp_path / "other")
    assert _jit_cache.stamp_path(other, cache) != stamp
