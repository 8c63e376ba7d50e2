"""What the subcommands share: the gait options, the run summary as text, the parser class."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any, TextIO

from .._io import atomic_write, check_output, same_file_key
from .._plugin import import_from_cwd
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES
from ..plan import GaitParams
from .long_options import GAIT_OPTIONS, add_long_options

__all__ = [
    "INPUT_OPTIONS",
    "Parser",
    "add_accept_implausible",
    "add_gait_options",
    "check_outputs",
    "format_summary",
    "gait_params_from",
    "import_from_cwd",
    "recording_line",
    "write_json",
]


class Parser(argparse.ArgumentParser):
    """argparse with exit code 2 and a one-line message on bad usage.

    ``--help`` that cannot be written (a closed pipe, a full device) raises
    the OSError, which :func:`~exo_ctrl.cli.app.main` turns into exit 1.
    """

    def print_help(self, file: TextIO | None = None) -> None:
        """Print the help, flushed; a failed write raises (argparse would drop it silently)."""
        stream = sys.stdout if file is None else file
        stream.write(self.format_help())
        stream.flush()

    def error(self, message: str) -> None:  # type: ignore[override]
        """Print ``prog: error: message`` on one line and exit with code 2."""
        self.exit(2, f"{self.prog}: error: {message}\n")


def add_gait_options(parser: argparse.ArgumentParser) -> None:
    """The gait's options (:data:`~.long_options.GAIT_OPTIONS`; GaitParams' defaults)."""
    add_long_options(parser, GAIT_OPTIONS)


def add_accept_implausible(parser: argparse.ArgumentParser) -> None:
    """``--accept-implausible``: read a CSV log that looks wrong for the device, with a warning."""
    parser.add_argument(
        "--accept-implausible",
        action="store_true",
        help="read a CSV log whose angles, speeds or time steps are far outside the "
        "exoskeleton's URDF limits (angles in degrees? times in hours?) with a warning "
        "(default: refused, naming the first such sample)",
    )


def gait_params_from(args: argparse.Namespace) -> GaitParams:
    """GaitParams from the gait options given (GaitParams' defaults for the others)."""
    given = {}
    for opt in GAIT_OPTIONS:
        section, _, name = opt.key.partition(".")
        if section == "gait" and hasattr(args, opt.dest):
            given[name] = getattr(args, opt.dest)
    return GaitParams(**given)


#: The options of the subcommands that name input files, attribute → name: every
#: output is checked against those given (a value that is not an existing file,
#: such as ``--patient human``, is no file to protect).
INPUT_OPTIONS = {
    "file": "the input file",
    "scenario": "the scenario file",
    "exo": "--exo",
    "patient": "--patient",
    "session": "--session",
    "controller_patient": "--controller-patient",
    "controller_exo": "--controller-exo",
}


def check_outputs(
    args: argparse.Namespace, reads: dict[str, str] | None = None, **options: str
) -> None:
    """Check the output paths given in ``args`` before any work starts.

    Two paths are one file when they have the same device and inode
    (:func:`exo_ctrl._io.same_file_key`: hard and symbolic links count).

    Args:
        args: the parsed options; the input files among them
            (:data:`INPUT_OPTIONS`) are protected without being listed.
        reads: further input files, a description → path
            (``{"the input file": args.file}``): an output may not replace one.
        options: attribute of ``args`` → the option's name (``summary="--summary"``);
            an attribute that is None (not given) is skipped.

    Raises:
        InvalidParameter: a path cannot be written (:func:`exo_ctrl._io.check_output`),
            two options name one file, or an output names an input.

    """
    named = {
        name: getattr(args, attribute)
        for attribute, name in INPUT_OPTIONS.items()
        if isinstance(getattr(args, attribute, None), (str, os.PathLike))
    }
    inputs = {**(reads or {}), **named}  # an option the user typed names the file first
    taken = {
        same_file_key(path): name
        for name, path in inputs.items()
        if isinstance(path, (str, os.PathLike)) and os.path.isfile(path)
    }
    for attribute, option in options.items():
        path = getattr(args, attribute)
        if path is None:
            continue
        check_output(path, option)
        if os.path.exists(path) and not os.path.isfile(path):  # a device: /dev/null twice
            continue
        key = same_file_key(path)
        other = taken.get(key)
        if other is not None:
            what = other if other in inputs else f"{other}'s"
            raise InvalidParameter(
                option, str(path), f"a file other than {what}", "one would replace the other"
            )
        taken[key] = option


def recording_line(written: str | os.PathLike[str], out: str, viewer: str) -> str:
    """The line naming a run's recording: ``out``, or its partial file if the run was cut.

    Args:
        written: where the recording is (:attr:`exo_ctrl.record.RerunRecorder.written`).
        out: the path asked for.
        viewer: the viewer's command.

    """
    if os.fspath(written) == os.fspath(out):
        return f"recording: {out} (view offline: {viewer} {out})"
    kept = f"{out} kept as it was" if os.path.lexists(out) else f"{out} not written"
    return f"recording: {written} (the run was cut short: {kept}; view offline: {viewer} {written})"


def write_json(path: str | os.PathLike[str], data: dict[str, Any]) -> None:
    """Write ``data`` as indented JSON, atomically (a failure leaves no file).

    Raises:
        OutputError: the file could not be written (e.g. the disk is full).

    """
    with atomic_write(path) as handle:
        json.dump(data, handle, indent=2)
        handle.write("\n")


def format_summary(summary: dict[str, Any]) -> str:
    """A run's summary (:meth:`exo_ctrl.sim.SimResult.summary`) as a plain-text table."""
    lines = [
        f"controller {summary['controller']}, {summary['status']}: "
        f"{summary['duration_s']:.3f} s simulated in {summary['wall_time_s']:.2f} s "
        f"(real-time factor {summary['real_time_factor']:.1f}), "
        f"belt speed {summary['belt_speed_mps']:.3f} m/s",
        f"{'joint':<12}{'rms err [mrad]':>15}{'max err [mrad]':>15}{'peak τ [N·m]':>13}"
        f"{'peak I [A]':>11}{'peak U [V]':>11}",
    ]
    for j in JOINT_NAMES:
        lines.append(
            f"{j:<12}{1e3 * summary['rms_tracking_error_rad'][j]:>15.3f}"
            f"{1e3 * summary['max_tracking_error_rad'][j]:>15.3f}"
            f"{summary['peak_drive_torque_Nm'][j]:>13.1f}"
            f"{summary['peak_motor_current_A'][j]:>11.2f}{summary['peak_motor_voltage_V'][j]:>11.2f}"
        )
    cuffs = ", ".join(f"{c} {f:.1f}" for c, f in summary["peak_cuff_force_N"].items())
    lines.append(f"peak cuff force [N]: {cuffs}")
    lines += estimate_lines(summary)
    lines.append(
        f"{'drive sizing':<12}{'rms τ [N·m]':>12}{'peak q̇ [rad/s]':>16}{'peak P [W]':>11}"
        f"{'rms I [A]':>10}{'at τ, I, U limit [% of ticks]':>31}"
    )
    for j, d in summary["drive_sizing"].items():
        shares = (d[f"share_at_{x}"] for x in ("torque_limit", "current_limit", "supply_voltage"))
        lines.append(
            f"{j:<12}{d['rms_torque_Nm']:>12.1f}{d['peak_speed_rad_s']:>16.2f}"
            f"{d['peak_power_W']:>11.1f}{d['rms_current_A']:>10.2f}"
            f"{', '.join(f'{100 * x:.1f}' for x in shares):>31}"
        )
    if "energy_balance_residual_rel" in summary:
        residual = summary["energy_balance_residual_rel"]
        lines.append(
            f"drive energy balance: residual {residual:.2e} of the energy drawn"
            + (" (the drive model is not energy-consistent)" if residual > 1e-6 else "")
        )
    gps = summary.get("gait_profile_score_deg") or {}
    if gps.get("actual") is not None:  # exo_ctrl/sim/gait_score.py
        lines.append(
            f"gait profile score (sagittal hip, knee; Baker 2009) against normative gait: "
            f"patient {gps['actual']:.1f} deg, plan {gps['planned']:.1f} deg"
        )
    if "slip_speed_rms_mps" in summary:
        feet = ", ".join(f"{f} {x:.1f}" for f, x in summary["peak_ground_force_N"].items())
        lines.append(
            f"belt contact after the ramp-in: slip RMS {summary['slip_speed_rms_mps']:.4f} m/s "
            f"(max {summary['slip_speed_max_mps']:.4f}), touchdown vertical "
            f"{summary['touchdown_speed_mps']:.4f} m/s, horizontal "
            f"{summary['touchdown_slip_mps']:.4f} m/s; peak ground force [N]: {feet}; "
            f"belt speed error RMS {summary['belt_speed_error_rms_mps']:.4f} m/s"
        )
        if summary.get("stop_touchdown_count") or summary.get("stop_slip_speed_max_mps"):
            lines.append(
                "belt contact during the supervisor's stop (not in the figures above): slip "
                f"RMS {summary['stop_slip_speed_rms_mps']:.4f} m/s, "
                f"{summary['stop_touchdown_count']} touchdowns, worst vertical "
                f"{summary['stop_touchdown_speed_mps']:.4f} m/s, horizontal "
                f"{summary['stop_touchdown_slip_mps']:.4f} m/s"
            )
    pf = summary.get("patient_feet")
    if pf:  # --patient-feet on (exo_ctrl/plant/patient_feet.py)
        lines.append(
            "patient's feet on the belt: peak ground force [N] "
            + ", ".join(f"{f} {x:.1f}" for f, x in pf["peak_ground_force_N"].items())
            + "; after the ramp-in deepest in contact [mm] "
            + ", ".join(f"{f} {x * 1e3:.2f}" for f, x in pf["max_penetration_m"].items())
            + f", slip RMS {pf['slip_speed_rms_mps']:.4f} m/s"
        )
    if "stance_knee_torque_rms_Nm" in summary:  # exo_ctrl/sim/load_stats.py
        rms, peak = summary["stance_knee_torque_rms_Nm"], summary["stance_knee_torque_peak_Nm"]
        lines.append(
            "stance knee torque after the ramp-in [N·m]: "
            + ", ".join(f"{side} RMS {rms[side]:.1f} (peak {peak[side]:.1f})" for side in rms)
        )
    pelvis = summary.get("pelvis")
    if pelvis and pelvis["mean_vertical_ground_force_N"] is not None:
        lines.append(
            f"pelvis supported: {pelvis['support_N']:.0f} N ({pelvis['bws_fraction']:.0%} of "
            f"body weight); vertical ground force over whole cycles "
            f"{pelvis['mean_vertical_ground_force_N']:.1f} N against the unsupported weight "
            f"{pelvis['unsupported_weight_N']:.1f} N "
            + (
                f"with the harness (travel stops, brake) carrying "
                f"{pelvis['mean_harness_stop_force_N']:.1f} N "
                if pelvis["mean_harness_stop_force_N"] > 0.0
                else ""
            )
            + f"(balance {pelvis['vertical_balance_error_rel']:+.2%}); "
            f"pelvis excursion {1e3 * pelvis['excursion_m']:.1f} mm"
        )
    if "device_belief" in summary:
        lines.append(describe_belief(summary["device_belief"]))
    for event in summary["safety_events"][:5]:
        lines.append(f"safety: {event['message']}")
    if summary["safety_state"] != "normal":
        lines.append(f"safety supervisor ended in state {summary['safety_state']!r}")
    return "\n".join(lines)


def estimate_lines(summary: dict[str, Any]) -> list[str]:
    """The cuff-force estimate per component (the summary's ``…_over_rms`` keys), or none.

    One line of each cuff's normal and along errors over their RMS true values
    [%] ("—": a true component under 1 N RMS), one of where each component
    comes from (``cuff_force_estimate_components``: observed, or from models).
    """
    normal = summary.get("cuff_force_estimate_normal_rms_error_over_rms")
    along = summary.get("cuff_force_estimate_along_rms_error_over_rms")
    if normal is None or along is None:
        return []

    def pct(x: float | None) -> str:
        return "—" if x is None else f"{100 * x:.1f}"

    start = summary.get("cuff_force_estimate_components_from_s")
    since = "" if start is None else f" from t = {start:g} s"
    cuffs = ", ".join(f"{c} {pct(normal[c])} / {pct(along[c])}" for c in normal)
    lines = [f"cuff force estimate{since}, RMS error over RMS true, normal / along [%]: {cuffs}"]
    components = summary.get("cuff_force_estimate_components") or {}
    sources = {f"{c} {part}": how for c, d in components.items() for part, how in d.items()}
    observed = [name for name, how in sources.items() if how.startswith("observed")]
    by_cuffs = any("cuff's" in how for how in sources.values())
    if components:
        lines.append(
            f"observed by the joint torque{' and cuff' if by_cuffs else ''} sensors: "
            + (", ".join(observed) or "none")
            + "; every other component from models or assumptions"
        )
    return lines


def describe_belief(belief: dict[str, Any]) -> str:
    """One line on what the device held (the summary's ``device_belief``)."""
    patient = belief["patient"]
    if patient == "nominal":
        patient = (
            f"nominal ({belief['patient_height_m']:g} m, {belief['patient_mass_kg']:g} kg, "
            f"{belief['patient_sex']}, de Leva's tables)"
        )
    elif patient == "truth":
        patient = "the true patient (perfect knowledge: the ideal comparison)"
    force = belief["safety_cuff_force"]
    watched = {
        "estimate": "estimated",
        "widened estimate": "estimated (the shanks' along force widened by what it cannot see)",
    }.get(force, "true (a force sensor per cuff: ideal)")
    return (
        f"device model: patient {patient}, cuffs {belief['cuffs']}, drive {belief['drive']}, "
        f"estimator {belief['estimator']}, plan {belief.get('plan', 'precomputed')}; "
        f"the supervisor watched the {watched} cuff forces"
    )
