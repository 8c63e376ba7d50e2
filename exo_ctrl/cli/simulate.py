"""``exo-ctrl simulate [SCENARIO.toml]``: run the closed loop and write a rerun recording.

The run is a scenario (:mod:`exo_ctrl.scenario`): a TOML file, a preset, or
the default preset (the paper's device and gait on the belt).  A few common
options override it (``--controller``, ``--cycles``/``--duration``,
``--out``, ``--summary``, ``--no-record``) and ``--set section.key=value``
reaches any setting.  The long options (``--contact on``,
``--patient-torque spastic``, ...; :mod:`.long_options`) are accepted,
hidden from ``--help``: each is another spelling of one scenario key.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from .. import _validate as v
from .._io import DefaultOutput, DerivedOutput, is_special, partial_path
from ..control import controller_name
from ..exceptions import InvalidParameter
from ..model import load_exo
from ..plan import GaitParams
from ..plan.exercise import CALIBRATION_DURATION_S
from ..plant import consistency_warning
from ..record import RerunRecorder
from ..record.sizing_plot import OperatingPoints, write_torque_speed_plot
from ..record.viewer import find_viewer
from ..scenario import DEFAULT_PRESET, PRESETS, RecordingParams, Scenario
from ..scenario.load import scenario_document, scenario_from_document
from ..sim import SimConfig, SimResult, drive_for, simulate
from ..sim.config import MAX_DURATION_S
from ..sim.scenario_read import apply_setting
from .common import check_outputs, format_summary, import_from_cwd, recording_line, write_json
from .long_options import add_long_options, given_options, option_settings

__all__ = ["register", "run", "scenario_of", "sim_config"]

#: The options ``simulate --help`` shows; the long tail is hidden (docs/cli.md).
SHOWN = frozenset(
    {
        "help",
        "scenario",
        "preset",
        "set",
        "controller",
        "cycles",
        "duration",
        "out",
        "summary",
        "no_record",
        "scene_rate",
        "plots",
        "spawn",
    }
)

USAGE = (
    "exo-ctrl simulate [SCENARIO.toml | --preset NAME] [--controller pd|ct|qp|MODULE:CLASS] "
    "[--cycles N | --duration SEC] [--set SECTION.KEY=VALUE ...] [--out PATH.rrd] "
    "[--summary PATH.json] [--no-record] [--plots DIR] [--spawn]"
)

EPILOG = (
    "Every setting of a run is a key of the scenario file: 'exo-ctrl scenario --preset "
    f"{DEFAULT_PRESET} --out my.toml' writes them all with their units, defaults and "
    "meaning (docs/scenarios.md). Each also has a long option (--contact on, --period 1.1, "
    "...), hidden here: docs/options.md lists them."
)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` subcommand."""
    p = sub.add_parser(
        "simulate",
        help="run a scenario: the closed loop, a summary and a rerun recording",
        usage=USAGE,
        description="Run the closed loop of a scenario, print a summary and write a rerun "
        "recording.",
        epilog=EPILOG,
    )
    p.add_argument(
        "scenario",
        nargs="?",
        default=None,
        metavar="SCENARIO.toml",
        help=f"the scenario file (default: the preset {DEFAULT_PRESET!r})",
    )
    p.add_argument(
        "--preset",
        default=None,
        metavar="NAME",
        help="a shipped scenario instead of a file: " + ", ".join(PRESETS) + " (default: none; "
        f"with no file either, {DEFAULT_PRESET})",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override one key of the scenario, e.g. --set gait.period=1.1 "
        "--set contact.enabled=false (repeatable; 'default' restores a key's default) "
        "(default: none)",
    )
    p.add_argument(
        "--controller",
        default=None,
        metavar="NAME",
        help="pd (the paper's PD voltage law), ct (computed torque + PD), qp (CT + PD "
        "through a QP under drive limits and cuff-force bounds), or your own: the import "
        "path of an exo_ctrl.control.Controller subclass, e.g. mypkg.ctl:Impedance "
        "(docs/controllers.md) (default: the scenario's)",
    )
    span = p.add_mutually_exclusive_group()
    span.add_argument(
        "--cycles",
        type=float,
        default=None,
        metavar="N",
        help="gait cycles at full speed after the ramp-in [cycles]; 0.5 = one step "
        "(default: none, the scenario's run.duration_s: 2 cycles after the ramp-in in most "
        "presets)",
    )
    span.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="SEC",
        help="simulated time, ramps included [s] (default: the scenario's run.duration_s, "
        f"{SimConfig().duration_s:g} s in most presets)",
    )
    outputs = p.add_argument_group("outputs (default: the scenario's [recording] section)")
    outputs.add_argument(
        "--out",
        default=None,
        metavar="PATH.rrd",
        help=f"the rerun recording (default: recording.out, {RecordingParams().out})",
    )
    outputs.add_argument(
        "--summary",
        default=None,
        metavar="PATH.json",
        help="also write the summary as JSON (default: recording.summary, none)",
    )
    outputs.add_argument("--no-record", action="store_true", help="write no recording")
    outputs.add_argument(
        "--scene-rate",
        type=float,
        default=None,
        metavar="HZ",
        help="rate of the recording's 3-D scene [Hz]; the plots keep every tick (default: "
        f"recording.scene_rate_hz, {RecordingParams().scene_rate_hz:g})",
    )
    outputs.add_argument(
        "--plots",
        default=None,
        metavar="DIR",
        help="write the drives' torque-speed operating points against their limits as "
        "DIR/torque_speed.png (an existing directory; needs matplotlib) (default: none)",
    )
    outputs.add_argument(
        "--spawn", action="store_true", help="also stream to a rerun viewer while it runs"
    )
    for action in add_long_options(p):
        action.hidden_help = action.help  # what docs/options.md lists
        action.help = argparse.SUPPRESS
    p.set_defaults(func=run)


