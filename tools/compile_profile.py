"""Where the first run after an install spends its time: imports, each kernel's compile, the run.

    .venv/bin/python tools/compile_profile.py [--scenarios pd,ct,qp] [--top N] [--duration S]
    .venv/bin/python tools/compile_profile.py --cli [-- simulate options]

For each scenario of ``bench.py`` a fresh process with a fresh, empty numba
cache directory (``NUMBA_CACHE_DIR``: a cold start, as
``.venv/bin/python tools/bench.py --cold``)
imports the libraries one by one (numpy + numba, pinocchio, proxsuite,
rerun, then ``exo_ctrl`` itself), builds the run (``sim.build``: models,
plan, components; kernels called while building compile here), and runs
``simulate`` for ``--duration`` seconds of simulated time (the kernels of the
tick compile on their first call).

Every compile is recorded through numba's public event API
(``numba.core.event``, the ``"numba:compile"`` event, which numba raises
only when it compiles, not when it loads from the cache).  A kernel that
calls another kernel has the callee compiled inside its own typing, so the
events nest; the table gives per kernel (``module.function``):

- ``n``: the number of signatures it compiled (more than one: the same
  kernel specialised for several argument types);
- ``self``: the time of its own compiles, callees' compiles left out [s];
- ``incl``: with the callees compiled on its behalf [s];
- ``from``: ``py`` when first compiled by a call (or ``preload``) from
  Python, else the kernel whose typing compiled it.

Then the phases (wall and CPU time): imports, build, first run (its
compiles and the rest), and the sum of every compile.  The figures are wall
times on a shared machine: compare within one invocation, or repeat (the CPU
times vary less when other processes load the machine).

``--cli`` profiles the command a user runs first instead, ``exo-ctrl
simulate`` (default: the default run, recorded to a temporary file; options
after ``--`` are passed on), in a fresh process with an empty cache, then
once more with the cache it filled (the second run of an install), and
prints both runs' wall times.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench import SCENARIOS

from exo_ctrl._io import output_problem
from exo_ctrl.cli.common import write_json

ROOT = Path(__file__).resolve().parents[1]

# The child: time the imports, install the listener, build, run; print JSON.
_CHILD = r"""
import json, sys, time
sys.path.insert(0, {root!r})
clock = time.perf_counter
cpu = time.process_time
phases = {{}}
cpu_phases = {{}}
t, c = clock(), cpu()
import numpy, numba
from numba.core import event
phases["import numpy+numba"], cpu_phases["import numpy+numba"] = clock() - t, cpu() - c
for mod in ("pinocchio", "proxsuite", "rerun"):
    t, c = clock(), cpu()
    __import__(mod)
    phases["import " + mod], cpu_phases["import " + mod] = clock() - t, cpu() - c
t, c = clock(), cpu()
from exo_ctrl.sim import SimConfig, build, simulate
from exo_ctrl.plant import BeltParams, ContactParams, PelvisParams
from exo_ctrl.plan import GaitParams
phases["import exo_ctrl"], cpu_phases["import exo_ctrl"] = clock() - t, cpu() - c


class Compiles(event.Listener):
    def __init__(self):
        self.stack, self.rows = [], []

    def on_start(self, ev):
        d = ev.data["dispatcher"]
        name = d.py_func.__module__.removeprefix("exo_ctrl.") + "." + d.py_func.__qualname__
        sig = ", ".join(str(a) for a in ev.data["args"])
        parent = self.stack[-1][0] if self.stack else "py"
        self.stack.append([name, sig, parent, clock(), 0.0])

    def on_end(self, ev):
        name, sig, parent, t0, callees = self.stack.pop()
        dt = clock() - t0
        if self.stack:
            self.stack[-1][4] += dt
        self.rows.append(dict(name=name, sig=sig, parent=parent, incl=dt, self=dt - callees))


listener = Compiles()
event.register("numba:compile", listener)
cli = {cli!r}
n_build = 0
if cli is None:
    config = SimConfig(**{overrides}, duration_s={duration!r})
    t, c = clock(), cpu()
    build(config)
    phases["build (models, plan)"], cpu_phases["build (models, plan)"] = clock() - t, cpu() - c
    n_build = len(listener.rows)
    t, c = clock(), cpu()
    simulate(config)
    phases["simulate"], cpu_phases["simulate"] = clock() - t, cpu() - c
else:
    from exo_ctrl.cli import main
    t, c = clock(), cpu()
    import contextlib, io
    with contextlib.redirect_stdout(io.StringIO()):
        main(cli)
    phases["exo-ctrl " + cli[0]], cpu_phases["exo-ctrl " + cli[0]] = clock() - t, cpu() - c
