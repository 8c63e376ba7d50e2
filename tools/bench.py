"""Benchmark of the control tick, its Pinocchio floor and the real-time factor.

    python tools/bench.py [--ticks N] [--json PATH] [--controllers pd,ct,...]

For each controller: the cost of one control tick (sensors, estimator,
controller, safety supervisor, plant step, logging: exactly
``Runner.tick``), median and p99 over the default scenario; the floor, the
library calls the tick makes timed alone in the same run (see
:func:`floor_calls`); their ratio; and the real-time factor of the default
run (simulated time / wall time), without and with a rerun recording.  For
the QP also the median of its own update + solve + checks in the loop: the
floor's warm update + solve of an already solved problem takes no iteration,
a tick's solve takes a few (and one more solve when its screened rows are
widened).
Absolute times drift on shared machines; the ratio is the figure to compare.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl.simulate import Runner, SimConfig, build, simulate


def _time_calls(calls, repeats: int = 2000) -> float:
    """Median time of running ``calls`` once each [µs]."""
    samples = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter_ns()
        for call in calls:
            call()
        samples[i] = time.perf_counter_ns() - t0
    return float(np.median(samples)) / 1e3


def floor_calls(runner: Runner) -> list:
    """The library calls one tick makes (Pinocchio, proxsuite), as zero-argument callables.

    Plant: one ABA of the model holding both bodies.  Estimator: CRBA,
    Coriolis matrix and gravity of the exoskeleton.  CT: none (its
    feedforward is tabulated along the plan when the controller is built).
    QP: the cuff model's CRBA and non-linear effects of both bodies, the
    patient's joint Jacobians and four frame Jacobians, and the proxsuite
    update + solve (a warm re-solve of the tick's problem, its data passed
    again as the tick does).  Each is called with the present state.
    """
    setup = runner.setup
    plant = setup.plant
    q, v, tau = plant.q.copy(), plant.v.copy(), np.zeros(8)
    qe, ve = q[:4].copy(), v[:4].copy()
    pm, pd = plant._model, plant._data
    calls = [
        lambda: pin.aba(pm, pd, q, v, tau),
    ]
    est = runner.estimator
    em, ed = est._model, est._data
    calls += [
        lambda: pin.crba(em, ed, qe),
        lambda: pin.computeCoriolisMatrix(em, ed, qe, ve),
        lambda: pin.computeGeneralizedGravity(em, ed, qe),
    ]
    ctrl = setup.controller
    model = getattr(ctrl, "cuff_model", None)
    if model is not None:
        cm = model
        calls += [
            lambda: pin.crba(cm._me, cm._de, qe),
            lambda: pin.crba(cm._mp, cm._dp, qe),
            lambda: pin.nonLinearEffects(cm._me, cm._de, qe, ve),
            lambda: pin.nonLinearEffects(cm._mp, cm._dp, qe, ve),
            lambda: pin.computeJointJacobians(cm._mp, cm._dp, qe),
        ]
        calls += [
            (lambda f=f: pin.getFrameJacobian(cm._mp, cm._dp, f, pin.LOCAL_WORLD_ALIGNED))
            for f in cm._cuffs
        ]
        calls.append(ctrl.qp.update_and_solve)
    return calls


def bench_controller(name: str, ticks: int) -> dict[str, float]:
    config = SimConfig(controller=name)
    setup = build(config)
    runner = Runner(setup)
    n = min(ticks, config.n_ticks)
    samples = np.empty(n)
    chunk = runner.chunk
    solve = np.zeros(n)  # the QP's own update + solve + checks, in the loop [µs]
    ctrl = setup.controller
    for k in range(n):
        t0 = time.perf_counter_ns()
        runner.tick(k, k % chunk)
        samples[k] = time.perf_counter_ns() - t0
        solve[k] = getattr(ctrl, "solve_time_us", 0.0)
    tick = samples[n // 10 :] / 1e3  # skip warm-up
    floor = _time_calls(floor_calls(runner))
    rtf = simulate(config).summary()["real_time_factor"]
    with tempfile.TemporaryDirectory() as tmp:
        try:
            from exo_ctrl.record import RerunRecorder

            rec = simulate(config, observers=[RerunRecorder(Path(tmp) / "b.rrd")])
            rtf_rec = rec.summary()["real_time_factor"]
        except ImportError:
            rtf_rec = float("nan")
    median = float(np.median(tick))
    extra = {}
    if hasattr(ctrl, "solve_time_us"):
        extra["qp_solve_in_loop_median_us"] = float(np.median(solve[n // 10 :]))
    return {
        "tick_median_us": median,
        "tick_p99_us": float(np.percentile(tick, 99)),
        "floor_us": floor,
        "ratio": median / floor,
        "real_time_factor": rtf,
        "real_time_factor_recording": rtf_rec,
        **extra,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=2400, help="ticks to time (default 2400)")
    parser.add_argument(
        "--controllers", default="pd,ct,qp", help="comma-separated (default pd,ct,qp)"
    )
    parser.add_argument("--json", default=None, metavar="PATH", help="write the figures as JSON")
    args = parser.parse_args()
    results = {}
    print(
        f"{'controller':<11}{'tick median':>12}{'tick p99':>10}{'floor':>8}{'ratio':>7}"
        f"{'RTF':>7}{'RTF rec':>9}"
    )
    for name in args.controllers.split(","):
        r = bench_controller(name.strip(), args.ticks)
        results[name] = r
        print(
            f"{name:<11}{r['tick_median_us']:>10.1f}µs{r['tick_p99_us']:>8.1f}µs"
            f"{r['floor_us']:>6.1f}µs{r['ratio']:>7.1f}{r['real_time_factor']:>7.1f}"
            f"{r['real_time_factor_recording']:>9.1f}"
        )
        if "qp_solve_in_loop_median_us" in r:
            print(
                f"{'':<11}QP update + solve in the loop: median "
                f"{r['qp_solve_in_loop_median_us']:.1f} µs "
                "(the floor's warm re-solve takes no iteration)"
            )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