#: The base of a run given by long options alone: SimConfig()'s defaults, as they always were.
FLAGS_PRESET = "paper-free-air"


def _set(doc: dict[str, Any], path: str, value: Any) -> None:
    """Set key ``path`` (``gait.period``) of a scenario document; None unsets it."""
    keys = path.split(".")
    for key in keys[:-1]:
        doc = doc.setdefault(key, {})
    if value is None:
        doc.pop(keys[-1], None)
    else:
        doc[keys[-1]] = value


def scenario_of(args: argparse.Namespace) -> Scenario:
    """The run ``args`` describe: the scenario, the long options given, ``--set``, the rest.

    Precedence, lowest first: the scenario file or the preset, the long
    options (:mod:`.long_options`, each a key of the scenario), ``--set`` in
    order, then ``--controller`` and ``--duration``/``--cycles``.  Long
    options given without a file or a preset describe a run on
    :data:`FLAGS_PRESET` (``SimConfig()``'s defaults) lasting its ramp-in and
    two gait cycles (the calibration exercise its own duration, a session
    its segments'), as they always have.  With nothing given the run is
    :data:`~exo_ctrl.scenario.DEFAULT_PRESET`.

    Raises:
        InvalidScenario: a key out of its range, naming the option or
            ``--set`` that set it.

    """
    given = given_options(args)
    chosen = args.scenario is not None or args.preset is not None
    preset = args.preset if chosen or not given else FLAGS_PRESET
    doc, source = scenario_document(args.scenario, preset)
    origin: dict[str, str] = {}
    for path, value, option in option_settings(args):
        _set(doc, path, value)
        origin[path] = option
    for setting in args.set:
        apply_setting(doc, setting)
        origin[setting.partition("=")[0].strip()] = "--set"
    _check_options(args, doc, given)
    run = doc.setdefault("run", {})
    if args.controller is not None:
        run["controller"] = args.controller
        origin["run.controller"] = "--controller"
    if args.duration is not None:
        run["duration_s"] = args.duration
        origin["run.duration_s"] = "--duration"
    elif args.cycles is not None:
        run["duration_s"] = _cycles_duration(doc, args.cycles)
        origin["run.duration_s"] = "--cycles"
    elif given and not chosen and "duration_s" not in run:
        calibration = run.get("exercise") == "calibration"
        two = round(_cycles_duration(doc, 2.0), 9)  # to the nanosecond: 3.6 s, not 3.5999…
        run["duration_s"] = CALIBRATION_DURATION_S if calibration else two
    return scenario_from_document(doc, source, origin)


def _check_options(args: argparse.Namespace, doc: dict[str, Any], given: list) -> None:
    """Refuse an active patient's options without one, and ``--cycles`` beside a session."""
    torque = doc.get("interaction", {}).get("patient_torque", "none")
    active = [opt.option for opt in given if opt.key.startswith("patient_active.")]
    if active and torque != "active":
        raise InvalidParameter(
            "patient_torque", torque, f"active with {active[0]} (an active patient's)"
        )
    if args.cycles is not None and any(opt.form == "session" for opt in given):
        raise InvalidParameter(
            "cycles", args.cycles, "unset with --session", "its segments' durations set the run"
        )


def _cycles_duration(doc: dict[str, Any], cycles: float) -> float:
    """The duration [s] of ``cycles`` gait cycles after the ramp-in, the ramps included."""
    cycles = v.positive("cycles", cycles)
    period = doc.get("gait", {}).get("period", GaitParams().period)
    ramp_in = doc["run"].get("ramp_in_s")
    ramp_out = doc["run"].get("ramp_out_s", 0.0)
    lead = period if ramp_in is None else ramp_in
    duration = lead + cycles * period + ramp_out
    if duration > MAX_DURATION_S:
        most = (MAX_DURATION_S - lead - ramp_out) / period
        raise InvalidParameter(
            "cycles",
            cycles,
            f"at most {most:.6g} at the {period:g} s period",
            f"the run would last {duration:.4g} s, beyond {MAX_DURATION_S:g} s",
        )
    return duration


