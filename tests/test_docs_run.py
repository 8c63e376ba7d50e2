"""The commands of README.md and docs/*.md run, and the figures they quote are what they print.

The rule (docs/index.md, "How these pages are tested"):

- Each page runs in a fresh directory that links the repository's ``.venv``, ``tools``,
  ``urdf`` and ``examples``; its ``bash`` blocks run line by line and its ``python`` blocks as
  scripts, in page order, so a command can use what an earlier one wrote.
- ``exo-ctrl simulate``, ``sweep`` and ``compare`` are cut short to ``--duration 0.5`` (in place
  of their ``--duration``/``--cycles``), except the runs of :data:`FULL_RUNS` and the blocks
  whose output the text quotes, which run as written.
- An ``output`` block right after a command block quotes what that block prints: every quoted
  line must match a printed line, in order, with the text between the numbers equal, and each
  number must be within the tolerance the text between the two blocks states ("within 1 %")
  or within half a unit of its last digit.
- :data:`NOT_RUN` lists what cannot run here, with the reason; everything else must exit 0.
- ``.venv/bin/exo-ctrl`` commands run in a child forked from the test's process, which calls
  the console script's entry point (``exo_ctrl.cli:main``, ``[project.scripts]``) with the words
  the shell would pass, in the page's directory, with the page's environment and a new
  interpreter's warning filters, its stdout and stderr captured apart and its exit code the
  child's: the command as written, without a new interpreter's start-up (about 1.5 s a
  command: importing, numba's registries, the cached kernels).  The console script itself runs
  in the CLI tests (tests/cli/).  Every other command runs in a shell.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from exo_ctrl.cli import main as exo_ctrl_main

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
SHELL_BLOCKS = frozenset({"bash", "sh", "shell", "console"})
SHORT = ("--duration", "0.5")
SHORTENED = frozenset({"simulate", "sweep", "compare"})
#: Runs that need whole cycles, run as written: the calibration exercise (identify fits all
#: of it), assist-as-needed and path control (they need a gait period after the ramp-in).
FULL_RUNS = frozenset({"calibration", "aan", "path"})
#: The console script, run in a forked child (module docstring).
CONSOLE_SCRIPT = ".venv/bin/exo-ctrl"
#: The longest a command may take [s].
TIMEOUT_S = 900
TOLERANCE = re.compile(r"within (\d+(?:\.\d+)?) ?%")
NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w.])")
#: What is not run, and why: (pattern on a command, reason).
NOT_RUN = (
    (r"^python3 -m venv \.venv$", "creates the environment the test runs in"),
    (r"^\.venv/bin/pip install ", "installs the package the test runs"),
    (r"^\.venv/bin/python -m pytest\b", "the test suite itself"),
    (r"^\.venv/bin/rerun (?!rrd )", "opens the viewer, or serves it, until it is closed"),
    (
        r"^\.venv/bin/python tools/(bench|bench_sweep|tick_profile|compile_profile|faults"
        r"|load_held|touchdowns|robustness|modes|path_wall)\.py\b",
        "a benchmark or a campaign of several minutes",
    ),
)


@dataclass
class Block:
    """A runnable fenced block, and the output block that quotes what it prints."""

    lang: str
    body: str
    line: int
    quoted: str | None = None
    tolerance: float | None = None
    commands: list[str] = field(default_factory=list)


def page_blocks(text: str) -> list[Block]:
    """The runnable blocks of a Markdown text, each with its quoted output and tolerance."""
    found: list[Block] = []
    matches = list(FENCE.finditer(text))
    for i, m in enumerate(matches):
        lang, body = m.group(1), m.group(2)
        if lang == "output":
            if not found or i == 0 or matches[i - 1].group(1) not in SHELL_BLOCKS | {"python"}:
                raise AssertionError(f"an output block must follow a command block: {body!r}")
            between = text[matches[i - 1].end() : m.start()]
            tol = TOLERANCE.search(between)
            found[-1].quoted = body
            found[-1].tolerance = float(tol.group(1)) / 100 if tol else None
        elif lang in SHELL_BLOCKS or lang == "python":
            block = Block(lang, body, text.count("\n", 0, m.start()) + 1)
            if lang != "python":
                block.commands = [
                    s.strip()
                    for s in body.splitlines()
                    if s.strip() and not s.strip().startswith("#")
                ]
            found.append(block)
    return found


def not_run(command: str) -> str | None:
    """Why a command (one part of an ``&&`` chain) is not run, or None."""
    for pattern, reason in NOT_RUN:
        if re.search(pattern, command):
            return reason
    return None


def short_form(words: list[str]) -> list[str]:
    """An ``exo-ctrl simulate|sweep|compare`` command cut to a short run (module docstring)."""
    if len(words) < 2 or not words[0].endswith("exo-ctrl") or words[1] not in SHORTENED:
        return words
    if FULL_RUNS & set(words):
        return words
    out, skip = [], False
    for word in words:
        if skip:
            skip = False
        elif word in ("--duration", "--cycles"):
            skip = True
        else:
            out.append(word)
    return [*out, *SHORT]


def decimals(number: str) -> int:
    """Digits after the point of a printed number (mantissa only)."""
    mantissa = re.split("[eE]", number)[0]
    return len(mantissa.split(".")[1]) if "." in mantissa else 0


def skeleton(line: str) -> str:
    """A line with its numbers replaced and its spacing normalised."""
    return " ".join(NUMBER.sub("#", line).split())


def compare_quoted(quoted: str, printed: str, tolerance: float) -> list[str]:
    """Where the printed output differs from the quoted one ([] when it matches)."""
    problems, lines, at = [], printed.splitlines(), 0
    for want in (q for q in quoted.splitlines() if q.strip()):
        shape = skeleton(want)
        hit = next((i for i in range(at, len(lines)) if skeleton(lines[i]) == shape), None)
        if hit is None:
            problems.append(f"quoted line not printed (in order): {want.strip()!r}")
            continue
        at = hit + 1
        for e, a in zip(NUMBER.findall(want), NUMBER.findall(lines[hit]), strict=True):
            bound = max(tolerance * abs(float(e)), 0.5 * 10.0 ** -decimals(e))
            if not math.isclose(float(a), float(e), rel_tol=0.0, abs_tol=bound * (1 + 1e-9)):
                problems.append(
                    f"{want.strip()!r}: quoted {e}, printed {a} (tolerance {bound:.3g})"
                )
    return problems


def workdir(tmp: Path) -> Path:
    """A directory with the repository's environment, tools and models linked in."""
    local = ROOT / ".venv"
    (tmp / ".venv").symlink_to(local if local.is_dir() else Path(sys.prefix))
    for name in ("tools", "urdf", "examples"):
        (tmp / name).symlink_to(ROOT / name)
    return tmp


