"""Does the QP's cuff-force bound hold?  A seeded, randomised campaign ("Load held", issue 31).

    .venv/bin/python tools/load_held.py [--points N] [--seed S] [--json PATH]
        [--patients spastic,active] [--cuff-sensors none|normal|full] [--sync off]

Draws N points (default 200) from ``numpy.random.default_rng(S)`` (default
seed 0; point i is the same whatever N > i), each

- a gait: step length U(0.25, 0.50) m, period U(0.9, 1.5) s (hip height
  and lift the defaults scaled to the patient's leg length, as the
  robustness tool does);
- a bound F_max U(100, 180) N on every cuff;
- a true patient: stature U(1.55, 1.95) m, body mass U(50, 110) kg within a
  body-mass index of 18.5–35 kg/m² (as the robustness cohort,
  :func:`~exo_ctrl.model.benchmark_cohort`), sex at random, the segments
  drawn around de Leva's by the cohort's spreads
  (:func:`~exo_ctrl.model.cohort.drawn_patient`), written to a URDF for the
  point, the exoskeleton fitted to its legs
  (:func:`~exo_ctrl.model.fitted_exo`); the device holds the nominal
  patient of that stature, mass and sex (its default knowledge);
- a knee misalignment of magnitude U(0, 2) cm in a uniform direction;
- a spastic or an active patient; the pelvis fixed (feet in free air, as
  the issue's cases), or supported at a body-weight support U(0.3, 0.5)
  (the belt and contact on: a supported pelvis needs them);
- the patient's true cuffs, scattered around the published ones
  (:class:`~exo_ctrl.plant.cuff_scatter.CuffScatter`, its default spread,
  seeded per point), and the cuff sensors of ``--cuff-sensors`` (default
  none; their noise seeded per point);
- the plan: the QP's default, the synchronised plan for the supported points
  (the fixed points have no belt to follow: precomputed); with ``--sync off``
  the supported points on the precomputed plan;

and runs the QP (safety supervisor off, the default Kalman filter) for
three gait periods (the ramp-in and two cycles).  A point the device
refuses before the run (the planner, or a bound its margin cannot hold:
:class:`~exo_ctrl.exceptions.CuffBoundTooTight`; with the pelvis supported
a bound below the plan's load plus the margin) is recorded as refused
with the reason.  A supported point's walk stops where the QP leaves its
plan by more than the swing foot's clearance allows
(:mod:`exo_ctrl.safety.departure`, with the supervisor off too); the
stop's time is reported and the peak counts the whole run.  Prints a
progress line, per run point the true peak cuff force against the bound,
the margin the QP stated (``cuff_bound_margin_N``) and the stop, then the
worst overshoot and the share of runs within 5 % and 10 % of their bound.
Exit 0 if every run point is within 5 %, 1 if one is not (or none ran), 2
on bad input.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl._io import output_problem
from exo_ctrl._progress import Progress
from exo_ctrl.cli.common import write_json
from exo_ctrl.exceptions import CuffBoundTooTight, ExoCtrlError
from exo_ctrl.model import CohortSpread, fitted_exo, write_urdf
from exo_ctrl.model.anthropometry import SEXES, patient_from_anthropometry
from exo_ctrl.model.cohort import BMI_RANGE, _factors, drawn_patient
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.plant.cuff_scatter import CuffScatter
from exo_ctrl.plant.misalignment import Misalignment
from exo_ctrl.sensing.cuff_load import CUFF_SENSOR_SETS, CuffSensorParams
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief

#: The campaign's ranges (issue 31, item 1).
STEP_M = (0.25, 0.50)
PERIOD_S = (0.9, 1.5)
BOUND_N = (100.0, 180.0)
HEIGHT_M = (1.55, 1.95)
MASS_KG = (50.0, 110.0)
KNEE_MISALIGNMENT_M = 0.02
BWS = (0.3, 0.5)
PATIENT_TORQUES = ("spastic", "active")
PELVIS = ("fixed", "supported")
#: The leg (thigh + shank) the default gait's hip height and lift are for [m]
#: (the default exoskeleton's: 0.9 m hip height for a 1.04 m leg).
REFERENCE_LEG_M = 1.04
#: The acceptance: a run point's true peak within this of its bound [-].
TOLERANCE = 0.05
#: The run: ramp-in and two gait cycles [periods].
RUN_PERIODS = 3.0


def draw_points(
    n: int,
    seed: int,
    patients: tuple[str, ...] = PATIENT_TORQUES,
    pelvis: tuple[str, ...] = PELVIS,
) -> list[dict[str, Any]]:
    """The first ``n`` points for ``seed`` (module docstring); point i fixed by (seed, i).

    ``patients``: the patient torques drawn from (default spastic and active);
    ``pelvis``: the pelvis cases (default fixed and supported).
    """
    out = []
    for i in range(n):
        rng = np.random.default_rng([seed, i])
        height = float(rng.uniform(*HEIGHT_M))
        low = max(MASS_KG[0], BMI_RANGE[0] * height**2)
        high = min(MASS_KG[1], BMI_RANGE[1] * height**2)
        offset = float(rng.uniform(0.0, KNEE_MISALIGNMENT_M))
        angle = float(rng.uniform(0.0, 2.0 * math.pi))
        supported = pelvis[int(rng.integers(0, len(pelvis)))] == "supported"
        out.append(
            {
                "index": i,
                "step_length_m": float(rng.uniform(*STEP_M)),
                "period_s": float(rng.uniform(*PERIOD_S)),
                "bound_N": float(rng.uniform(*BOUND_N)),
                "height_m": height,
                "mass_kg": float(rng.uniform(low, high)),
                "sex": SEXES[int(rng.integers(0, 2))],
                "z": _factors(rng, 10).tolist(),
                "knee_xz": (offset * math.cos(angle), offset * math.sin(angle)),
                "patient_torque": patients[int(rng.integers(0, len(patients)))],
                "pelvis": "supported" if supported else "fixed",
                "bws": float(rng.uniform(*BWS)) if supported else 0.0,
                "cuff_seed": int(rng.integers(0, 2**31)),
            }
        )
    return out


def point_bodies(point: dict[str, Any], folder: Path) -> tuple[Path, Path, float]:
    """The point's exoskeleton and true patient URDFs, written into ``folder``, and k.

    The patient drawn around the nominal one of the point's stature, mass and
    sex by the cohort's spreads, the exoskeleton fitted to its legs; k the
    patient's leg (thigh + shank) over :data:`REFERENCE_LEG_M`, the factor the
    default gait's lengths are scaled by.
    """
    nominal = patient_from_anthropometry(point["height_m"], point["mass_kg"], point["sex"])
    truth = drawn_patient(nominal, np.asarray(point["z"]), CohortSpread())
    exo = write_urdf(fitted_exo(truth), folder / f"exo_{point['index']:04d}.urdf")
    patient = write_urdf(truth, folder / f"patient_{point['index']:04d}.urdf")
    return exo, patient, (truth.thigh_length + truth.shank_length) / REFERENCE_LEG_M


def device_belief(point: dict[str, Any]) -> Belief:
    """What the device holds of the point's patient: the nominal one of its stature, mass, sex."""
    return Belief(
        patient_height_m=point["height_m"],
        patient_mass_kg=point["mass_kg"],
        patient_sex=point["sex"],
    )


