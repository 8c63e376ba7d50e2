"""``exo-ctrl simulate [SCENARIO.toml]``: run the closed loop and write a rerun recording.

The run is a scenario (:mod:`exo_ctrl.scenario`): a TOML file, a preset, or
the default preset (the paper's device and gait on the belt).  A few common
options override it (``--controller``, ``--cycles``/``--duration``,
``--out``, ``--summary``, ``--no-record``) and ``--set section.key=value``
reaches any setting.  The older long options (``--contact on``,
``--patient-torque spastic``, ...; :mod:`.simulate_options`) are still
accepted, hidden from ``--help``: each one given becomes a setting.
"""

from __future__ import annotations

import argparse
import functools
import sys
from pathlib import Path
from typing import Any

from .. import _validate as v
from .._io import DefaultOutput
from ..exceptions import InvalidParameter
from ..model import load_exo
from ..plan import GaitParams
from ..plant import consistency_warning
from ..record import RerunRecorder
from ..record.sizing_plot import OperatingPoints, write_torque_speed_plot
from ..record.viewer import find_viewer
from ..scenario import DEFAULT_PRESET, PRESETS, RecordingParams, Scenario
from ..scenario.load import scenario_document, scenario_from_document
from ..sim import CONTROLLERS, SimConfig, SimResult, drive_for, simulate
from ..sim.config import MAX_DURATION_S
from ..sim.scenario_file import document_from_config
from ..sim.scenario_read import apply_setting
from .common import check_outputs, format_summary, recording_line, write_json
from .simulate_options import add_run_options, flags_config

__all__ = ["flag_settings", "register", "run", "scenario_of", "sim_config"]

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
    "exo-ctrl simulate [SCENARIO.toml | --preset NAME] [--controller pd|ct|qp] "
    "[--cycles N | --duration SEC] [--set SECTION.KEY=VALUE ...] [--out PATH.rrd] "
    "[--summary PATH.json] [--no-record] [--plots DIR] [--spawn]"
)

