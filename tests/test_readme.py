"""Every command README.md, the docs/ pages and the tools' docstrings show names its program.

A command written ``python tools/reproduce_paper.py`` works only with the
virtual environment active (otherwise: ``ModuleNotFoundError``), so every
command names its program by its path in the environment
(``.venv/bin/python tools/…``, ``.venv/bin/exo-ctrl``, ``.venv/bin/rerun``);
the one exception is ``python3 -m venv .venv``, which creates it.

What counts as a command: every line of a ``bash``/``sh``/``console`` code
block, and every other code span or code-block line whose first word is a
program (:data:`PROGRAMS`, a ``.venv/`` path, or a ``.py`` file followed by
arguments).  ``a && b`` and ``a; b`` are checked part by part.  An ``output`` block
quotes what a command prints and holds no command.  tests/test_docs_run.py runs the
commands; this module also checks the README's size, the pages' links and that mkdocs.yml
lists every page.
"""

from __future__ import annotations

import ast
import importlib.util
import os
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Bare program names a reader could type, which must be written as venv paths.
PROGRAMS = frozenset({"python", "python3", "pip", "pip3", "exo-ctrl", "rerun", "pytest", "ruff"})
SHELL_BLOCKS = frozenset({"bash", "sh", "shell", "console"})
#: Blocks that quote output, not commands.
OUTPUT_BLOCKS = frozenset({"output"})
#: README.md, then the docs/ pages.
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
README_MAX_LINES = 300
README_MAX_LINE_CHARS = 200
BOOTSTRAP = "python3 -m venv .venv"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
SPAN = re.compile(r"`([^`\n]+)`")


def venv_bin() -> Path:
    """The environment's ``bin`` folder: the repository's ``.venv``, else the running one."""
    local = ROOT / ".venv" / "bin"
    return local if local.is_dir() else Path(sys.executable).parent


def looks_like_command(text: str) -> bool:
    """Whether a code span or block line outside a shell block is a command."""
    words = text.split()
    if not words:
        return False
    first = words[0]
    return (
        first in PROGRAMS
        or first.startswith(".venv/")
        or (first.endswith(".py") and len(words) > 1)
    )


def commands_in_markdown(text: str) -> list[str]:
    """The commands a Markdown text shows (see the module docstring)."""
    found = []
    for lang, body in FENCE.findall(text):
        for line in body.splitlines():
            line = line.strip()
            if lang in OUTPUT_BLOCKS:
                continue
            if lang in SHELL_BLOCKS:
                shown = bool(line) and not line.startswith("#")
            else:
                shown = lang != "python" and looks_like_command(line)
            if shown:
                found.append(line)
    outside = FENCE.sub("", text)
    found += [span.strip() for span in SPAN.findall(outside) if looks_like_command(span.strip())]
    return found


def commands_in_docstring(text: str) -> list[str]:
    """The commands a module docstring shows: lines (after an optional ``Usage:``)."""
    found = []
    for line in text.splitlines():
        line = line.strip().removeprefix("Usage:").strip()
        found += [s.strip() for s in SPAN.findall(line) if looks_like_command(s.strip())]
        if looks_like_command(line):
            found.append(line)
    return found


def problems(command: str) -> list[str]:
    """What is wrong with a command ([] when each part names an existing program)."""
    out = []
    for part in re.split(r"&&|\|\||;", command):
        words = part.split()
        if not words or " ".join(words) == BOOTSTRAP:
            continue
        first = words[0]
        if first.startswith(".venv/bin/"):
            program = venv_bin() / first.removeprefix(".venv/bin/")
        else:
            program = ROOT / first
        if first in PROGRAMS or not first.startswith((".venv/", "tools/", "./")):
            out.append(f"{first!r} is not a path in the environment or the repository")
            continue
        if not (program.is_file() and os.access(program, os.X_OK)):
            out.append(f"{first!r} is not an executable file")
            continue
        if program.name.startswith("python") and len(words) > 1:
            target = words[1]
            if target == "-m" and len(words) > 2:
                if importlib.util.find_spec(words[2]) is None:
                    out.append(f"module {words[2]!r} is not installed")
            elif target.endswith(".py") and not (ROOT / target).is_file():
                out.append(f"script {target!r} is not in the repository")
    return out


def readme_commands() -> list[str]:
    return commands_in_markdown((ROOT / "README.md").read_text(encoding="utf-8"))


def page_commands() -> list[tuple[str, str]]:
    """(page, command) for every command of README.md and the docs/ pages."""
    return [
        (page.relative_to(ROOT).as_posix(), command)
        for page in PAGES
        for command in commands_in_markdown(page.read_text(encoding="utf-8"))
    ]


