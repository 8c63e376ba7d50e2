"""Path mode's wall against its stiffness and damping, on a healthy, a weak and a spastic patient.

    .venv/bin/python tools/path_wall.py [--stiffness K1,K2,...] [--damping-ratio Z1,Z2,...]
        [--force-max N] [--leg-weight-support A] [--duration SEC]
        [--patients healthy,weak,spastic] [--estimator kalman|momentum]

Runs ``path`` (:mod:`exo_ctrl.control.modes.path`; its defaults otherwise)
for every wall stiffness k [N/m] and damping ratio ζ given (defaults: the
defaults of :class:`~exo_ctrl.control.modes.PathParams`) on the active
patients of ``tools/modes.py`` (their own gait: a 1.0 s period, 0.30 m
steps against the device's 1.2 s, 0.35 m): healthy, weak (strength 0.3)
and spastic.  Each run is the default scenario (standing start, 1.2 s
ramp-in, default sensors and estimator, the supervisor on), ``--duration``
seconds (default 6).  Over the ticks after the ramp-in the table gives:

- the feet's distance from the planned path, measured on the truth as the
  summary does (:func:`exo_ctrl.sim.interaction.path_distances`: the true
  exoskeleton's feet at the true angles, the path within the controller's
  window about the logged phase): RMS and max over both feet [mm], the
  share of ticks a foot is outside the tunnel (d > w) and outside the
  tunnel + 2 cm;
- the wall's force on the feet, |F_wall| (the controller's record): RMS and
  max [N];
- the cuff forces' magnitudes, all four cuffs, true and estimated: RMS and
  max [N];
- the drives' largest current [A] (the driver clips at its limit, 32 A by
  default) and largest |torque| [N·m] (the URDF effort limit, 150 N·m);
- stability: the feet's RMS distance per second of the run after the
  ramp-in (first and last second) and the cuff forces' RMS in the first
  and last second [N];
- the supervisor's first event (its time; ``none``).

Prints a Markdown table (exit 0).  Importable:
``run_wall(patient, duration_s, **path_params) -> WallRow``.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import modes as modes_tool

from exo_ctrl.control.modes import PathParams
from exo_ctrl.sim import Runner, SimConfig, build
from exo_ctrl.sim.interaction import PathReference, path_distances

#: The ramp-in [s] (the default scenario's).
RAMP_S = 1.2
#: The patients: this tool's label → tools/modes.py's.
PATIENTS = {"healthy": "healthy", "weak": "weak (0.3)", "spastic": "spastic"}


@dataclass(frozen=True)
class WallRow:
    """One run's figures (module docstring); distances [mm], forces [N]."""

    patient: str
    stiffness_N_per_m: float
    damping_ratio: float
    d_rms_mm: float
    d_max_mm: float
    outside: float
    outside_2cm: float
    wall_rms_N: float
    wall_max_N: float
    cuff_rms_N: float
    cuff_max_N: float
    cuff_est_rms_N: float
    cuff_est_max_N: float
    current_max_A: float
    torque_max_Nm: float
    d_first_s_mm: float
    d_last_s_mm: float
    cuff_first_s_N: float
    cuff_last_s_N: float
    stop_s: float | None


def run_wall(
    patient: str, duration_s: float = 6.0, estimator: str = "kalman", **path: float
) -> WallRow:
    """Run ``path`` with ``PathParams(**path)`` on ``patient`` (a key of :data:`PATIENTS`)."""
    params = PathParams(**path)
    config = SimConfig(
        mode="path",
        path=params,
        patient_torque="active",
        patient_active=modes_tool.PATIENTS[PATIENTS[patient]],
        duration_s=duration_s,
        estimator=estimator,
    )
    setup = build(config)
    runner = Runner(setup)
    rec, n = setup.controller.record, config.n_ticks
    keys = ("q", "path_phase", "cuff_force", "cuff_force_est", "current", "drive_torque")
    sig = {key: np.empty((n, *runner.log[key].shape[1:])) for key in keys}
    wall = np.empty(n)
    for k in range(n):
        runner.tick(k, k % runner.chunk)
        row = runner.log[k % runner.chunk]
        for key in keys:
            sig[key][k] = row[key]
        wall[k] = np.max(np.linalg.norm(rec["wall_force"][0], axis=1))
    start = round(RAMP_S / config.dt)
    ticks = np.arange(start, n)
    ref = PathReference.of(setup.controller, setup.plan, setup.exo)
    d = path_distances(ref, sig["q"][ticks], sig["path_phase"][ticks].astype(int), ticks)
    cuff = np.linalg.norm(sig["cuff_force"][ticks], axis=-1)
    est = np.linalg.norm(sig["cuff_force_est"][ticks], axis=-1)
    second = round(1.0 / config.dt)
    w = params.tunnel_width_m
    sup = runner.supervisor
    events = sup.events if sup is not None else []
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))  # noqa: E731
    return WallRow(
        patient=patient,
        stiffness_N_per_m=params.wall_stiffness_N_per_m,
        damping_ratio=params.wall_damping_ratio,
        d_rms_mm=1e3 * rms(d),
        d_max_mm=1e3 * float(d.max()),
        outside=float(np.mean(d > w)),
        outside_2cm=float(np.mean(d > w + 0.02)),
        wall_rms_N=rms(wall[ticks]),
        wall_max_N=float(wall[ticks].max()),
        cuff_rms_N=rms(cuff),
        cuff_max_N=float(cuff.max()),
        cuff_est_rms_N=rms(est),
        cuff_est_max_N=float(est.max()),
        current_max_A=float(np.abs(sig["current"][ticks]).max()),
        torque_max_Nm=float(np.abs(sig["drive_torque"][ticks]).max()),
        d_first_s_mm=1e3 * rms(d[:second]),
        d_last_s_mm=1e3 * rms(d[-second:]),
        cuff_first_s_N=rms(cuff[:second]),
        cuff_last_s_N=rms(cuff[-second:]),
        stop_s=events[0]["t"] if events else None,
    )