def fresh_warnings() -> None:
    """The warnings' filters and printing of a new interpreter, in place of the test's.

    pytest records the warnings of each test and shows deprecations ``always``; a
    command started from a shell has Python's default filters and prints to stderr.
    """
    warnings.resetwarnings()
    for category in (ResourceWarning, ImportWarning, PendingDeprecationWarning, DeprecationWarning):
        warnings.simplefilter("ignore", category)  # each put first: Python's order
    warnings.filterwarnings("default", category=DeprecationWarning, module="__main__")

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))

    warnings.showwarning = show


def run_forked(words: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    """``words`` (``.venv/bin/exo-ctrl …``) run in a forked child (module docstring)."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:  # the child: never returns into the test
            code = 1
            try:
                os.chdir(cwd)
                os.environ.clear()
                os.environ.update(env)
                stdin = os.open(os.devnull, os.O_RDONLY)
                for fd, target in ((stdin, 0), (out.fileno(), 1), (err.fileno(), 2)):
                    os.dup2(fd, target)
                sys.stdin = open(0, closefd=False)  # noqa: SIM115
                sys.stdout = open(1, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
                sys.stderr = open(2, "w", encoding="utf-8", closefd=False)  # noqa: SIM115
                sys.argv = list(words)
                fresh_warnings()
                code = exo_ctrl_main(words[1:])
            except SystemExit as exc:  # as the interpreter ends on it: None 0, a text 1
                code = 0 if exc.code is None else exc.code if isinstance(exc.code, int) else 1
                if not isinstance(exc.code, int | None):
                    print(exc.code, file=sys.stderr)
            except BaseException:
                traceback.print_exc()
            finally:
                for stream in (sys.stdout, sys.stderr):
                    with contextlib.suppress(OSError, ValueError):
                        stream.flush()
                os._exit(code)
        deadline = time.monotonic() + TIMEOUT_S
        while True:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                break
            if time.monotonic() > deadline:
                os.kill(pid, 9)
                os.waitpid(pid, 0)
                raise AssertionError(f"{shlex.join(words)} ran over {TIMEOUT_S} s")
            time.sleep(0.01)
        texts = []
        for f in (out, err):
            f.seek(0)
            texts.append(f.read().decode("utf-8", errors="replace"))
    return subprocess.CompletedProcess(words, os.waitstatus_to_exitcode(status), *texts)


def run_command(command: str, cwd: Path, env: dict[str, str], shorten: bool) -> tuple[str, list]:
    """Run one line (an ``&&`` chain part by part); its output and the parts not run."""
    output, skipped = [], []
    for part in (p.strip() for p in command.split("&&")):
        reason = not_run(part)
        if reason:
            skipped.append((part, reason))
            continue
        words = shlex.split(part)
        if shorten:
            words = short_form(words)
        if words[0] == CONSOLE_SCRIPT:
            done = run_forked(words, cwd, env)
        else:
            done = subprocess.run(
                shlex.join(words),
                shell=True,
                cwd=cwd,
                env=env,
                capture_output=True,
                text=True,
                timeout=TIMEOUT_S,
            )
        assert done.returncode == 0, (
            f"{shlex.join(words)} exited {done.returncode}:\n{done.stdout[-2000:]}"
            f"\n{done.stderr[-2000:]}"
        )
        output.append(done.stdout + done.stderr)
    return "".join(output), skipped


@pytest.mark.heavy
@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(ROOT).as_posix() for p in PAGES])
def test_the_page_runs_as_written(page, tmp_path):
    cwd = workdir(tmp_path)
    env = {**os.environ, "EXO_CTRL_WARMUP": "0", "MPLBACKEND": "Agg"}
    problems = []
    for block in page_blocks(page.read_text(encoding="utf-8")):
        where = f"{page.name}:{block.line}"
        if block.quoted is not None and block.tolerance is None:
            problems.append(f"{where}: the text before its output block states no tolerance")
            continue
        printed = []
        try:
            if block.lang == "python":
                script = cwd / f"block_{block.line}.py"
                script.write_text(block.body, encoding="utf-8")
                printed.append(run_command(f".venv/bin/python {script.name}", cwd, env, False)[0])
            for command in block.commands:
                printed.append(run_command(command, cwd, env, block.quoted is None)[0])
        except AssertionError as exc:
            problems.append(f"{where}: {exc}")
            continue
        if block.quoted is not None:
            problems += [
                f"{where}: {p}"
                for p in compare_quoted(block.quoted, "".join(printed), block.tolerance)
            ]
    assert not problems, "\n".join(problems)


def test_what_is_not_run_is_shown_and_listed():
    """Every NOT_RUN pattern matches a shown command (no stale entry), and nothing else is left."""
    parts = [
        part.strip()
        for page in PAGES
        for block in page_blocks(page.read_text(encoding="utf-8"))
        for command in block.commands
        for part in command.split("&&")
    ]
    for pattern, reason in NOT_RUN:
        assert any(re.search(pattern, p) for p in parts), (pattern, reason)
    assert ".venv/bin/rerun exo_run.rrd" in parts
    assert not_run(".venv/bin/rerun rrd verify exo_run.rrd") is None


X = ".venv/bin/exo-ctrl"


@pytest.mark.parametrize(
    ("words", "expected"),
    [
        (f"{X} simulate --out a.rrd", f"{X} simulate --out a.rrd --duration 0.5"),
        (f"{X} simulate --cycles 3 --no-record", f"{X} simulate --no-record --duration 0.5"),
        (f"{X} sweep --duration 6 --out s.parquet", f"{X} sweep --out s.parquet --duration 0.5"),
        (f"{X} simulate --exercise calibration", f"{X} simulate --exercise calibration"),
        (f"{X} simulate --mode aan --duration 6", f"{X} simulate --mode aan --duration 6"),
        (f"{X} urdf --kind exo --out e.urdf", f"{X} urdf --kind exo --out e.urdf"),
    ],
)
def test_the_short_form(words, expected):
    assert " ".join(short_form(words.split())) == expected


def test_a_drifted_figure_fails_and_a_kept_one_passes():
    printed = (
        "header\n  peak drive torque  118.8 N·m   (paper: about 100 N·m)\n  residual 3.5e-16\n"
    )
    assert compare_quoted("peak drive torque 118.8 N·m (paper: about 100 N·m)", printed, 0.01) == []
    assert compare_quoted("peak drive torque 119.9 N·m (paper: about 100 N·m)", printed, 0.01) == []
    assert compare_quoted("peak drive torque 121.0 N·m (paper: about 100 N·m)", printed, 0.01) == [
        "'peak drive torque 121.0 N·m (paper: about 100 N·m)': quoted 121.0, printed 118.8 "
        "(tolerance 1.21)"
    ]
    assert compare_quoted("peak cuff force 96 N", printed, 0.01) == [
        "quoted line not printed (in order): 'peak cuff force 96 N'"
    ]
    # a figure quoted with no decimals is held to half a unit when the tolerance is smaller
    assert compare_quoted("share 0.0, 0.0", "share 0.04, 0.0", 0.01) == []


def test_blocks_quotes_and_tolerances_are_read():
    text = (
        "```bash\n# c\n.venv/bin/exo-ctrl gait --csv g.csv\n```\n\nprints (within 2 %):\n\n"
        "```output\nwrote 1\n```\n\n```python\nprint(1)\n```\n\n```text\nnot run\n```\n"
    )
    blocks = page_blocks(text)
    assert [(b.lang, b.commands, b.quoted, b.tolerance) for b in blocks] == [
        ("bash", [".venv/bin/exo-ctrl gait --csv g.csv"], "wrote 1\n", 0.02),
        ("python", [], None, None),
    ]


@pytest.mark.parametrize(
    "words",
    [
        "simulate --duration -1 --no-record",
        "gait --help",
        "urdf --kind exo --out e.urdf",
        "simulate --controller nope",
    ],
)
def test_a_forked_command_is_the_console_script(words, tmp_path):
    """Exit code, stdout, stderr and the file written: the same forked as from the shell."""
    runs = []
    for how in ("forked", "shell"):
        (tmp_path / how).mkdir()
        cwd = workdir(tmp_path / how)
        command = [CONSOLE_SCRIPT, *words.split()]
        env = {**os.environ, "EXO_CTRL_WARMUP": "0"}
        if how == "forked":
            done = run_forked(command, cwd, env)
        else:
            done = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True)
        written = (cwd / "e.urdf").read_text() if (cwd / "e.urdf").exists() else None
        runs.append((done.returncode, done.stdout, done.stderr, written))
    assert runs[0] == runs[1]
    assert runs[0][0] == (2 if "-1" in words or "nope" in words else 0)


def test_a_forked_command_has_a_new_interpreters_warning_filters():
    shape = (
        "[(a, getattr(m, 'pattern', m), c.__name__, getattr(mod, 'pattern', mod), n)"
        " for a, m, c, mod, n in warnings.filters]"
    )
    new = subprocess.run(
        [sys.executable, "-c", f"import warnings; print(repr({shape}))"],
        capture_output=True,
        text=True,
        env={k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"},
    ).stdout.strip()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # as a test may have left them
        fresh_warnings()
        forked = repr(eval(shape))
    assert forked == new


@pytest.mark.parametrize("code", [None, 0, 3, "a message"])
def test_a_forked_command_ends_on_system_exit_as_an_interpreter_does(code, tmp_path, monkeypatch):
    def leave(words):
        raise SystemExit(code)

    monkeypatch.setattr(sys.modules[__name__], "exo_ctrl_main", leave)
    forked = run_forked([CONSOLE_SCRIPT], tmp_path, dict(os.environ))
    shell = subprocess.run(
        [sys.executable, "-c", f"raise SystemExit({code!r})"], capture_output=True, text=True
    )
    assert (forked.returncode, forked.stdout, forked.stderr) == (
        shell.returncode,
        shell.stdout,
        shell.stderr,
    )
