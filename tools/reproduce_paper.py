"""Reproduce the paper's figures and its §VI numbers.

    .venv/bin/python tools/reproduce_paper.py [--out DIR] [--controller pd|ct]
        [--motor default|paper-printed]

Writes PNG plots in the manner of the paper's Figs. 3, 5, 6 and 8 into DIR
(default ``paper_figures/``) and prints the peak drive torques and cuff forces
of the §VI run (Table I, patient torques zero, step 0.35 m, lift 0.1 m) beside
the paper's ~100 N·m and ~200 N.  The run starts standing, ramps into the
gait over one period and the figures and peaks are of the one gait cycle
after the ramp.

The drive: by default exo_ctrl's energy-consistent drive (the paper's
winding, L, R and k_E, with k_m = 1/k_E, a 120:1 gearbox of 85 %
efficiency, 24 V, 32 A; exo_ctrl/plant/motor.py).  ``--motor paper-printed``
runs Table I's pair as printed, k_m = 0.35 N·m/A with k_E = 25.9 rad/(V·s)
(k_m k_E = 9.06: that drive puts out nine times the mechanical power its
back-EMF takes in), a lossless 50:1 gearbox and 10 A capped at the URDF
effort (8.57 A), with the gains it was tuned with (k_p = 100 V/rad,
k_d = 2 V·s/rad).

Other parameters the paper does not report, as chosen in exo_ctrl (see the
module docstrings): cuff damping 100 N·s/m, PD gains k_p = 300 V/rad,
k_d = 5 V·s/rad for the default drive, link inertias (exo: uniform
cylinders; patient: Winter's tables), joint damping and friction, hip height
0.90 m, shape coefficient 0.5, period 1.2 s.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl.control import PDGains
from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES
from exo_ctrl.plan.gait import GaitParams, GaitPlan
from exo_ctrl.plan.kinematics import inverse_kinematics
from exo_ctrl.plant import MOTOR_PRESETS, consistency_warning, motor_preset
from exo_ctrl.sim import SimConfig, simulate

PAPER_PEAK_TORQUE_NM = 100.0
PAPER_PEAK_CUFF_FORCE_N = 200.0


def _plt():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise SystemExit(
            'matplotlib is needed for the plots: .venv/bin/pip install -e ".[plots]"'
        ) from None
    return plt


def _gait_label(p: GaitParams) -> str:
    """The gait parameter vector s̄ with its entries named (paper §III)."""
    return (
        f"step s = {p.step_length:g} m, lift h_s = {p.lift_height:g} m, "
        f"hip height H_s = {p.hip_height:g} m, k_v = {p.shape_coeff:g}, period T_s = {p.period:g} s"
    )


def _legend_below(ax, ncol: int) -> None:
    """The axes' legend under them, off the curves."""
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=ncol, frameon=False)