def table(rows: list[WallRow]) -> str:
    """The rows as a Markdown table."""
    head = (
        "patient | k [N/m] | ζ | d RMS / max [mm] | outside w / w+2cm | F_wall RMS / max [N] | "
        "cuff true RMS / max [N] | cuff est. RMS / max [N] | I max [A] | τ max [N·m] | "
        "d 1st / last s [mm] | cuff 1st / last s [N] | stop"
    )
    lines = [f"| {head} |", "|" + "---|" * (head.count("|") + 1)]
    for r in rows:
        stop = "none" if r.stop_s is None else f"{r.stop_s:.3f} s"
        lines.append(
            f"| {r.patient} | {r.stiffness_N_per_m:.0f} | {r.damping_ratio:.2f} | "
            f"{r.d_rms_mm:.1f} / {r.d_max_mm:.0f} | {r.outside:.1%} / {r.outside_2cm:.1%} | "
            f"{r.wall_rms_N:.1f} / {r.wall_max_N:.0f} | {r.cuff_rms_N:.1f} / {r.cuff_max_N:.0f} | "
            f"{r.cuff_est_rms_N:.1f} / {r.cuff_est_max_N:.0f} | {r.current_max_A:.1f} | "
            f"{r.torque_max_Nm:.0f} | {r.d_first_s_mm:.1f} / {r.d_last_s_mm:.1f} | "
            f"{r.cuff_first_s_N:.1f} / {r.cuff_last_s_N:.1f} | {stop} |"
        )
    return "\n".join(lines)


def _floats(text: str) -> list[float]:
    values = [float(x) for x in text.split(",")]
    if not all(math.isfinite(x) and x >= 0.0 for x in values):
        raise argparse.ArgumentTypeError(f"non-negative numbers, comma-separated; got {text!r}")
    return values


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring)."""
    base = PathParams()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stiffness", type=_floats, default=[base.wall_stiffness_N_per_m])
    parser.add_argument("--damping-ratio", type=_floats, default=[base.wall_damping_ratio])
    parser.add_argument("--force-max", type=float, default=base.wall_force_max_N)
    parser.add_argument("--leg-weight-support", type=float, default=base.leg_weight_support)
    parser.add_argument("--duration", type=float, default=6.0, help="run length [s] (default 6)")
    parser.add_argument("--patients", default=",".join(PATIENTS))
    parser.add_argument("--estimator", default="kalman", choices=("kalman", "momentum"))
    args = parser.parse_args(argv)
    patients = args.patients.split(",")
    unknown = [p for p in patients if p not in PATIENTS]
    if unknown:
        parser.exit(2, f"patients: unknown {unknown}; known: {', '.join(PATIENTS)}\n")
    if not (math.isfinite(args.duration) and args.duration >= 2.4):
        parser.exit(2, f"duration must be >= 2.4 s (ramp-in and a second); got {args.duration}\n")
    rows = [
        run_wall(
            p,
            args.duration,
            args.estimator,
            wall_stiffness_N_per_m=k,
            wall_damping_ratio=z,
            wall_force_max_N=args.force_max,
            leg_weight_support=args.leg_weight_support,
        )
        for k in args.stiffness
        for z in args.damping_ratio
        for p in patients
    ]
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