EPILOG = (
    "Every setting of a run is a key of the scenario file: 'exo-ctrl scenario --preset "
    f"{DEFAULT_PRESET} --out my.toml' writes them all with their units, defaults and "
    "meaning (docs/scenarios.md). The older long options (--contact on, --patient-torque "
    "spastic, ...) are still accepted: docs/cli.md lists them."
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
        choices=CONTROLLERS,
        default=None,
        help="pd (the paper's PD voltage law), ct (computed torque + PD) or qp (CT + PD "
        "through a QP under drive limits and cuff-force bounds) (default: the scenario's)",
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
    add_run_options(p)
    for action in p._actions:  # argparse keeps its actions there; no public accessor
        if action.dest not in SHOWN:
            action.hidden_help = action.help  # what docs/cli.md lists
            action.help = argparse.SUPPRESS
            _FLAG_DEFAULTS[action.dest] = action.default
            _FLAG_OPTIONS[action.dest] = action.option_strings[0]
            action.default = _UNSET  # tells a flag given from one left out
    p.set_defaults(func=run)


#: A hidden option's default while parsing: whether it was given is ``value is not _UNSET``.
_UNSET = object()

#: The hidden options' own defaults, and their option strings, by destination.
_FLAG_DEFAULTS: dict[str, Any] = {}
_FLAG_OPTIONS: dict[str, str] = {}

#: The base of a run given by long options alone: SimConfig()'s defaults, as they always were.
FLAGS_PRESET = "paper-free-air"


def given_flags(args: argparse.Namespace) -> list[str]:
    """The long (hidden) options given in ``args``, by destination."""
    return [dest for dest in _FLAG_DEFAULTS if getattr(args, dest, _UNSET) is not _UNSET]


def _with_defaults(args: argparse.Namespace) -> argparse.Namespace:
    """``args`` with every long option not given at its own default."""
    filled = argparse.Namespace(**vars(args))
    for dest, default in _FLAG_DEFAULTS.items():
        if getattr(filled, dest, _UNSET) is _UNSET:
            setattr(filled, dest, default)
    return filled


@functools.cache
def _default_flags_config() -> SimConfig:
    """The SimConfig of the long options' defaults (no option given)."""
    common = {"duration": None, "cycles": None, "controller": None}
    return flags_config(argparse.Namespace(**_FLAG_DEFAULTS, **common))


def _leaves(data: Any, prefix: tuple[str, ...] = ()) -> dict[tuple[str, ...], Any]:
    """A plain document's values by key path (dicts recursed; anything else a leaf)."""
    if not isinstance(data, dict):
        return {prefix: data}
    out: dict[tuple[str, ...], Any] = {}
    for key, value in data.items():
        out.update(_leaves(value, (*prefix, key)))
    return out


def flag_settings(args: argparse.Namespace) -> list[tuple[tuple[str, ...], Any]]:
    """The settings (scenario key path, value) the long options given in ``args`` make.

    The SimConfig the options build and the one their defaults build, as
    scenario documents, compared key by key; a sub-table unset on one side
    is one value.  The duration is left to ``--duration``/``--cycles`` when
    either is given.
    """
    given = flags_config(_with_defaults(args))
    doc_given = _as_read(document_from_config(given))
    doc_base = _as_read(document_from_config(_default_flags_config()))
    new, old = _leaves(doc_given), _leaves(doc_base)
    settings = []
    for path, value in new.items():
        if path in old and old[path] == value:
            continue
        if path not in old:  # a table that was unset: set it whole
            path = next(p for p in _prefixes(path) if p in old)
            value = _get(doc_given, path)
        settings.append((path, value))
    for path in old:
        if path not in new and not any(p[: len(path)] == path for p in new):
            settings.append((path, None))  # unset where the default is set
    if args.duration is not None or args.cycles is not None:
        settings = [(p, val) for p, val in settings if p != ("run", "duration_s")]
    return list(dict(settings).items())


def _as_read(data: Any) -> Any:
    """A plain document as a TOML file reads back: its tuples lists."""
    if isinstance(data, dict):
        return {key: _as_read(value) for key, value in data.items()}
    if isinstance(data, (list, tuple)):
        return [_as_read(value) for value in data]
    return data


def _prefixes(path: tuple[str, ...]) -> list[tuple[str, ...]]:
    return [path[:i] for i in range(1, len(path))]


def _get(doc: dict[str, Any], path: tuple[str, ...]) -> Any:
    for key in path:
        doc = doc.get(key) if isinstance(doc, dict) else None
    return doc


def _set(doc: dict[str, Any], path: tuple[str, ...], value: Any) -> None:
    for key in path[:-1]:
        doc = doc.setdefault(key, {})
    if value is None:
        doc.pop(path[-1], None)
    else:
        doc[path[-1]] = value


def scenario_of(args: argparse.Namespace) -> Scenario:
    """The run ``args`` describe: the scenario, the long options given, ``--set``, the rest.

    Precedence, lowest first: the scenario file, the preset, or the long
    options (``--contact on``, ...; they describe the run on
    :data:`FLAGS_PRESET`, ``SimConfig()``'s defaults, and are refused beside
    a file or a preset), then ``--set`` in order, then ``--controller`` and
    ``--duration``/``--cycles``.  With none of them the run is
    :data:`~exo_ctrl.scenario.DEFAULT_PRESET`.
    """
    flags = given_flags(args)
    chosen = args.scenario is not None or args.preset is not None
    preset = args.preset if chosen or not flags else FLAGS_PRESET
    doc, source = scenario_document(args.scenario, preset)
    if chosen and flags:
        raise InvalidParameter(
            _FLAG_OPTIONS[flags[0]],
            getattr(args, flags[0]),
            "left out with a scenario file or preset",
            "the long options describe a run on their own; with a scenario, set its keys "
            "with --set SECTION.KEY=VALUE (exo-ctrl scenario --preset paper --out s.toml "
            "lists them)",
        )
    for path, value in flag_settings(args):
        _set(doc, path, value)
    for setting in args.set:
        apply_setting(doc, setting)
    run = doc.setdefault("run", {})
    if args.controller is not None:
        run["controller"] = args.controller
    if args.duration is not None:
        run["duration_s"] = args.duration
    elif args.cycles is not None:
        run["duration_s"] = _cycles_duration(doc, args.cycles)
    return scenario_from_document(doc, source)


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
    scenario = scenario_of(args)
    config, recording = scenario.config, scenario.recording
    # the scenario's output: a path the user did not name on the command line
    args.out = args.out if args.out is not None else DefaultOutput(recording.out)
    args.no_record = args.no_record or not recording.enabled
    args.summary = args.summary if args.summary is not None else (recording.summary or None)
    scene_rate = args.scene_rate if args.scene_rate is not None else recording.scene_rate_hz
    args.plot_file = None if args.plots is None else str(Path(args.plots) / "torque_speed.png")
    inputs = {"the exoskeleton URDF": config.exo, "the patient URDF": config.patient}
    if args.scenario is not None:
        inputs["the scenario file"] = args.scenario
    check_outputs(
        args,
        reads={k: str(p) for k, p in inputs.items() if p is not None and Path(p).is_file()},
        summary="--summary",
        plot_file="--plots",
        **({} if args.no_record else {"out": "--out"}),
    )
    points = OperatingPoints() if args.plots is not None else None  # needs matplotlib
    warning = consistency_warning(config.motor)
    if warning:
        print(f"exo-ctrl simulate: warning: the drive: {warning}", file=sys.stderr)
    observers: list = [_WarnAtStart()]
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
        title = f"{config.controller} controller, {config.duration_s:g} s of the gait"
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
    """Prints the run's warnings (a device that does not fit its patient) before its first tick."""

    def start(self, result: SimResult) -> None:
        for text in result.warnings:
            print(f"exo-ctrl simulate: warning: {text}", file=sys.stderr)

    def chunk(self, result: SimResult, start: int, rows: dict[str, Any]) -> None:
        """Nothing: the warnings are said at the start."""

    def finish(self, result: SimResult) -> None:
        """Nothing: the summary lists the warnings again."""