def point_config(
    point: dict[str, Any], folder: Path, cuff_sensors: str = "none", sync: bool = True
) -> SimConfig:
    """The point's run: its URDFs written into ``folder``; ``cuff_sensors`` the sensor set.

    ``sync``: False puts a supported point on the precomputed plan (True: the QP's
    default, synchronised).
    """
    exo, patient, k = point_bodies(point, folder)
    pelvis = PelvisParams(
        supported=point["pelvis"] == "supported",
        bws_fraction=point["bws"],
        body_mass_kg=point["mass_kg"],
    )
    base = GaitParams()
    gait = GaitParams(
        period=point["period_s"],
        step_length=point["step_length_m"],
        hip_height=base.hip_height * k,
        lift_height=base.lift_height * k,
    )
    return SimConfig(
        gait=gait,
        contact=ContactParams(enabled=pelvis.supported, patient_feet=pelvis.supported),
        exo=str(exo),
        patient=str(patient),
        misalignment=Misalignment(knee_xz=point["knee_xz"]),
        controller="qp",
        patient_torque=point["patient_torque"],
        cuff_force_limit_N=point["bound_N"],
        safety=False,
        pelvis=pelvis,
        sync=None if sync else False,
        duration_s=RUN_PERIODS * point["period_s"],
        cuff_scatter=CuffScatter(seed=point["cuff_seed"]),
        cuff_sensors=CuffSensorParams(mode=cuff_sensors, seed=point["cuff_seed"]),
        belief=device_belief(point),
    )


