"""The package's imports follow the data flow (walked with ``ast``, nothing imported).

model < plan < plant < sensing < estimation < control < safety < sim < record
< comparison < sweep < cli, with the small shared modules (exceptions, _jit, _jit_cache, _validate,
_io, _progress, _lifetime, _plugin) below them all.  A module may import its own package and the
packages below it, never one above; no module imports another of the
project's lazily (inside a function), so no cycle can hide; the module graph
has no cycle; the plant never imports control, and only the cli, the
comparison of recordings (``exo_ctrl.comparison.recordings``) and the
package's public face import the recorder.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "exo_ctrl"

RANKS = {
    "exceptions": 0,
    "_jit": 0,
    "_jit_cache": 0,
    "_validate": 0,
    "_io": 0,
    "_progress": 0,
    "_lifetime": 0,
    "_plugin": 0,
    "_version": 0,
    "model": 1,
    "plan": 2,
    "plant": 3,
    "sensing": 4,
    "estimation": 5,
    "control": 6,
    "safety": 7,
    "sim": 8,
    "scenario": 9,
    "record": 10,
    "comparison": 11,
    "sweep": 12,
    "cli": 13,
    "__main__": 14,
}


def module_name(path: Path) -> tuple[str, bool]:
    """Dotted name of a source file, and whether it is a package's __init__."""
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    is_package = parts[-1] == "__init__"
    if is_package:
        parts = parts[:-1]
    return ".".join(parts), is_package


def imports_of(path: Path) -> list[tuple[str, bool]]:
    """(absolute module imported, at module level) for every exo_ctrl import of a file."""
    name, is_package = module_name(path)
    package = name.split(".") if is_package else name.split(".")[:-1]
    tree = ast.parse(path.read_text(), str(path))
    top = {id(node) for node in tree.body}
    for node in tree.body:  # imports under `if TYPE_CHECKING:` are module level too
        if isinstance(node, ast.If):
            top |= {id(n) for n in node.body}
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if node.module is None:  # `from .. import x`: x must be a module
                targets = [f"{target}.{alias.name}" for alias in node.names]
            else:
                targets = [target]
        elif isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        else:
            continue
        for t in targets:
            if t == "exo_ctrl" or t.startswith("exo_ctrl."):
                found.append((t, id(node) in top))
    return found


def existing(module: str) -> bool:
    path = ROOT.parent / module.replace(".", "/")
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


SOURCES = sorted(p for p in ROOT.rglob("*.py") if "__pycache__" not in p.parts)


def layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_module_imports_a_package_above_it(path: Path) -> None:
    name, _ = module_name(path)
    if name == "exo_ctrl":
        return  # the public face gathers every package
    own = RANKS[layer(name)]
    for target, at_top in imports_of(path):
        assert existing(target), f"{name} imports {target}, which is not a module"
        assert at_top, f"{name} imports {target} inside a function"
        above = layer(target)
        assert above in RANKS, f"{name} imports {target}, a package with no place in the flow"
        assert RANKS[above] <= own, f"{name} ({layer(name)}) imports {target} ({above}), above it"


def test_the_module_graph_has_no_cycle() -> None:
    graph: dict[str, set[str]] = {}
    for path in SOURCES:
        name, _ = module_name(path)
        if name == "exo_ctrl":
            continue
        graph[name] = {t for t, _ in imports_of(path) if existing(t) and t != "exo_ctrl"}
    state: dict[str, int] = {}

    def visit(node: str, trail: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if nxt.startswith(node + "."):
                continue  # a package's __init__ importing its own modules
            if state.get(nxt) == 1:
                cycle = [*trail[trail.index(nxt) :], nxt] if nxt in trail else [node, nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if state.get(nxt) is None:
                visit(nxt, [*trail, nxt])
        state[node] = 2

    for node in sorted(graph):
        if state.get(node) is None:
            visit(node, [node])


def test_the_plant_never_imports_control_and_only_the_cli_imports_the_recorder() -> None:
    for path in SOURCES:
        name, _ = module_name(path)
        for target, _ in imports_of(path):
            if layer(name) == "plant":
                assert layer(target) not in ("control", "safety", "estimation"), (name, target)
            if layer(target) == "record" and name != "exo_ctrl":
                reader = name == "exo_ctrl.comparison.recordings"  # compare_recordings
                assert layer(name) in ("record", "cli") or reader, f"{name} imports {target}"


def test_the_walk_sees_the_imports() -> None:
    """The checks above can fail: the walker finds a known upward-looking import."""
    found = dict(imports_of(ROOT / "sim" / "tick.py"))
    assert any(layer(t) == "estimation" for t in found)
    assert any(layer(t) == "plant" for t in found)


def test_the_public_face_imports_the_recorder_on_first_use_of_read_recording() -> None:
    # rerun (the recorder's) is not loaded by `import exo_ctrl`, nor by a sweep's worker
    # module; `read_recording` (attribute, from-import or star-import) is the recorder's own
    code = (
        "import sys, exo_ctrl, exo_ctrl.sweep.run; print('rerun' in sys.modules); "
        "from exo_ctrl import read_recording; import exo_ctrl.record as r; "
        "print('rerun' in sys.modules, read_recording is r.read_recording); "
        "ns = {}; exec('from exo_ctrl import *', ns); "
        "print(ns['read_recording'] is r.read_recording)\n"
        "try:\n    exo_ctrl.no_such_name\nexcept AttributeError as e:\n    print(e)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.splitlines() == [
        "False",
        "True True",
        "True",
        "module 'exo_ctrl' has no attribute 'no_such_name'",
    ]


def test_no_module_is_over_500_lines() -> None:
    # one concept a module, a few hundred lines each (the package layout's rule)
    lines = {p: len(p.read_text(encoding="utf-8").splitlines()) for p in SOURCES}
    assert max(lines.values()) > 300  # the count sees the files
    over = {str(p.relative_to(ROOT)): n for p, n in lines.items() if n > 500}
    assert over == {}
