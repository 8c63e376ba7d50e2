"""Do the loaded touchdowns hold off the default patient?  A seeded campaign (issue 31, item 4).

    .venv/bin/python tools/touchdowns.py [--points N] [--seed S] [--controller ct|qp]
        [--patients none,active,spastic] [--cycles C] [--safety-widen] [--json PATH]

The touchdown bounds (under 0.05 m/s vertically and along the belt, slip RMS
under 0.02 m/s in stance) are asserted on the default patient
(``tests/sim/test_touchdown_loaded.py``).  This draws N points (default 30)
from ``numpy.random.default_rng([S, i])`` (default seed 0; point i is the same
whatever N > i), each a true patient as ``tools/load_held.py`` draws them
(stature 1.55–1.95 m, body mass 50–110 kg within a body-mass index of
18.5–35 kg/m², sex at random, the segments around de Leva's by the cohort's
spreads, the exoskeleton fitted to its legs, the knee misaligned up to 2 cm,
the true cuffs scattered around the published ones; the device holds the
nominal patient of that stature, mass and sex), a body-weight support
U(0.3, 0.5) and a patient torque (passive, active or spastic, at random),
and walks it on its preset with the safety supervisor on: the passive and
the active patient on ``clinic-bws``, the spastic one on ``clinic-spastic``
(its slower gait), the gait's hip height, lift and step length scaled to the
patient's legs (``tools/load_held.py`` scales hip height and lift so: the
presets' are for a 1.04 m leg; the period kept, so the belt runs slower
under shorter legs), for the ramp-in and ``C`` cycles (default 3) with
``--controller`` (default ct; qp at the ``clinic-spastic`` preset's bound,
200 N on the thighs and 120 N on the shanks, for every point); ``--safety-widen``
(CT only): the supervisor watches the estimate widened by the along-shank force it
cannot see (:mod:`exo_ctrl.safety.unseen`).

Prints a progress line, per point its patient, support, the walk's worst
touchdown (vertical and along the belt) and slip RMS, the largest true and
estimated shank cuff force (after the estimator's 0.05 s start-up), the
supervisor's stop if any, and for a point outside the bounds whether the run warned before it
started (the drives' reach, a device that does not fit, ...: ``warned``) or
not (``unwarned``); then per patient torque the worst of each figure, the
share of the points within all three bounds and the points outside them
unwarned, the largest true shank force and the points whose true shank force
passed the supervisor's limit with no stop, and each warned point's first warning.
A point the planner refuses before the run is listed with its reason.  Exit 0 if every point
walked without a stop within the bounds, 1 if one did not, 2 on bad input.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from load_held import device_belief, draw_points, point_bodies, run_points  # a sibling tool

from exo_ctrl._io import output_problem
from exo_ctrl.cli.common import write_json
from exo_ctrl.exceptions import ExoCtrlError
from exo_ctrl.plant.cuff_scatter import CuffScatter
from exo_ctrl.plant.misalignment import Misalignment
from exo_ctrl.scenario.load import load_scenario
from exo_ctrl.sim import SimConfig, simulate

#: The patient torques drawn from.
PATIENTS = ("none", "active", "spastic")
#: Each patient torque's preset.
PRESET = {"none": "clinic-bws", "active": "clinic-bws", "spastic": "clinic-spastic"}
#: What ``tools/load_held.py`` draws for a point that this campaign does not use (the gait is
#: the preset's in proportion, the bound the preset's; every point's pelvis is supported).
NOT_OURS = ("step_length_m", "period_s", "bound_N", "pelvis")
#: Issue 31's bounds: touchdown vertical and along the belt, slip RMS in stance [m/s].
BOUND_MPS = 0.05
SLIP_RMS_MPS = 0.02
#: The shank forces are compared after the estimator's start-up [s] (as the summary's errors).
ESTIMATE_START_S = 0.05


def point_config(
    point: dict[str, Any], folder: Path, controller: str, cycles: int, widen: bool = False
) -> SimConfig:
    """The point's run on its preset, its URDFs in ``folder`` (``widen``: safety_widen)."""
    base = load_scenario(preset=PRESET[point["patient_torque"]]).config
    exo, patient, k = point_bodies(point, folder)
    gait = dataclasses.replace(  # the preset's gait for these legs: lengths in proportion
        base.gait,
        hip_height=base.gait.hip_height * k,
        lift_height=base.gait.lift_height * k,
        step_length=base.gait.step_length * k,
    )
    pelvis = dataclasses.replace(
        base.pelvis, bws_fraction=point["bws"], body_mass_kg=point["mass_kg"]
    )
    return dataclasses.replace(
        base,
        controller=controller,
        gait=gait,
        exo=str(exo),
        patient=str(patient),
        misalignment=Misalignment(knee_xz=point["knee_xz"]),
        patient_torque=point["patient_torque"],
        pelvis=pelvis,
        duration_s=(1 + cycles) * gait.period,
        cuff_scatter=CuffScatter(seed=point["cuff_seed"]),
        cuff_force_limit_N=load_scenario(preset="clinic-spastic").config.cuff_force_limit_N,
        belief=device_belief(point),
        safety_widen=widen,
    )


