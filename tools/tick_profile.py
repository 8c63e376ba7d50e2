"""Stage-by-stage cost of one control tick (``Runner.tick``), for the scenarios of ``bench.py``.

    .venv/bin/python tools/tick_profile.py [--scenarios pd,ct] [--ticks N]
    .venv/bin/python tools/tick_profile.py --boundary [--scenarios pd,ct,qp]
    .venv/bin/python tools/tick_profile.py --fusion [--scenarios pd,ct,qp]

Runs the scenario's ticks through :meth:`Runner.tick` with its stage calls
wrapped by a timer: each stage's per-tick method (the device's sensors read,
joints and drive currents; estimator update, controller command, supervisor
step, plant step, log writes) is replaced on the runner by a wrapper that times it, so
the tick runs its own code and the figures are the stages' costs inside it
(median per tick [µs], the timer's own cost subtracted), with the rest of
the tick (its own Python between the calls) as "tick body".  The Pinocchio
calls inside a stage are timed the same way (the ``pinocchio`` functions the
stages' modules call, wrapped), so each stage's own overhead (its Python
and compiled work beside the library) shows.

The figures are medians over the ticks after the first tenth; the machine is
noisy, so compare within one run.

``--boundary`` splits the tick instead into what it is made of (:func:`anatomy`):
the library calls (``bench.py``'s floor), the compiled kernels' own work,
the cost of crossing into them (numba's dispatch: typing and unboxing each
argument, measured as an empty kernel called with the same arguments), and
the Python around them (the rest).  Every kernel the tick calls from Python
is found by wrapping the numba dispatchers among the package's module
globals for a few ticks (a kernel held elsewhere, as an attribute, counts as
Python); each is then timed on copies of its last arguments, the run's state
untouched.

``--fusion`` bounds what a fused tick could gain (design.md §8: a
configuration's tick as one compiled composition of its stages' kernels
between the library calls, which numba cannot call), on the tick stage by
stage.  One tick's calls are recorded in order, Pinocchio's and the
kernels', and the kernels are grouped into the runs between library calls:
each group is what one fused call would do.  Its boundary is measured as an
empty kernel called with the group's distinct arguments (a record or an
array two kernels share is passed once), against the group's kernels' own
boundaries.  A fused tick keeps the floor and the kernels' work; at best it
also loses all the Python around the calls: floor + work + the fused
boundaries is its lower bound.  Beside it, the tick as runs use it (fused
where :mod:`exo_ctrl.sim.fused` covers the scenario).  ``--boundary`` and
the timing of the kernels split the tick as runs use it; the stages' costs
(no option) are of the tick stage by stage.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import pinocchio as pin
from bench import SCENARIOS

from exo_ctrl.sim import Runner, SimConfig, build
from exo_ctrl.sim import tick as tick_module

_NS = time.perf_counter_ns


def _timer_cost() -> float:
    """The cost of one timed empty call through a wrapper [ns]."""
    samples = []
    acc = defaultdict(int)
    f = _wrap(lambda: None, "x", acc)
    for _ in range(20000):
        t0 = _NS()
        f()
        samples.append(_NS() - t0)
    plain = []
    g = lambda: None  # noqa: E731
    for _ in range(20000):
        t0 = _NS()
        g()
        plain.append(_NS() - t0)
    return float(np.median(samples) - np.median(plain))


def _wrap(func, name, acc):
    def timed(*args, **kwargs):
        t0 = _NS()
        out = func(*args, **kwargs)
        acc[name] += _NS() - t0
        acc["#" + name] += 1
        return out

    return timed


def profile(name: str, ticks: int) -> dict[str, float]:
    """Median per-tick cost of each stage of scenario ``name`` [µs] (the tick stage by stage)."""
    config = SimConfig(**SCENARIOS[name])
    setup = build(config)
    runner = Runner(setup, fuse=False)  # the fused tick (sim/fused.py) has no stages to time
    acc: dict[str, int] = defaultdict(int)
    # Stage methods, replaced on the runner's stage tuple and objects.
    read, truth, estimate, command, supervise, step = runner._stages
    runner._stages = (
        _wrap(read, "sensors.read", acc),
        truth,
        _wrap(estimate, "estimator.update", acc),
        _wrap(command, "controller.command", acc),
        None if supervise is None else _wrap(supervise, "supervisor.step", acc),
        None if step is None else _wrap(step, "plant.step", acc),
    )
    originals = {}
    for kname in ("write_measured", "write_applied", "belt_tick", "write_plan"):
        if hasattr(tick_module, kname):
            originals[kname] = getattr(tick_module, kname)
            setattr(tick_module, kname, _wrap(originals[kname], f"log.{kname}", acc))
    pin_originals = {}
    for fname in ("aba", "crba", "nonLinearEffects", "rnea"):
        pin_originals[fname] = getattr(pin, fname)
        setattr(pin, fname, _wrap(pin_originals[fname], f"  pin.{fname}", acc))
    n = min(ticks, config.n_ticks)
    chunk = runner.chunk
    rows = []
    totals = []
    try:
        for k in range(n):
            acc.clear()
            t0 = _NS()
            runner.tick(k, k % chunk)
            totals.append(_NS() - t0)
            rows.append(dict(acc))
    finally:
        for kname, f in originals.items():
            setattr(tick_module, kname, f)
        for fname, f in pin_originals.items():
            setattr(pin, fname, f)
    cost = _timer_cost()
    skip = n // 10
    names = sorted({key for r in rows for key in r if not key.startswith("#")})
    out = {}
    for key in names:
        spent = [r.get(key, 0) - cost * r.get("#" + key, 0) for r in rows[skip:]]
        out[key] = float(np.median(spent)) / 1e3
    calls = [sum(v for key, v in r.items() if key.startswith("#")) for r in rows[skip:]]
    out["tick (timed)"] = float(np.median(totals[skip:])) / 1e3
    staged = sum(v for k, v in out.items() if not k.startswith("  ") and k != "tick (timed)")
    out["tick body (rest)"] = out["tick (timed)"] - staged - cost * float(np.median(calls)) / 1e3
    return out


def _is_kernel(obj: object) -> bool:
    return callable(obj) and hasattr(obj, "py_func") and hasattr(obj, "signatures")


def _kernel_holders(runner: Runner) -> list[tuple[object, str, object]]:
    """(holder, name, kernel) for every kernel the tick can call from Python.

    The package's module globals (a kernel of its own or imported: each call
    site looks up its own module's), and kernels the run's objects hold as
    attributes (the plant's contact solve, the cuffs' force kernel), found by
    walking the runner's objects a few levels deep.
    """
    found = []
    for mod_name, mod in list(sys.modules.items()):
        if mod_name.startswith("exo_ctrl") and mod is not None:
            found += [(mod, a, obj) for a, obj in list(vars(mod).items()) if _is_kernel(obj)]
    seen: set[int] = set()

    def walk(obj: object, depth: int) -> None:
        attrs = getattr(obj, "__dict__", None)
        if id(obj) in seen or depth > 4 or attrs is None:
            return
        seen.add(id(obj))
        for a, value in list(attrs.items()):
            if _is_kernel(value):
                found.append((obj, a, value))
            elif type(value).__module__.startswith("exo_ctrl"):
                walk(value, depth + 1)

    walk(runner, 0)
    return found


def _captured_calls(runner: Runner, start: int, ticks: int) -> dict[str, list]:
    """Kernel name → [dispatcher, calls per tick, arguments of its last call], over ``ticks``.

    Call it once the run's kernels are compiled (after a few ticks): a kernel
    typed while a callee's global is wrapped would see a Python function.
    """
    seen: dict[str, list] = {}
    patched = _kernel_holders(runner)

    def capture(name, kernel):
        def call(*args):
            entry = seen.setdefault(name, [kernel, 0, None])
            entry[1] += 1
            entry[2] = args
            return kernel(*args)

        return call

    for holder, attr, obj in patched:
        own = f"{obj.py_func.__module__.removeprefix('exo_ctrl.')}.{obj.py_func.__name__}"
        setattr(holder, attr, capture(own, obj))
    try:
        for k in range(start, start + ticks):
            runner.tick(k, k % runner.chunk)
    finally:
        for holder, attr, obj in patched:
            setattr(holder, attr, obj)
    for entry in seen.values():
        entry[1] /= ticks
    return seen


def _copied(args: tuple) -> tuple:
    """Copies of the arrays among ``args``, a record's noise ``row`` back at its block's start.

    A sensor's kernel takes its next noise sample from row ``row`` of its
    block and leaves the refill to Python when the block runs out: called
    again and again it would read past the block's end.  From row 0 a batch
    of :data:`_BATCH` calls stays inside any block (1000 rows, sensing/sensors.py).
    """
    out = []
    for a in args:
        if isinstance(a, np.ndarray):
            a = a.copy()
            if a.dtype.names and "row" in a.dtype.names and "noise" in a.dtype.names:
                a["row"] = 0
        out.append(a)
    return tuple(out)


#: Calls per timed batch (each on fresh copies of the arguments, :func:`_copied`).
_BATCH = 200


def _per_call_us(func, args: tuple, batches: int = 25) -> float:
    """Best of ``batches`` batches of :data:`_BATCH` calls on copies of ``args`` [µs a call]."""
    best = np.inf
    for _ in range(batches):
        own = _copied(args)
        t0 = _NS()
        for _ in range(_BATCH):
            func(*own)
        best = min(best, (_NS() - t0) / _BATCH)
    return best / 1e3


def _empty_kernel(n: int):
    """A compiled kernel of ``n`` arguments that does nothing (not cached)."""
    names = ", ".join(f"a{i}" for i in range(n))
    space: dict = {}
    exec(f"def empty({names}):\n    return 0\n", space)
    return numba.njit(space["empty"])


def _kind(a: object) -> str:
    if isinstance(a, np.ndarray):
        return "record" if a.dtype.names else "array"
    return "other"


def _median_tick(runner: Runner, start: int, n: int) -> tuple[float, float]:
    """Median cost of ticks ``start`` … ``start + n - 1`` [µs], and their share with a contact CRBA.

    With contact on and the pelvis fixed the plant makes a CRBA (its friction
    solve) on the steps that find a foot on the belt (``bench.py``).
    """
    samples = np.empty(n)
    contact_any = runner.setup.plant.record["contact"]["any"]
    crba = 0
    for i in range(n):
        t0 = _NS()
        runner.tick(start + i, (start + i) % runner.chunk)
        samples[i] = _NS() - t0
        crba += bool(contact_any[0])
    return float(np.median(samples)) / 1e3, crba / n


def anatomy(name: str, ticks: int, fuse: bool = True) -> dict:
    """The tick of scenario ``name`` as floor + kernels' work + call boundary + Python [µs].

    The ticks are timed before and after the kernels (the machine's speed
    drifts); the faster median is the tick's figure.  ``fuse``: the tick as
    runs use it (fused where :mod:`exo_ctrl.sim.fused` covers the scenario);
    False: stage by stage.
    """
    from bench import library_floor

    setup = build(SimConfig(**SCENARIOS[name]))
    runner = Runner(setup, fuse=fuse)
    n = min(ticks, setup.config.n_ticks // 3)
    warm = n // 10
    for k in range(warm):
        runner.tick(k, k % runner.chunk)
    before, share = _median_tick(runner, warm, n)
    floor = library_floor(runner, share)
    calls = _captured_calls(runner, warm + n, min(200, n))
    rows = []
    for kname, (kernel, per_tick, args) in sorted(calls.items()):
        real = _per_call_us(kernel, args)
        empty = _empty_kernel(len(args))
        empty(*args)
        boundary = _per_call_us(empty, args)
        kinds = [_kind(a) for a in args]
        rows.append(
            {
                "kernel": kname,
                "calls_per_tick": per_tick,
                "records": kinds.count("record"),
                "arrays": kinds.count("array"),
                "other": kinds.count("other"),
                "call_us": real,
                "boundary_us": boundary,
            }
        )
    after, _ = _median_tick(runner, warm + n + min(200, n), n)
    tick = min(before, after)
    called = sum(r["calls_per_tick"] * r["call_us"] for r in rows)
    boundary = sum(r["calls_per_tick"] * r["boundary_us"] for r in rows)
    return {
        "tick_us": tick,
        "floor_us": floor,
        "kernel_work_us": called - boundary,
        "boundary_us": boundary,
        "python_us": tick - floor - called,
        "kernels": rows,
    }


def _print_anatomy(name: str, out: dict) -> None:
    rows = out["kernels"]
    kinds = ("records", "arrays", "other")
    args = {k: sum(r["calls_per_tick"] * r[k] for r in rows) for k in kinds}
    print(
        f"{name}: tick {out['tick_us']:.1f} µs = floor {out['floor_us']:.1f} (library calls)"
        f" + kernels' work {out['kernel_work_us']:.1f} + call boundary {out['boundary_us']:.1f}"
        f" + Python {out['python_us']:.1f}"
    )
    print(
        f"  {sum(r['calls_per_tick'] for r in rows):.1f} kernel calls a tick with"
        f" {args['records']:.0f} record, {args['arrays']:.0f} array and {args['other']:.0f}"
        f" other arguments; 2x the floor leaves {out['floor_us']:.1f} µs for all but the floor"
    )
    print(f"  {'kernel':<40}{'calls/tick':>11}{'R/a/o args':>12}{'call µs':>9}{'boundary µs':>13}")
    for r in rows:
        kinds = f"{r['records']}/{r['arrays']}/{r['other']}"
        print(
            f"  {r['kernel']:<40}{r['calls_per_tick']:>11.2f}{kinds:>12}"
            f"{r['call_us']:>9.2f}{r['boundary_us']:>13.2f}"
        )


def _recorded_tick(name: str, warm: int = 300) -> tuple[Runner, list[tuple[str, object, tuple]]]:
    """One tick of scenario ``name``: its kernel and library calls in order, with arguments.

    Pinocchio's functions are wrapped before the run is built, so that the
    stages that hold them (bound at construction) hold the wrappers; the
    kernels as :func:`_captured_calls` does, after ``warm`` ticks.  The tick
    recorded is the first after ``warm`` whose kernels are those most ticks call.
    """
    order: list[tuple[str, object, tuple]] = []
    pin_originals = {}
    for fname in dir(pin):
        func = getattr(pin, fname)
        if fname[:1].islower() and type(func).__name__ in (
            "function",
            "builtin_function_or_method",
        ):
            pin_originals[fname] = func

    def library(fname, func):
        def call(*args, **kwargs):
            order.append(("library", fname, ()))
            return func(*args, **kwargs)

        return call

    for fname, func in pin_originals.items():
        setattr(pin, fname, library(fname, func))
    try:
        runner = Runner(build(SimConfig(**SCENARIOS[name])), fuse=False)
        for k in range(warm):
            runner.tick(k, k % runner.chunk)
        patched = _kernel_holders(runner)

        def capture(kname, kernel):
            def call(*args):
                order.append(("kernel", kname, args))
                return kernel(*args)

            return call

        for holder, attr, obj in patched:
            own = f"{obj.py_func.__module__.removeprefix('exo_ctrl.')}.{obj.py_func.__name__}"
            setattr(holder, attr, capture(own, obj))
        ticks = []
        try:
            for k in range(warm, warm + 40):
                order.clear()
                runner.tick(k, k % runner.chunk)
                ticks.append(list(order))
        finally:
            for holder, attr, obj in patched:
                setattr(holder, attr, obj)
    finally:
        for fname, func in pin_originals.items():
            setattr(pin, fname, func)
    patterns = [tuple(n for _, n, _ in t) for t in ticks]
    common = max(set(patterns), key=patterns.count)
    return runner, ticks[patterns.index(common)]


def paired_ticks(name: str, ticks: int, block: int = 100) -> tuple[float, float]:
    """Median tick of scenario ``name`` stage by stage and as runs use it [µs], timed in turns.

    Two runners of the same run, one with ``fuse=False``; blocks of
    ``block`` ticks alternate between them, so the machine's drift meets both.
    """
    config = SimConfig(**SCENARIOS[name])
    staged = Runner(build(config), fuse=False)
    used = Runner(build(config))
    n = min(ticks, config.n_ticks // 2)
    warm = n // 10
    for k in range(warm):
        staged.tick(k, k % staged.chunk)
        used.tick(k, k % used.chunk)
    times: tuple[list[int], list[int]] = ([], [])
    for start in range(warm, n, block):
        for runner, out in ((staged, times[0]), (used, times[1])):
            for k in range(start, min(start + block, n)):
                t0 = _NS()
                runner.tick(k, k % runner.chunk)
                out.append(_NS() - t0)
    return float(np.median(times[0])) / 1e3, float(np.median(times[1])) / 1e3


def fusion(name: str, ticks: int) -> dict:
    """The lower bound of a fused tick of scenario ``name`` (module docstring) [µs].

    Of the stage-by-stage tick; beside it the tick as runs use it and the
    stage-by-stage tick timed in turns with it (:func:`paired_ticks`).
    """
    out = anatomy(name, ticks, fuse=False)
    out["tick_staged_us"], out["tick_used_us"] = paired_ticks(name, ticks)
    _, calls = _recorded_tick(name)
    groups: list[list[tuple[str, tuple]]] = [[]]
    for kind, fname, args in calls:
        if kind == "library":
            if groups[-1]:
                groups.append([])
        else:
            groups[-1].append((fname, args))
    groups = [g for g in groups if g]
    rows = []
    for group in groups:
        apart = 0.0
        distinct: dict[int, object] = {}
        for _, args in group:
            empty = _empty_kernel(len(args))
            empty(*args)
            apart += _per_call_us(empty, args)
            for a in args:
                distinct.setdefault(id(a), a)
        args = tuple(distinct.values())
        empty = _empty_kernel(len(args))
        empty(*args)
        rows.append(([f for f, _ in group], len(args), apart, _per_call_us(empty, args)))
    fused = sum(r[3] for r in rows)
    apart = sum(r[2] for r in rows)
    bound = out["floor_us"] + out["kernel_work_us"] + fused
    out.update(groups=rows, fused_boundary_us=fused, apart_boundary_us=apart, fused_tick_us=bound)
    return out


def _print_fusion(name: str, out: dict) -> None:
    print(
        f"{name}: tick {out['tick_us']:.1f} µs (floor {out['floor_us']:.1f}, kernels' work "
        f"{out['kernel_work_us']:.1f}, boundary {out['boundary_us']:.1f}, Python "
        f"{out['python_us']:.1f}); {len(out['groups'])} kernel runs between library calls:"
    )
    for names, n_args, apart, fused in out["groups"]:
        short = ", ".join(n.rsplit(".", 1)[-1] for n in names)
        print(
            f"  [{short}]: boundary {apart:.2f} µs apart, {fused:.2f} µs in one call "
            f"({n_args} args)"
        )
    print(
        f"  fused tick at best (floor + work + fused boundaries, no Python): "
        f"{out['fused_tick_us']:.1f} µs, {out['fused_tick_us'] / out['tick_us']:.2f} of the tick; "
        f"timed in turns, stage by stage {out['tick_staged_us']:.1f} µs and as runs use it "
        f"{out['tick_used_us']:.1f} µs ({out['tick_used_us'] / out['tick_staged_us']:.2f})"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=2400)
    parser.add_argument("--scenarios", default="pd,ct")
    parser.add_argument(
        "--boundary", action="store_true", help="floor, kernels' work, call boundary, Python"
    )
    parser.add_argument(
        "--fusion", action="store_true", help="the lower bound of a fused tick (docstring)"
    )
    args = parser.parse_args()
    if args.fusion:
        for name in args.scenarios.split(","):
            _print_fusion(name.strip(), fusion(name.strip(), args.ticks))
        return 0
    if args.boundary:
        for name in args.scenarios.split(","):
            _print_anatomy(name.strip(), anatomy(name.strip(), args.ticks))
        return 0
    for name in args.scenarios.split(","):
        out = profile(name.strip(), args.ticks)
        print(f"{name}:")
        for key, value in out.items():
            print(f"  {key:<28}{value:7.2f} µs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