def tool_commands() -> list[tuple[str, str]]:
    found = []
    for path in sorted((ROOT / "tools").glob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
        found += [(path.name, command) for command in commands_in_docstring(doc)]
    return found


def test_the_readme_shows_the_commands_it_promises():
    commands = readme_commands()
    assert "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/exo-ctrl simulate" in (
        commands
    )
    assert ".venv/bin/python tools/reproduce_paper.py" in commands
    assert ".venv/bin/rerun exo_run.rrd" in commands
    for sub in ("gait", "urdf", "simulate", "estimate", "sweep"):
        assert any(c.startswith(f".venv/bin/exo-ctrl {sub} ") for c in commands), sub


@pytest.mark.parametrize(("page", "command"), page_commands())
def test_every_page_command_names_an_existing_program(page, command):
    assert problems(command) == [], page


def test_the_readme_is_a_short_guide():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES
    assert [i + 1 for i, line in enumerate(lines) if len(line) > README_MAX_LINE_CHARS] == []


def test_mkdocs_lists_every_page():
    config = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    listed = re.findall(r":\s*(\S+\.md)\s*$", config, re.M)
    assert sorted(listed) == sorted(p.name for p in (ROOT / "docs").glob("*.md"))


def heading_anchors(text: str) -> set[str]:
    """GitHub's anchors of a Markdown text's headings."""
    anchors = set()
    for title in re.findall(r"^#+ (.+)$", FENCE.sub("", text), re.M):
        slug = re.sub(r"[^\w\- ]", "", title.strip().lower()).replace(" ", "-")
        anchors.add(slug)
    return anchors


def page_links() -> list[tuple[str, str]]:
    """(page, target) of every relative Markdown link or image of the pages."""
    found = []
    for page in PAGES:
        text = FENCE.sub("", page.read_text(encoding="utf-8"))
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if not re.match(r"[a-z]+:", target):
                found.append((page.relative_to(ROOT).as_posix(), target))
    return found


@pytest.mark.parametrize(("page", "target"), page_links())
def test_every_link_points_at_a_file_and_heading(page, target):
    path, _, anchor = target.partition("#")
    file = (ROOT / page).parent / path if path else ROOT / page
    assert file.is_file(), target
    if anchor:
        assert anchor in heading_anchors(file.read_text(encoding="utf-8")), target


def test_the_pages_are_current_not_a_history():
    history = re.compile(
        r"this stage|previous session|last sessions?|than before|stopped importing"
    )
    hits = [
        (page.name, m.group(0))
        for page in PAGES
        for m in history.finditer(page.read_text(encoding="utf-8"))
    ]
    assert hits == []


@pytest.mark.parametrize(("tool", "command"), tool_commands())
def test_every_tool_usage_line_names_an_existing_program(tool, command):
    assert problems(command) == [], tool


def test_each_tool_shows_how_to_run_it():
    shown = {tool for tool, _ in tool_commands()}
    assert shown == {path.name for path in (ROOT / "tools").glob("*.py")}


@pytest.mark.parametrize(
    ("command", "expected"),
    [
        (
            "python tools/reproduce_paper.py",
            ["'python' is not a path in the environment or the repository"],
        ),
        (
            "exo-ctrl simulate --cycles 1",
            ["'exo-ctrl' is not a path in the environment or the repository"],
        ),
        ("rerun exo_run.rrd", ["'rerun' is not a path in the environment or the repository"]),
        ('pip install -e ".[dask]"', ["'pip' is not a path in the environment or the repository"]),
        ("tools/bench.py --cold", ["'tools/bench.py' is not an executable file"]),
        (".venv/bin/nothing-here --help", ["'.venv/bin/nothing-here' is not an executable file"]),
        (
            ".venv/bin/python tools/missing.py",
            ["script 'tools/missing.py' is not in the repository"],
        ),
        (".venv/bin/python -m no_such_module", ["module 'no_such_module' is not installed"]),
        (
            "python3 -m venv .venv && exo-ctrl gait --csv g.csv",
            ["'exo-ctrl' is not a path in the environment or the repository"],
        ),
        ("python3 -m venv .venv && .venv/bin/python -m pytest", []),
    ],
)
def test_the_check_refuses_bare_and_missing_programs(command, expected):
    assert problems(command) == expected


def test_extraction_finds_spans_lines_and_shell_blocks():
    text = (
        "Run `python tools/x.py --out d` or `exo-ctrl`, see `exo_ctrl/sim/`.\n\n"
        "```bash\n# comment\nmake all\n```\n\n```python\nprint('python x')\n```\n"
    )
    assert commands_in_markdown(text) == ["make all", "python tools/x.py --out d", "exo-ctrl"]
    doc = "Title.\n\nUsage: python tools/x.py [--check]\n\n    .venv/bin/python tools/y.py\n"
    assert commands_in_docstring(doc) == [
        "python tools/x.py [--check]",
        ".venv/bin/python tools/y.py",
    ]