def run_point(
    point: dict[str, Any], folder: Path, controller: str, cycles: int, widen: bool = False
) -> dict:
    """Walk one point: its touchdowns and slip, its shank forces, the supervisor's stop, or
    why it was refused."""
    out = {k: v for k, v in point.items() if k not in NOT_OURS}
    try:
        config = point_config(point, folder, controller, cycles, widen)
        g = config.gait
        out.update(step_length_m=g.step_length, period_s=g.period, hip_height_m=g.hip_height)
        result = simulate(config)
    except ExoCtrlError as exc:
        out.update(outcome="refused", reason=str(exc))
        return out
    s = result.summary()
    stops = [e for e in result.events if e["kind"] == "violation"]
    after = result.t > ESTIMATE_START_S
    shank = np.linalg.norm(result.cuff_force[after][:, 1::2], axis=2)
    shank_est = np.linalg.norm(result.signals["cuff_force_est"][after][:, 1::2], axis=2)
    out.update(
        shank_N=float(shank.max()),
        shank_est_N=float(shank_est.max()),
        shank_limit_N=float(config.safety_limits.cuff_limit_N[1]),
    )
    out.update(
        outcome=result.status,
        touchdowns=s["touchdown_count"],
        down_mps=s["touchdown_speed_mps"],
        along_mps=s["touchdown_slip_mps"],
        slip_rms_mps=s["slip_speed_rms_mps"],
        stop=None if not stops else f"{stops[0]['t']:.2f} s {stops[0].get('quantity', '')}",
        warnings=list(result.warnings),
    )
    out["held"] = (
        out["stop"] is None
        and out["touchdowns"] >= 2 * cycles
        and out["down_mps"] < BOUND_MPS
        and out["along_mps"] < BOUND_MPS
        and out["slip_rms_mps"] < SLIP_RMS_MPS
    )
    return out


def report(results: list[dict[str, Any]]) -> tuple[str, bool]:
    """The table and the closing lines; and whether every point held."""
    lines = [
        "  #  patient  height   mass  knee_cm   bws  down_mps along_mps slip_rms "
        "shank_N est_N  stop"
    ]
    for r in results:
        knee = 100 * float(np.hypot(*r["knee_xz"]))
        head = (
            f"{r['index']:3d} {r['patient_torque']:>8s} {r['height_m']:7.3f} {r['mass_kg']:6.1f} "
            f"{knee:8.2f} {r['bws']:5.2f}"
        )
        if r["outcome"] == "refused":
            lines.append(f"{head}  refused: {r['reason']}")
            continue
        mark = "" if r["held"] else ("  <- warned" if r["warnings"] else "  <- unwarned")
        lines.append(
            f"{head} {r['down_mps']:9.3f} {r['along_mps']:9.3f} {r['slip_rms_mps']:8.4f} "
            f"{r['shank_N']:7.1f} {r['shank_est_N']:5.1f}  {r['stop'] or '-'}{mark}"
        )
    ran = [r for r in results if r["outcome"] != "refused"]
    lines.append(f"{len(results)} points: {len(ran)} walked, {len(results) - len(ran)} refused")
    for torque in PATIENTS:
        group = [r for r in ran if r["patient_torque"] == torque]
        if group:
            lines.append(
                f"  {torque:>8s}: {len(group):3d} points, within the bounds "
                f"{100 * sum(r['held'] for r in group) / len(group):5.1f} %, worst "
                f"{max(r['down_mps'] for r in group):.3f} / "
                f"{max(r['along_mps'] for r in group):.3f} / "
                f"{max(r['slip_rms_mps'] for r in group):.4f} m/s, "
                f"{sum(r['stop'] is not None for r in group)} stopped, "
                f"{sum(not r['held'] and not r['warnings'] for r in group)} outside unwarned; "
                f"true shank force up to {max(r['shank_N'] for r in group):.1f} N, past the "
                f"supervisor's limit with no stop on {sum(_unseen(r) for r in group)}"
            )
    held = bool(ran) and all(r["held"] for r in ran) and len(ran) == len(results)
    for r in ran:
        if not r["held"] and r["warnings"]:
            lines.append(f"point {r['index']} was warned before the run: {r['warnings'][0]}")
    return "\n".join(lines), held


def _unseen(r: dict[str, Any]) -> bool:
    """The point's true shank force passed the supervisor's limit and nothing stopped it."""
    return r["stop"] is None and r["shank_N"] > r["shank_limit_N"]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=30, help="points to draw (default 30)")
    p.add_argument("--seed", type=int, default=0, help="the campaign's seed (default 0)")
    p.add_argument("--controller", default="ct", choices=("ct", "qp"), help="(default ct)")
    p.add_argument(
        "--patients",
        default=",".join(PATIENTS),
        help="patient torques to draw from, comma-separated (default none,active,spastic)",
    )
    p.add_argument("--cycles", type=int, default=3, help="cycles after the ramp-in (default 3)")
    p.add_argument(
        "--safety-widen",
        action="store_true",
        help="the supervisor watches the estimate widened by the along-shank force it cannot "
        "see (CT only)",
    )
    p.add_argument("--json", type=Path, default=None, help="write the points here")
    args = p.parse_args(argv)
    patients = tuple(args.patients.split(","))
    if not patients or any(x not in PATIENTS for x in patients):
        print(f"touchdowns: --patients must name some of {PATIENTS}", file=sys.stderr)
        return 2
    if args.safety_widen and args.controller == "qp":
        print(
            "touchdowns: --safety-widen is for CT (the QP tightens its own bound)", file=sys.stderr
        )
        return 2
    if args.points < 1 or args.seed < 0 or args.cycles < 1:
        print("touchdowns: --points and --cycles must be >= 1, --seed >= 0", file=sys.stderr)
        return 2
    if args.json is not None and (problem := output_problem(args.json)):
        print(f"touchdowns: --json {args.json}: {problem}", file=sys.stderr)
        return 2
    points = draw_points(args.points, args.seed, patients, ("supported",))
    results = run_points(
        points,
        lambda p, folder: run_point(p, folder, args.controller, args.cycles, args.safety_widen),
        "touchdowns",
    )
    text, held = report(results)
    print(text)
    if args.json is not None:
        write_json(args.json, results)
    return 0 if held else 1


if __name__ == "__main__":
    sys.exit(main())