print(json.dumps(dict(phases=phases, cpu_phases=cpu_phases, rows=listener.rows, n_build=n_build)))
"""


def profile(name: str, duration: float, cli: list[str] | None = None, runs: int = 1) -> dict:
    """Phases and compile rows of one scenario in a fresh process with an empty cache.

    With ``cli`` (the arguments of ``exo-ctrl``) that command instead; with
    ``runs`` > 1 it is run again in new processes on the cache the first
    filled, and their results are in ``later`` (a list).
    """
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        overrides = SCENARIOS.get(name, {})
        code = _CHILD.format(root=str(ROOT), overrides=overrides, duration=duration, cli=cli)
        results = []
        for _ in range(runs):
            run = subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=False
            )
            if run.returncode:
                raise SystemExit(run.stderr)
            results.append(json.loads(run.stdout.splitlines()[-1]))
            results[-1]["stderr"] = run.stderr
        return {**results[0], "later": results[1:]}


def kernel_table(rows: list[dict]) -> list[dict]:
    """Per kernel: signatures compiled, self and inclusive seconds, who compiled it first."""
    table: dict[str, dict] = {}
    for row in rows:
        entry = table.setdefault(
            row["name"],
            dict(name=row["name"], n=0, self=0.0, incl=0.0, parent=row["parent"], sigs=[]),
        )
        entry["n"] += 1
        entry["self"] += row["self"]
        entry["incl"] += row["incl"]
        entry["sigs"].append(row["sig"])
    return sorted(table.values(), key=lambda e: -e["self"])


def report(name: str, data: dict, top: int, signatures: bool) -> None:
    """Print one scenario's phases and its kernel table."""
    rows = data["rows"]
    total = sum(r["self"] for r in rows)
    build_compile = sum(r["self"] for r in rows[: data["n_build"]])
    kernels = kernel_table(rows)
    print(f"\n== {name}: {len(kernels)} kernels, {len(rows)} compiles, {total:.1f} s compiling")
    if data["later"]:
        print(
            f"  total wall: first run {sum(data['phases'].values()):.2f} s, then "
            + ", ".join(f"{sum(d['phases'].values()):.2f} s" for d in data["later"])
            + " (cache filled)"
        )
    print(f"  {'phase':<24}{'wall':>9}{'CPU':>9}")
    for phase, secs in data["phases"].items():
        extra = ""
        if phase.startswith("build"):
            extra = f"   (compiling {build_compile:.1f} s)"
        elif phase == "simulate":
            extra = f"   (compiling {total - build_compile:.1f} s)"
        print(f"  {phase:<24}{secs:>7.2f} s{data['cpu_phases'][phase]:>7.2f} s{extra}")
    print(f"  {'kernel':<44}{'n':>3}{'self':>8}{'incl':>8}  from")
    for e in kernels[:top]:
        print(f"  {e['name']:<44}{e['n']:>3}{e['self']:>7.2f}s{e['incl']:>7.2f}s  {e['parent']}")
        if signatures and e["n"] > 1:
            for sig in e["sigs"]:
                print(f"      ({sig})")
    rest = kernels[top:]
    if rest:
        print(f"  ... {len(rest)} more kernels, {sum(e['self'] for e in rest):.2f} s")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default="pd", help="comma-separated names of bench.py's")
    parser.add_argument("--top", type=int, default=25, help="kernels to list (default 25)")
    parser.add_argument(
        "--duration", type=float, default=0.05, help="simulated time of the run [s] (0.05)"
    )
    parser.add_argument(
        "--signatures", action="store_true", help="list the signatures of kernels compiled twice+"
    )
    parser.add_argument("--json", default=None, metavar="PATH", help="write the raw rows as JSON")
    parser.add_argument(
        "--cli",
        action="store_true",
        help="profile `exo-ctrl simulate` (the default run; options after -- passed on)",
    )
    parser.add_argument("rest", nargs="*", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.json is not None and (problem := output_problem(args.json)):
        print(f"compile_profile: --json {args.json}: {problem}", file=sys.stderr)
        return 2
    if args.cli:
        with tempfile.TemporaryDirectory() as tmp:
            cli = ["simulate", "--out", str(Path(tmp) / "run.rrd"), *args.rest]
            data = profile("cli", args.duration, cli=cli, runs=2)
        report("exo-ctrl " + " ".join(cli[3:] or ["simulate"]), data, args.top, args.signatures)
        notice = [line for line in data["stderr"].splitlines() if line.strip()]
        print("  stderr of the first run:", *(f"    {line}" for line in notice), sep="\n")
        if args.json is not None:
            write_json(args.json, {"cli": data})
        return 0
    names = [n.strip() for n in args.scenarios.split(",")]
    unknown = [n for n in names if n not in SCENARIOS]
    if unknown:
        parser.error(f"--scenarios: unknown {unknown}; allowed: {', '.join(SCENARIOS)}")
    out = {}
    for name in names:
        out[name] = profile(name, args.duration)
        report(name, out[name], args.top, args.signatures)
    if args.json is not None:
        write_json(args.json, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