def run_point(
    point: dict[str, Any], folder: Path, cuff_sensors: str = "none", sync: bool = True
) -> dict[str, Any]:
    """Run one point: its true peak cuff force against its bound, or why it was refused."""
    out = dict(point)
    try:
        result = simulate(point_config(point, folder, cuff_sensors, sync))
    except CuffBoundTooTight as exc:
        out.update(outcome="refused", kind="bound", reason=str(exc))
        return out
    except ExoCtrlError as exc:
        out.update(outcome="refused", kind="planner", reason=str(exc))
        return out
    summary = result.summary()
    peaks = np.array(list(summary["peak_cuff_force_N"].values()))
    margin = summary["cuff_bound_margin_N"] or {}
    stops = [e["t"] for e in result.events if str(e.get("quantity", "")).startswith("departure")]
    out.update(
        outcome=result.status,
        stopped_s=stops[0] if stops else None,
        peak_N=float(peaks.max()),
        cuff=int(peaks.argmax()),
        over=float(peaks.max() / point["bound_N"] - 1.0),
        margin_N=max(margin.values(), default=0.0),
        qp_failures=result.qp_failures,
    )
    return out


def campaign(
    n: int,
    seed: int,
    progress: bool = True,
    patients: tuple[str, ...] = PATIENT_TORQUES,
    pelvis: tuple[str, ...] = PELVIS,
    cuff_sensors: str = "none",
    sync: bool = True,
) -> list[dict[str, Any]]:
    """Run the first ``n`` points of ``seed``, one after the other, with ``cuff_sensors``."""
    points = draw_points(n, seed, patients, pelvis)
    return run_points(
        points, lambda p, folder: run_point(p, folder, cuff_sensors, sync), "load held", progress
    )


def run_points(
    points: list[dict[str, Any]],
    run: Callable[[dict[str, Any], Path], dict[str, Any]],
    label: str,
    progress: bool = True,
) -> list[dict[str, Any]]:
    """``run(point, folder)`` for each point in turn, the points' URDFs in one temporary
    folder, with a progress bar named ``label`` (``progress``)."""
    bar = Progress(len(points), label) if progress else None
    results = []
    with tempfile.TemporaryDirectory(prefix=label.replace(" ", "_") + "_") as tmp:
        for i, point in enumerate(points):
            results.append(run(point, Path(tmp)))
            if bar is not None:
                bar.update(i + 1)
    if bar is not None:
        bar.close(len(points))
    return results


