"""Does the QP's cuff-force bound hold over a grid of gaits and bounds?  ("Load held", issue 19)

    .venv/bin/python tools/load_held.py [--periods 0.9,1.05,...] [--steps 0.25,...]
        [--bounds 100,125,150] [--duration S] [--workers 2] [--json PATH]
        [--truth] [--restored-bandwidth W] [--disturbance-bandwidth W]
        [--horizon-ms 5,10,20,30,40]
        [--controller-patient nominal|truth|URDF] [--controller-cuffs split|isotropic]
        [--cuffs split|isotropic] [--estimator momentum|kalman]

Runs every (period, step length, bound) of the grid (default: the brief's
5 × 5 × 3) with the spastic patient, the safety supervisor off, the QP
controller and the default duration, in parallel over processes, and prints
per point the real (elastic) peak cuff force over the bound, which cuff,
when, the steepest rise of the real force in the 50 ms before the peak
[N/ms], the QP's fallbacks and the margin stated for that point
(:func:`exo_ctrl.control.qp.stated_margin`); then the worst point.  By
default the truth's cuffs are split (normal and shear apart, the default
plant) and the QP holds the device's default patient model (nominal) with
the split cuff model, with the run's default live estimator (the Kalman
filter; the stated margin is that estimator's); ``--controller-patient``,
``--controller-cuffs``, ``--cuffs`` and ``--estimator`` change them.  Exit 0
if every point holds within its stated margin, 1 if one does not (or a run
did not complete), 2 on bad input.

Diagnostics (they change the controller, not the plant):

- ``--truth``: the controller gets the plant's true cuff forces instead of
  the estimate (what the bound achieves without the estimate's lag), taken
  as they are (the lead–lag's ω_f set to the estimator's K_O: no filter
  to undo);
- ``--restored-bandwidth W``: ω_f of the estimate's lead–lag [1/s]
  (100 = the estimator's own K_O: f̂ as it is);
- ``--disturbance-bandwidth W``: ω_d of the patient-torque estimate d̂
  [1/s] (default: the estimator's, ``DISTURBANCE_BANDWIDTH_PER_S``);
- ``--horizon-ms``: the prediction's horizon points [ms].
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import itertools
import json
import multiprocessing
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl._progress import Progress
from exo_ctrl.control.qp import QPController, stated_margin
from exo_ctrl.control.qp.controller import (
    DISTURBANCE_BANDWIDTH_PER_S,
    RESTORED_BANDWIDTH_PER_S,
)
from exo_ctrl.control.qp.prediction import DEFAULT_HORIZON_TICKS
from exo_ctrl.estimation import DEFAULT_GAIN_PER_S, ESTIMATORS
from exo_ctrl.exceptions import ExoCtrlError
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import CuffParams
from exo_ctrl.sim import Runner, SimConfig, build
from exo_ctrl.sim.belief import Belief

PERIODS_S = (0.9, 1.05, 1.2, 1.35, 1.5)
STEPS_M = (0.25, 0.30, 0.35, 0.40, 0.45)
BOUNDS_N = (100.0, 125.0, 150.0)
#: The cuff parameter sets by name (the truth's and the device's).
CUFFS = {"split": CuffParams(), "isotropic": CuffParams.isotropic()}
#: The window before the peak in which the force's steepest rise is taken [s].
RISE_WINDOW_S = 0.05
#: The live cuff-force estimator of a default run (``SimConfig.estimator``).
DEFAULT_ESTIMATOR = SimConfig().estimator


def run_point(
    period_s: float,
    step_m: float,
    bound_N: float,
    duration_s: float | None = None,
    truth: bool = False,
    restored_bandwidth_per_s: float = RESTORED_BANDWIDTH_PER_S,
    horizon_ticks: tuple[int, ...] = DEFAULT_HORIZON_TICKS,
    controller_patient: str = "nominal",
    controller_cuffs: str = "split",
    cuffs: str = "split",
    estimator: str = DEFAULT_ESTIMATOR,
    disturbance_bandwidth_per_s: float | None = None,
) -> dict:
    """One grid point: the real peak cuff force against the bound, and where it came.

    The run is :func:`exo_ctrl.sim.simulate`'s tick loop (``Runner.tick``)
    on the configuration; only with a diagnostic option is the controller
    built here with it, and with ``truth`` the controller's force estimate
    replaced by the plant's cuff forces.  ``cuffs``: the truth's cuffs,
    ``controller_cuffs`` the device's cuff model (``split``:
    :class:`CuffParams`, the published normal and shear values;
    ``isotropic``: :meth:`CuffParams.isotropic`).
    """
    extra = {} if duration_s is None else {"duration_s": duration_s}
    config = SimConfig(
        gait=GaitParams(period=period_s, step_length=step_m),
        controller="qp",
        patient_torque="spastic",
        cuff_force_limit_N=bound_N,
        safety=False,
        cuffs=CUFFS[cuffs],
        estimator=estimator,
        belief=Belief(controller_patient, cuffs=CUFFS[controller_cuffs]),
        **extra,
    )
    setup = build(config)
    if (
        restored_bandwidth_per_s != RESTORED_BANDWIDTH_PER_S
        or horizon_ticks != tuple(DEFAULT_HORIZON_TICKS)
        or disturbance_bandwidth_per_s is not None
    ):
        setup.controller = QPController(
            setup.plan,
            setup.device_exo,
            setup.device_patient,
            setup.device_motor,
            config.gains,
            cuff_force_limit_N=bound_N,
            cuffs=config.belief.cuff_model,
            dt=config.dt,
            horizon_ticks=horizon_ticks,
            restored_bandwidth_per_s=restored_bandwidth_per_s,
            estimator=estimator,
            disturbance_bandwidth_per_s=disturbance_bandwidth_per_s,
        )
    runner = Runner(setup)
    if truth:
        runner.sensors.cuff_force_est = setup.plant.record["cuff_force"][0]
    n = config.n_ticks
    force = np.zeros((n, 4))
    for k in range(n):
        row = k % runner.chunk
        runner.tick(k, row)
        force[k] = np.linalg.norm(runner.log["cuff_force"][row], axis=1)
    k_peak, cuff = np.unravel_index(int(force.argmax()), force.shape)
    peak = float(force[k_peak, cuff])
    w = max(int(RISE_WINDOW_S / config.dt), 1)
    rise = np.diff(force[max(k_peak - w, 0) : k_peak + 1, cuff])
    return {
        "period_s": period_s,
        "step_length_m": step_m,
        "bound_N": bound_N,
        "peak_N": peak,
        "over": peak / bound_N - 1.0,
        "cuff": int(cuff),
        "t_peak_s": float(k_peak * config.dt),
        "phase": float((k_peak * config.dt - config.ramp_in) / period_s % 1.0),
        "rise_N_per_ms": float(rise.max() / (config.dt * 1e3)) if rise.size else 0.0,
        "qp_failures": int(setup.controller.failures),
        "margin": stated_margin(
            period_s, bound_N, estimator, true_patient=controller_patient == "truth"
        ),
    }


def _floats(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas; got {text!r}"
        ) from None
    return values


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--periods", type=_floats, default=PERIODS_S, help="gait periods [s]")
    p.add_argument("--steps", type=_floats, default=STEPS_M, help="step lengths [m]")
    p.add_argument("--bounds", type=_floats, default=BOUNDS_N, help="cuff-force bounds [N]")
    p.add_argument("--duration", type=float, default=None, help="run length [s] (default 3.6)")
    p.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    p.add_argument("--json", type=Path, default=None, help="write the points here")
    p.add_argument("--truth", action="store_true", help="true cuff forces, not the estimate")
    p.add_argument(
        "--controller-patient",
        default="nominal",
        metavar="truth|nominal|URDF",
        help="the patient model the QP holds (default nominal, the device's default; "
        "truth: the ideal comparison)",
    )
    p.add_argument(
        "--controller-cuffs",
        default="split",
        choices=tuple(CUFFS),
        help="the QP's cuff model (default split: normal and shear apart, as the truth's)",
    )
    p.add_argument(
        "--estimator",
        default=DEFAULT_ESTIMATOR,
        choices=ESTIMATORS,
        help=f"the live cuff-force estimator (default {DEFAULT_ESTIMATOR}, a run's default)",
    )
    p.add_argument(
        "--cuffs", default="split", choices=tuple(CUFFS), help="the truth's cuffs (default split)"
    )
    p.add_argument(
        "--restored-bandwidth",
        type=float,
        default=None,
        help=f"ω_f [1/s] (default {RESTORED_BANDWIDTH_PER_S:g}; with --truth, K_O)",
    )
    p.add_argument(
        "--disturbance-bandwidth",
        type=float,
        default=None,
        help="ω_d of the patient-torque estimate [1/s] (default: the estimator's, "
        + ", ".join(f"{k} {w:g}" for k, w in DISTURBANCE_BANDWIDTH_PER_S.items())
        + ")",
    )
    p.add_argument(
        "--horizon-ms",
        type=_floats,
        default=DEFAULT_HORIZON_TICKS,
        help="horizon points [ms] (default 5,10,20,30,40)",
    )
    args = p.parse_args(argv)
    if args.workers < 1:
        print("load_held: --workers must be >= 1", file=sys.stderr)
        return 2
    options = {
        "duration_s": args.duration,
        "truth": args.truth,
        "restored_bandwidth_per_s": (DEFAULT_GAIN_PER_S if args.truth else RESTORED_BANDWIDTH_PER_S)
        if args.restored_bandwidth is None
        else args.restored_bandwidth,
        "horizon_ticks": tuple(round(h) for h in args.horizon_ms),  # 1 kHz: 1 tick = 1 ms
        "controller_patient": args.controller_patient,
        "controller_cuffs": args.controller_cuffs,
        "cuffs": args.cuffs,
        "estimator": args.estimator,
        "disturbance_bandwidth_per_s": args.disturbance_bandwidth,
    }
    points = list(itertools.product(args.periods, args.steps, args.bounds))
    try:  # refuse bad input before any worker starts
        for period, step, bound in points:
            SimConfig(gait=GaitParams(period=period, step_length=step), cuff_force_limit_N=bound)
    except ExoCtrlError as exc:
        print(f"load_held: {exc}", file=sys.stderr)
        return 2
    bar = Progress(len(points), "load held")
    results: list[dict] = []
    failed = 0
    context = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(args.workers, mp_context=context) as pool:
        futures = {pool.submit(run_point, *pt, **options): pt for pt in points}
        for fut in cf.as_completed(futures):
            pt = futures[fut]
            try:
                results.append(fut.result())
            except ExoCtrlError as exc:
                failed += 1
                print(f"\n{pt}: {exc}", file=sys.stderr)
            bar.update(len(results) + failed)
    bar.close(len(points))
    results.sort(key=lambda r: (r["period_s"], r["step_length_m"], r["bound_N"]))
    print("period_s step_m bound_N   peak_N    over  margin  cuff  phase  rise_N/ms  fallbacks")
    for r in results:
        flag = "" if r["over"] <= r["margin"] else "  <-- beyond the margin"
        print(
            f"{r['period_s']:8.2f} {r['step_length_m']:6.2f} {r['bound_N']:7.0f} "
            f"{r['peak_N']:8.1f} {100 * r['over']:+6.1f}% {100 * r['margin']:5.1f}% "
            f"{r['cuff']:5d} {r['phase']:6.2f} {r['rise_N_per_ms']:10.2f} "
            f"{r['qp_failures']:10d}{flag}"
        )
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1))
    if not results:
        print("load_held: no point completed", file=sys.stderr)
        return 1
    worst = max(results, key=lambda r: r["over"] - r["margin"])
    held = all(r["over"] <= r["margin"] for r in results) and not failed
    print(
        f"worst: period {worst['period_s']:g} s, step {worst['step_length_m']:g} m, "
        f"bound {worst['bound_N']:g} N: peak {worst['peak_N']:.1f} N "
        f"({100 * worst['over']:+.1f} %, stated margin {100 * worst['margin']:.1f} %); "
        f"largest overshoot {100 * max(r['over'] for r in results):+.1f} %; "
        f"{'every point held' if held else 'NOT held'}"
    )
    return 0 if held else 1


if __name__ == "__main__":
    sys.exit(main())
