"""Benchmark of sweep throughput: simulations per second with 1 and 2 local workers.

    .venv/bin/python tools/bench_sweep.py [--runs 8] [--duration 2.4] [--repeats 3] [--workers 1,2]

The same grid (``--runs`` step lengths from 0.30 to 0.37 m, the default
scenario otherwise, ``--duration`` simulated seconds each) runs on a local
spawn process pool of each size, through :func:`exo_ctrl.sweep.run_sweep`
(journal, table and all, into a fresh folder each time: no resume).

- warm: the pool is started and every worker has run a short simulation
  (imports and first-call set-up done) before the clock starts: the
  steady-state rate of a long sweep.  Best of ``--repeats``, the pool sizes
  taking turns so that a change in the machine's load hits them alike.
- cold: the pool is started with the clock (interpreters spawned, numpy,
  Pinocchio and the package imported), as a short command-line sweep sees
  it.  One sweep per size, measured first.

Also printed per size: the CPU time per run (measured in the workers; it
does not change with the pool size unless the runs contend), the cores the
sweep got (worker CPU time / wall time: 2 workers on an idle 2-core machine
should get ~2), and the 1-minute load average.  On a shared machine other
jobs take cores and the wall-clock ratio drops while the CPU per run stays
put; the ratio is only meaningful when ``cores got`` is close to the worker
count.  Target: warm ratio 2 workers / 1 worker >= 1.8 on an idle 2-core
machine.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import multiprocessing
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl.sweep import SweepSpec, run_point, run_sweep


def _cpu_timed(fn, *args, **kwargs):
    """Run ``fn`` in the worker; return (its result, the worker's CPU time for it [s])."""
    start = time.process_time()
    result = fn(*args, **kwargs)
    return result, time.process_time() - start


class _CPUTiming(cf.Executor):
    """Wraps an executor; adds up the CPU time of every call made on it."""

    def __init__(self, inner: cf.Executor) -> None:
        self.inner = inner
        self.cpu_s = 0.0

    def submit(self, fn, /, *args, **kwargs):
        outer: cf.Future = cf.Future()

        def unwrap(inner: cf.Future) -> None:
            try:
                result, cpu = inner.result()
            except BaseException as exc:
                outer.set_exception(exc)
                return
            self.cpu_s += cpu
            outer.set_result(result)

        self.inner.submit(_cpu_timed, fn, *args, **kwargs).add_done_callback(unwrap)
        return outer


def _warm(_: int) -> int:
    """Run a tiny simulation in a worker (imports, lazy set-up); return its pid."""
    spec = SweepSpec.parse(["step_length=0.35"], duration_s=0.05)
    run_point(spec.base, spec.tasks()[0].values, tempfile.gettempdir())
    time.sleep(0.5)  # keep this worker busy so that the next warm-up starts another
    return os.getpid()


def _pool(workers: int, warm: bool) -> cf.ProcessPoolExecutor:
    pool = cf.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
    pids: set[int] = set()
    while warm and len(pids) < workers:
        pids |= set(pool.map(_warm, range(workers)))
    return pool


def _sweep(spec: SweepSpec, pool: cf.Executor, workers: int) -> tuple[float, float]:
    """(wall time [s], worker CPU time [s]) of one sweep on ``pool``."""
    timed = _CPUTiming(pool)
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        table = run_sweep(
            spec,
            Path(folder) / "bench.parquet",
            executor=timed,
            workers=workers,
            progress=False,
            plots=False,
            report=False,
        )
        elapsed = time.perf_counter() - start
    statuses = set(table.column("status").to_pylist())
    if statuses != {"completed"}:
        raise SystemExit(f"bench_sweep: runs did not complete: {statuses}")
    return elapsed, timed.cpu_s


def _cold(spec: SweepSpec, workers: int) -> float:
    """Wall time [s] of a sweep on a pool started with the clock."""
    start = time.perf_counter()
    with _pool(workers, warm=False) as pool:
        _sweep(spec, pool, workers)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8, help="runs in the grid (default 8)")
    parser.add_argument("--duration", type=float, default=2.4, help="simulated s per run")
    parser.add_argument("--repeats", type=int, default=3, help="warm sweeps per size (best)")
    parser.add_argument("--workers", default="1,2", help="pool sizes (default 1,2)")
    args = parser.parse_args()
    spec = SweepSpec.parse([f"step_length=0.30:0.37:{args.runs}"], duration_s=args.duration)
    sizes = [int(x) for x in args.workers.split(",")]
    print(
        f"grid: {args.runs} runs of {args.duration:g} s simulated (default scenario, step "
        f"length 0.30-0.37 m); {os.cpu_count()} CPUs; load average {os.getloadavg()[0]:.2f}"
    )
    cold = {n: _cold(spec, n) for n in sizes}
    pools = {n: _pool(n, warm=True) for n in sizes}
    try:
        warm: dict[int, list[tuple[float, float]]] = {n: [] for n in sizes}
        for _ in range(args.repeats):
            for n in sizes:
                warm[n].append(_sweep(spec, pools[n], n))
    finally:
        for pool in pools.values():
            pool.shutdown()
    rates = {}
    for n in sizes:
        wall, cpu = min(warm[n])
        rates[n] = (args.runs / wall, args.runs / cold[n])
        print(
            f"{n} worker{'s' if n > 1 else ' '}: warm {rates[n][0]:5.2f} sims/s ({wall:.2f} s; "
            f"CPU {cpu / args.runs:.3f} s/run; cores got {cpu / wall:.2f}), "
            f"cold {rates[n][1]:5.2f} sims/s ({cold[n]:.2f} s incl. pool start)"
        )
    for n in sizes:
        if n != 1 and 1 in rates:
            print(
                f"speed-up {n} vs 1 worker: warm {rates[n][0] / rates[1][0]:.2f}x, "
                f"cold {rates[n][1] / rates[1][1]:.2f}x; load average now {os.getloadavg()[0]:.2f}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
