"""Every interaction mode on a healthy, a weak and a spastic active patient: what a therapist sees.

    .venv/bin/python tools/modes.py [--duration SEC] [--png PATH]

Runs the modes ``tracking``, ``guidance`` (G = 0.5), ``transparent``,
``aan`` and ``path`` (tunnel 0.03 m) (:mod:`exo_ctrl.control.modes`, their
default parameters otherwise) on three
active patients (:mod:`exo_ctrl.plant.patient_active`), each preferring
their own gait, a 1.0 s period and 0.30 m steps, against the device's plan
of 1.2 s and 0.35 m (the preferences of ``tests/sim/test_modes_run.py``):

- healthy: strength 1;
- weak: strength 0.3 at every joint;
- spastic: strength 1 with the spastic torques (:class:`SpasticPatient`'s
  defaults) on top.

Each run is the default scenario otherwise (standing start, 1.2 s ramp-in,
default sensors, the default Kalman filter, the supervisor on), ``--duration``
seconds in all (default 6.0: the ramp-in and four gait cycles).  From each
run's summary, over the cycles after the ramp-in (:mod:`exo_ctrl.sim.interaction`,
:mod:`exo_ctrl.sim.gait_score`), the table gives: the RMS interaction force,
true (the plant's cuff forces) and estimated (the device's) [N]; the
patient's effort, the RMS of their joint torques (RMS over the four joints)
[N·m] and their positive work per cycle (all joints) [J]; the drives'
positive work per cycle [J]; the RMS tracking error (RMS over the joints)
[mrad] against the clock's plan (in ``path``, whose timing is free, it
counts the patient's own pace as an error); for ``path`` the feet's RMS
distance from the planned path at the device's own phase (RMS over both
feet, the summary's ``path_error_rms_m``) [mm]; the Gait Profile Score
of the patient's true angles [deg] (the plan's is the same in every run
and printed under the table); the supervisor's stop (its state and first
event's time; ``--no-safety`` runs without it).  Figures of a stopped run include the hold after the
stop.  Prints a Markdown table; ``--png`` draws a panel
per figure with a marker per mode (exit 0).

Importable: ``run_table(duration_s, modes, patients) -> list[Row]``.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl import SimConfig, simulate
from exo_ctrl.control.modes import ModeParams
from exo_ctrl.control.modes.path import PathParams
from exo_ctrl.plant.patient_active import ActiveParams

#: The modes run: label → (mode, its parameters).
MODES: dict[str, tuple[str, ModeParams]] = {
    "tracking": ("tracking", ModeParams()),
    "guidance 0.5": ("guidance", ModeParams(guidance=0.5)),
    "transparent": ("transparent", ModeParams()),
    "aan": ("aan", ModeParams()),
    "path 0.03": ("path", ModeParams()),
}
#: The path mode's parameters per label of :data:`MODES` (others: the default).
PATH_PARAMS: dict[str, PathParams] = {"path 0.03": PathParams(tunnel_width_m=0.03)}
#: The patient's preferred gait [s], [m] (the device's: 1.2 s, 0.35 m).
PREFERRED = {"period_s": 1.0, "step_length_m": 0.30}
#: The active patients: label → their parameters.
PATIENTS: dict[str, ActiveParams] = {
    "healthy": ActiveParams(**PREFERRED),
    "weak (0.3)": ActiveParams(strength=0.3, **PREFERRED),
    "spastic": ActiveParams(spastic=True, **PREFERRED),
}
#: The figures: attribute → (column heading, unit).
FIGURES: dict[str, tuple[str, str]] = {
    "force_true_N": ("RMS interaction force, true", "N"),
    "force_est_N": ("RMS interaction force, estimated", "N"),
    "patient_torque_Nm": ("patient RMS joint torque", "N·m"),
    "patient_work_J": ("patient positive work per cycle", "J"),
    "device_work_J": ("device positive work per cycle", "J"),
    "tracking_error_mrad": ("RMS tracking error (clock)", "mrad"),
    "path_error_mm": ("feet from the path at the device's phase, RMS", "mm"),
    "gps_deg": ("Gait Profile Score, patient", "deg"),
}


@dataclass(frozen=True)
class Row:
    """One run's figures (module docstring), over the cycles after the ramp-in."""

    mode: str
    patient: str
    force_true_N: float
    force_est_N: float
    patient_torque_Nm: float
    patient_work_J: float
    device_work_J: float
    tracking_error_mrad: float
    gps_deg: float
    gps_planned_deg: float
    safety_state: str
    stop_s: float | None
    path_error_mm: float = math.nan


def config_of(mode: str, patient: str, duration_s: float, safety: bool = True) -> SimConfig:
    """The run of one mode (a key of :data:`MODES`) and patient (of :data:`PATIENTS`)."""
    name, params = MODES[mode]
    return SimConfig(
        patient_torque="active",
        patient_active=PATIENTS[patient],
        mode=name,
        modes=params,
        path=PATH_PARAMS.get(mode, PathParams()),
        duration_s=duration_s,
        safety=safety,
    )


