"""Stage-by-stage cost of one control tick (``Runner.tick``), for the scenarios of ``bench.py``.

    .venv/bin/python tools/tick_profile.py [--scenarios pd,ct] [--ticks N]

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
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import defaultdict
from pathlib import Path

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
    """Median per-tick cost of each stage of scenario ``name`` [µs]."""
    config = SimConfig(**SCENARIOS[name])
    setup = build(config)
    runner = Runner(setup)
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
    for kname in ("write_measured", "write_applied", "read_belt", "write_plan"):
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=2400)
    parser.add_argument("--scenarios", default="pd,ct")
    args = parser.parse_args()
    for name in args.scenarios.split(","):
        out = profile(name.strip(), args.ticks)
        print(f"{name}:")
        for key, value in out.items():
            print(f"  {key:<28}{value:7.2f} µs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