def fig3(out: Path) -> Path:
    """Foot paths for the paper's two Fig. 3 parameter vectors."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2), constrained_layout=True)
    for ax, vec, label in zip(
        axes, ((0.2, 0.3, 0.7, 0.5, 4.0), (0.6, 0.1, 0.8, 0.25, 4.0)), "ab", strict=True
    ):
        params = GaitParams(*vec)
        feet = GaitPlan(params).feet(np.linspace(0, params.period, 801))
        ax.plot(feet.pos[:, 0, 0], feet.pos[:, 0, 1], label="left foot O_L3")
        ax.plot(feet.pos[:, 1, 0], feet.pos[:, 1, 1], "--", label="right foot O_R3")
        ax.set_title(f"({label}) " + _gait_label(params).replace(", hip", ",\nhip"), fontsize=9)
        ax.set_xlabel("foot x relative to the hip [m]")
        ax.set_ylabel("foot z relative to the hip [m]")
        ax.axis("equal")
        ax.grid(True)
        _legend_below(ax, 2)
    fig.suptitle("Fig. 3: foot paths over one gait period")
    path = out / "fig3_foot_paths.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def fig5_6(out: Path) -> list[Path]:
    """Coordinates and absolute angles over time, §IV: links 0.5 m, s̄ = (0.5, 0.2, 0.8, 0.5, 1)."""
    plt = _plt()
    params = GaitParams(0.5, 0.2, 0.8, 0.5, 1.0)
    t = np.linspace(0, 2.0, 2001)
    feet = GaitPlan(params).feet(t)
    fig, ax = plt.subplots(figsize=(9, 4.8), constrained_layout=True)
    for leg, name in enumerate(("L", "R")):
        ax.plot(t, feet.pos[:, leg, 0], label=f"x of O_{name}3")
        ax.plot(t, feet.pos[:, leg, 1], "--", label=f"y of O_{name}3 (up, the URDF's z)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("foot coordinate relative to the hip [m]")
    ax.set_title("Fig. 5: foot coordinates, links 0.5 m, " + _gait_label(params), fontsize=9)
    ax.grid(True)
    _legend_below(ax, 4)
    paths = [out / "fig5_foot_coordinates.png"]
    fig.savefig(paths[0], dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(9, 4.8), constrained_layout=True)
    for leg, name in enumerate(("L", "R")):
        phi1, phi2 = inverse_kinematics(feet.pos[:, leg, 0], feet.pos[:, leg, 1], 0.5, 0.5)
        ax.plot(t, np.degrees(phi1), label=f"φ_{name}1 (thigh)")
        ax.plot(t, np.degrees(phi2), "--", label=f"φ_{name}2 (shank)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("absolute link angle from +x [deg]")
    ax.set_title("Fig. 6: absolute link angles, " + _gait_label(params), fontsize=9)
    ax.grid(True)
    _legend_below(ax, 4)
    paths.append(out / "fig6_absolute_angles.png")
    fig.savefig(paths[1], dpi=120)
    plt.close(fig)
    return paths


def fig8(out: Path, controller: str, motor: str) -> tuple[Path, dict]:
    """The §VI run: one gait cycle after the ramp-in, Table I, patient torques zero."""
    plt = _plt()
    gait = GaitParams(step_length=0.35, lift_height=0.10)
    config = SimConfig(
        gait=gait,
        controller=controller,
        motor=motor_preset(motor),
        gains=PDGains.paper_printed() if motor == "paper-printed" else PDGains(),
        duration_s=2 * gait.period,
        ramp_in_s=gait.period,
    )
    result = simulate(config)
    cycle = result.t >= gait.period  # the cycle at full speed after the ramp
    s = {name: value[cycle] for name, value in result.signals.items()}
    t = result.t[cycle]
    fig, axes = plt.subplots(3, 1, figsize=(10, 11), sharex=True, constrained_layout=True)
    for j, name in enumerate(JOINT_NAMES[:2]):
        axes[0].plot(t, np.degrees(s["q"][:, j]), label=f"exo {name}")
        axes[0].plot(t, np.degrees(s["q_patient"][:, j]), "--", label=f"patient {name}")
    axes[0].set_ylabel("joint angle [deg]")
    for j, name in enumerate(JOINT_NAMES[:2]):
        axes[1].plot(t, s["drive_torque"][:, j], label=name)
    axes[1].set_ylabel("drive torque [N·m]")
    for c, name in enumerate(CUFF_NAMES[:2]):
        axes[2].plot(t, s["cuff_force"][:, c, 0], label=f"{name} x")
        axes[2].plot(t, s["cuff_force"][:, c, 1], "--", label=f"{name} z")
    axes[2].set_ylabel("cuff force on exo [N]")
    axes[2].set_xlabel("t [s]")
    for ax in axes:
        ax.grid(True)
        ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    fig.suptitle(
        f"Fig. 8: left leg, {controller.upper()} controller, {motor} drive, patient torques "
        "zero, the gait cycle after the ramp-in\n" + _gait_label(config.gait),
        fontsize=10,
    )
    path = out / f"fig8_dynamics_{controller}_{motor}.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    summary = result.summary()
    summary["cycle"] = {
        "peak_drive_torque_Nm": {
            name: float(np.max(np.abs(s["drive_torque"][:, j])))
            for j, name in enumerate(JOINT_NAMES)
        },
        "peak_cuff_force_N": {
            name: float(np.max(np.hypot(*s["cuff_force"][:, c].T)))
            for c, name in enumerate(CUFF_NAMES)
        },
        "peak_motor_current_A": {
            name: float(np.max(np.abs(s["current"][:, j]))) for j, name in enumerate(JOINT_NAMES)
        },
    }
    return path, summary


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="paper_figures", help="output folder")
    parser.add_argument("--controller", default="pd", choices=("pd", "ct"))
    parser.add_argument("--motor", default="default", choices=MOTOR_PRESETS)
    args = parser.parse_args()
    warning = consistency_warning(motor_preset(args.motor))
    if warning:
        print(f"reproduce_paper: warning: --motor {args.motor}: {warning}", file=sys.stderr)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    written = [fig3(out), *fig5_6(out)]
    path, summary = fig8(out, args.controller, args.motor)
    written.append(path)
    cycle = summary["cycle"]
    torque = max(cycle["peak_drive_torque_Nm"].values())
    force = max(cycle["peak_cuff_force_N"].values())
    print(
        f"§VI run, controller {args.controller}, {args.motor} drive, the gait cycle after a "
        f"{summary['duration_s'] / 2:.2f} s ramp-in:"
    )
    print(f"  peak drive torque {torque:6.1f} N·m   (paper: about {PAPER_PEAK_TORQUE_NM:.0f} N·m)")
    for name, value in cycle["peak_drive_torque_Nm"].items():
        amps = cycle["peak_motor_current_A"][name]
        print(f"    {name:<11}{value:6.1f} N·m  at most {amps:5.1f} A")
    print(f"  peak cuff force   {force:6.1f} N     (paper: about {PAPER_PEAK_CUFF_FORCE_N:.0f} N)")
    for name, value in cycle["peak_cuff_force_N"].items():
        print(f"    {name:<11}{value:6.1f} N")
    print(f"  drive energy balance residual {summary['energy_balance_residual_rel']:.2e}")
    print("figures:", ", ".join(str(p) for p in written))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