def row_of(mode: str, patient: str, summary: dict[str, Any]) -> Row:
    """The table's row from a run's summary."""
    block = summary["interaction"]
    run = block["run"]
    n = sum(1 for c in block["cycles"] if c["cycle"] != "ramp_in")
    rms = lambda d: math.sqrt(float(np.mean(np.square(list(d.values())))))  # noqa: E731
    gps = summary["gait_profile_score_deg"]
    path = run.get("path_error_rms_m")
    return Row(
        mode=mode,
        patient=patient,
        force_true_N=run["rms_interaction_force_N"],
        force_est_N=run["rms_interaction_force_estimated_N"],
        patient_torque_Nm=rms(run["patient_rms_torque_Nm"]),
        patient_work_J=sum(run["patient_positive_work_J"].values()) / n,
        device_work_J=sum(run["device_positive_work_J"].values()) / n,
        tracking_error_mrad=1e3 * rms(run["rms_tracking_error_rad"]),
        gps_deg=gps["actual"],
        gps_planned_deg=gps["planned"],
        safety_state=summary["safety_state"],
        stop_s=next((e["t"] for e in summary["safety_events"] if e["kind"] != "warning"), None),
        path_error_mm=1e3 * rms(path) if path is not None else math.nan,
    )


def run_table(
    duration_s: float = 6.0,
    modes: tuple[str, ...] = tuple(MODES),
    patients: tuple[str, ...] = tuple(PATIENTS),
    safety: bool = True,
) -> list[Row]:
    """Run every mode on every patient; rows by patient, then mode."""
    rows = []
    for patient in patients:
        for mode in modes:
            summary = simulate(config_of(mode, patient, duration_s, safety)).summary()
            rows.append(row_of(mode, patient, summary))
    return rows


def table(rows: list[Row]) -> str:
    """The rows as a Markdown table."""
    head = ["patient", "mode", *(f"{h} [{u}]" for h, u in FIGURES.values()), "safety stop"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        stop = f"{r.safety_state} at {r.stop_s:.2f} s" if r.stop_s is not None else "none"
        cells = [r.patient, r.mode, *(_cell(getattr(r, k)) for k in FIGURES), stop]
        lines.append("| " + " | ".join(cells) + " |")
    if rows:
        lines.append("")
        lines.append(f"Gait Profile Score of the plan: {rows[0].gps_planned_deg:.2f} deg")
    return "\n".join(lines)


def _cell(x: float) -> str:
    """A figure in the table; a dash where the mode has none (NaN)."""
    return f"{x:.2f}" if math.isfinite(x) else "–"


def plot(rows: list[Row], path: Path, duration_s: float) -> None:
    """A panel per figure: the patients along x, a marker per mode."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    patients = list(dict.fromkeys(r.patient for r in rows))
    modes = list(dict.fromkeys(r.mode for r in rows))
    markers = dict(zip(modes, "osD^v<>", strict=False))
    colors = dict(
        zip(modes, ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"), strict=False)
    )
    fig, axes = plt.subplots(3, 3, figsize=(15, 10.5))
    for ax, (key, (title, unit)) in zip(axes.flat, FIGURES.items(), strict=False):
        for j, mode in enumerate(modes):
            xs = [i + 0.12 * (j - (len(modes) - 1) / 2) for i in range(len(patients))]
            ys = [
                next(getattr(r, key) for r in rows if r.mode == mode and r.patient == p)
                for p in patients
            ]
            ax.plot(xs, ys, markers[mode], color=colors[mode], ms=8, label=mode)
            stopped = [
                (x, y) for x, y, p in zip(xs, ys, patients, strict=True) if _stopped(rows, mode, p)
            ]
            if stopped:  # a run the supervisor stopped: a ring around its marker
                ax.plot(*zip(*stopped, strict=True), "o", ms=15, mfc="none", mec=colors[mode])
        ax.set_title(f"{title} [{unit}]", fontsize=10)
        ax.set_xticks(range(len(patients)), patients)
        ax.set_xlim(-0.5, len(patients) - 0.5)
        if key == "path_error_mm":  # the tunnels' half-widths, for scale
            for label, params in PATH_PARAMS.items():
                ax.axhline(1e3 * params.tunnel_width_m, ls="--", color="0.5", lw=1)
                ax.text(-0.45, 1e3 * params.tunnel_width_m, f" tunnel ({label})", va="bottom")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
    legend_ax = axes.flat[-1]
    legend_ax.axis("off")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    legend_ax.legend(handles, labels, title="mode", loc="center", fontsize=11)
    legend_ax.text(0.5, 0.1, "ringed: stopped by the safety supervisor", ha="center", fontsize=10)
    fig.suptitle(
        "Interaction modes on active patients (preferring 1.0 s, 0.30 m steps) walked by a "
        f"device planning 1.2 s, 0.35 m; {duration_s:g} s runs, figures after the 1.2 s ramp-in",
        fontsize=11,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100, format="png")
    plt.close(fig)


def _stopped(rows: list[Row], mode: str, patient: str) -> bool:
    return any(r.stop_s is not None for r in rows if r.mode == mode and r.patient == patient)


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=6.0, help="run length [s] (default 6)")
    parser.add_argument("--png", type=Path, default=None, help="write the figure here")
    parser.add_argument("--no-safety", action="store_true", help="runs without the supervisor")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.duration) and args.duration >= 2.4):
        parser.exit(2, f"duration must be >= 2.4 s (ramp-in and a cycle); got {args.duration}\n")
    if args.png is not None and not args.png.resolve().parent.is_dir():
        parser.exit(2, f"png: directory {args.png.resolve().parent} does not exist\n")
    rows = run_table(args.duration, safety=not args.no_safety)
    print(table(rows))
    if args.png is not None:
        plot(rows, args.png, args.duration)
        print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