def sim_config(args: argparse.Namespace) -> SimConfig:
    """The run's SimConfig from the parsed options (:func:`scenario_of`)."""
    return scenario_of(args).config


def run(args: argparse.Namespace) -> int:
    """Run, record, print the summary; 0 completed, 1 diverged or failed, 130 interrupted.

    The scenario is read and the output paths checked before anything else;
    the summary is written after the run.
    """
    import_from_cwd()  # a user's controller given as module:Class
    scenario = scenario_of(args)
    config, recording = scenario.config, scenario.recording
    # the scenario's output: a path the user did not name on the command line
    args.out = args.out if args.out is not None else DefaultOutput(recording.out)
    args.no_record = args.no_record or not recording.enabled
    args.summary = args.summary if args.summary is not None else (recording.summary or None)
    scene_rate = args.scene_rate if args.scene_rate is not None else recording.scene_rate_hz
    plot_file = None if args.plots is None else Path(args.plots) / "torque_speed.png"
    args.plot_file = None if plot_file is None else DerivedOutput(plot_file)  # never via a link
    inputs = {  # an input option given names it instead (check_outputs)
        "the exoskeleton URDF (urdf.exo)": config.exo,
        "the patient URDF (urdf.patient)": config.patient,
        "the device's exoskeleton URDF (belief.exo)": config.belief.exo,
        "the device's patient URDF (belief.patient)": config.belief.patient,
    }
    if args.scenario is not None:
        inputs["the scenario file"] = args.scenario
    recorded = {} if args.no_record else {"out": "--out"}
    args.partial_file = None  # where a regular file's recording is written first (claimed)
    if not args.no_record and not is_special(args.out):
        args.partial_file = DerivedOutput(partial_path(args.out))
        recorded["partial_file"] = "--out"
    check_outputs(
        args,
        reads={k: str(p) for k, p in inputs.items() if p is not None and Path(p).is_file()},
        summary="--summary",
        plot_file="--plots",
        **recorded,
    )
    points = OperatingPoints() if args.plots is not None else None  # needs matplotlib
    warning = consistency_warning(config.motor)
    if warning:
        print(f"exo-ctrl simulate: warning: the drive: {warning}", file=sys.stderr)
    notes = []
    if scenario.source == f"preset {FLAGS_PRESET}" and args.preset is None:
        notes.append(
            f"long options without --preset or a scenario file run on preset {FLAGS_PRESET} "
            "(the feet in free air); --preset paper for the default scenario (the belt on)"
        )
    observers: list = [_WarnAtStart(notes)]
    if not args.no_record:
        recorder = RerunRecorder(args.out, spawn=args.spawn, scene_rate_hz=scene_rate)
        observers.append(recorder)
    if points is not None:
        observers.append(points)
    result = simulate(config, observers=observers, progress=True, keep_history=False, warmup=True)
    summary = result.summary()
    if args.summary:
        write_json(args.summary, summary)
    print(format_summary(summary))
    if points is not None:
        exo = load_exo(config.exo)
        name = controller_name(config.controller)
        title = f"{name} controller, {config.duration_s:g} s of the gait"
        motor = drive_for(config.motor, exo)
        write_torque_speed_plot(points, motor, exo.effort_limit, args.plot_file, title)
        print(f"torque-speed plot: {args.plot_file}")
    if not args.no_record:
        print(recording_line(recorder.written, args.out, find_viewer() or "rerun"))
    if result.status == "interrupted":
        return 143 if result.error.startswith("terminated by SIGTERM") else 130
    if result.status != "completed":
        print(f"exo-ctrl simulate: error: {result.error}", file=sys.stderr)
        return 1
    return 0


class _WarnAtStart:
    """Prints notes on the run, then its warnings, before its first tick.

    The warnings: a device that does not fit its patient, say.  A run refused before it
    starts prints only the refusal.
    """

    def __init__(self, notes: list[str]) -> None:
        self.notes = notes

    def start(self, result: SimResult) -> None:
        for text in self.notes:
            print(f"exo-ctrl simulate: note: {text}", file=sys.stderr)
        for text in result.notes:
            print(f"exo-ctrl simulate: note: {text}", file=sys.stderr)
        for text in result.warnings:
            print(f"exo-ctrl simulate: warning: {text}", file=sys.stderr)

    def chunk(self, result: SimResult, start: int, rows: dict[str, Any]) -> None:
        """Nothing: the warnings are said at the start."""

    def finish(self, result: SimResult) -> None:
        """Nothing: the summary lists the warnings again."""