def report(results: list[dict[str, Any]]) -> tuple[str, bool]:
    """The table and the closing lines; and whether every run point held within 5 %."""
    lines = [
        "  #  period_s step_m bound_N  height   mass  knee_cm patient  pelvis "
        "  peak_N    over  margin_N  fallbacks  stop_s"
    ]
    ran = [r for r in results if r["outcome"] == "completed"]
    for r in results:
        knee = 100 * math.hypot(*r["knee_xz"])
        head = (
            f"{r['index']:3d} {r['period_s']:9.3f} {r['step_length_m']:6.3f} {r['bound_N']:7.1f} "
            f"{r['height_m']:7.3f} {r['mass_kg']:6.1f} {knee:8.2f} {r['patient_torque']:>7s} "
            f"{r['pelvis']:>7s}"
        )
        if r["outcome"] == "completed":
            stop = "" if r["stopped_s"] is None else f"{r['stopped_s']:7.3f}"
            lines.append(
                f"{head} {r['peak_N']:8.1f} {100 * r['over']:+6.1f}% {r['margin_N']:9.1f} "
                f"{r['qp_failures']:10d} {stop}"
            )
        else:
            lines.append(f"{head}  {r['outcome']} ({r.get('kind', '')}): {r.get('reason', '')}")
    refused = [r for r in results if r["outcome"] == "refused"]
    lines.append(
        f"{len(results)} points: {len(ran)} ran, {len(refused)} refused before the run "
        f"({sum(r['kind'] == 'planner' for r in refused)} by the planner, "
        f"{sum(r['kind'] == 'bound' for r in refused)} as a bound the margin cannot hold), "
        f"{len(results) - len(ran) - len(refused)} did not complete"
    )
    if not ran:
        return "\n".join(lines), False
    worst = max(ran, key=lambda r: r["over"])
    within5 = sum(r["over"] <= TOLERANCE for r in ran) / len(ran)
    within10 = sum(r["over"] <= 2 * TOLERANCE for r in ran) / len(ran)
    lines.append(
        f"worst: point {worst['index']} (period {worst['period_s']:.3f} s, step "
        f"{worst['step_length_m']:.3f} m, bound {worst['bound_N']:.1f} N, "
        f"{worst['patient_torque']}, pelvis {worst['pelvis']}): peak {worst['peak_N']:.1f} N "
        f"({100 * worst['over']:+.1f} %); within 5 %: {100 * within5:.1f} % of the runs, "
        f"within 10 %: {100 * within10:.1f} %"
    )
    for torque in PATIENT_TORQUES:
        for case in PELVIS:
            group = [r for r in ran if r["patient_torque"] == torque and r["pelvis"] == case]
            if group:
                stopped = sum(r["stopped_s"] is not None for r in group)
                lines.append(
                    f"  {torque:>7s}, pelvis {case:>9s}: {len(group):3d} runs ({stopped} stopped "
                    "on a departure), worst "
                    f"{100 * max(r['over'] for r in group):+7.1f} %, within 5 %: "
                    f"{100 * sum(r['over'] <= TOLERANCE for r in group) / len(group):5.1f} %, "
                    f"within 10 %: "
                    f"{100 * sum(r['over'] <= 2 * TOLERANCE for r in group) / len(group):5.1f} %"
                )
    held = within5 == 1.0 and len(ran) + len(refused) == len(results)
    return "\n".join(lines), held


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--points", type=int, default=200, help="points to draw (default 200)")
    p.add_argument("--seed", type=int, default=0, help="the campaign's seed (default 0)")
    p.add_argument("--json", type=Path, default=None, help="write the points here")
    p.add_argument(
        "--patients",
        default=",".join(PATIENT_TORQUES),
        help="patient torques to draw from, comma-separated (default spastic,active)",
    )
    p.add_argument(
        "--cuff-sensors",
        default="none",
        choices=CUFF_SENSOR_SETS,
        help="the cuff sensors of every point (default none)",
    )
    p.add_argument(
        "--sync",
        default="on",
        choices=("off", "on"),
        help="off: the supported points on the precomputed plan (default on: synchronised)",
    )
    args = p.parse_args(argv)
    patients = tuple(args.patients.split(","))
    if not patients or any(x not in PATIENT_TORQUES for x in patients):
        print(f"load_held: --patients must name some of {PATIENT_TORQUES}", file=sys.stderr)
        return 2
    if args.points < 1 or args.seed < 0:
        print("load_held: --points must be >= 1 and --seed >= 0", file=sys.stderr)
        return 2
    if args.json is not None and (problem := output_problem(args.json)):
        print(f"load_held: --json {args.json}: {problem}", file=sys.stderr)
        return 2
    results = campaign(
        args.points,
        args.seed,
        patients=patients,
        cuff_sensors=args.cuff_sensors,
        sync=args.sync == "on",
    )
    text, held = report(results)
    print(text)
    if args.json is not None:
        write_json(args.json, results)
    return 0 if held else 1


if __name__ == "__main__":
    sys.exit(main())
