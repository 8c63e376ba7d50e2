"""Reading a scenario: a file or a preset, with overrides, into a :class:`Scenario`.

Precedence, lowest first: the defaults (the dataclasses'), the file or the
preset (default :data:`DEFAULT_PRESET`), then each ``section.key=value``
override in order (``exo-ctrl simulate --set``).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import _validate as v
from ..exceptions import ExoCtrlError, InvalidScenario
from ..sim import SimConfig
from ..sim.plain import from_plain
from ..sim.scenario_file import AUTO, DEVICE_GAIT_KEYS, scenario_toml
from ..sim.scenario_read import (
    apply_setting,
    config_from_document,
    located_error,
    parse_scenario,
)
from .presets import preset_description, preset_text

__all__ = [
    "DEFAULT_PRESET",
    "RecordingParams",
    "Scenario",
    "load_scenario",
    "preset",
    "scenario_document",
    "scenario_from_document",
    "scenario_template",
]

#: The preset a run without a scenario file takes: the paper's device and gait on the belt.
DEFAULT_PRESET = "paper"

#: The largest scenario file read [bytes] (a complete commented file is about 25 kB).
MAX_SCENARIO_BYTES = 1 << 20


@dataclass(frozen=True)
class RecordingParams:
    """What the run writes (the ``[recording]`` section; the command line's outputs).

    Attributes:
        enabled: write a rerun recording.
        out: the recording's path (.rrd), relative to the current directory.
        scene_rate_hz: rate of the recording's 3-D scene [Hz]; the time series
            keep every tick (the recorder's default,
            :data:`exo_ctrl.record.DEFAULT_SCENE_RATE_HZ`, is this one).
        summary: also write the summary to this JSON file ("" for none).

    """

    enabled: bool = True
    out: str = "exo_run.rrd"
    scene_rate_hz: float = 50.0
    summary: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "enabled", v.flag("recording.enabled", self.enabled))
        for name in ("out", "summary"):
            if not isinstance(getattr(self, name), str):
                raise InvalidScenario("", f"recording.{name}", "must be a path (a string)")
        if self.enabled and not self.out:
            raise InvalidScenario("", "recording.out", "must be a path when enabled is true")
        v.positive("recording.scene_rate_hz", self.scene_rate_hz, "Hz")


@dataclass(frozen=True)
class Scenario:
    """A run and its outputs, as a scenario file describes them.

    Attributes:
        config: the run.
        recording: what it writes.
        source: where it came from (a file's path, ``preset NAME``).

    """

    config: SimConfig = field(default_factory=SimConfig)
    recording: RecordingParams = field(default_factory=RecordingParams)
    source: str = ""

    def to_toml(self, comments: bool = True, header: str = "", auto: Iterable[str] = ()) -> str:
        """The complete scenario file (:func:`~exo_ctrl.sim.scenario_file.scenario_toml`).

        ``auto``: key paths written as ``"auto"`` (they follow the device).
        """
        extra = (("recording", self.recording),)
        return scenario_toml(self.config, comments, header, extra, auto)


def load_scenario(
    path: str | os.PathLike[str] | None = None,
    preset: str | None = None,
    overrides: Sequence[str] = (),
) -> Scenario:
    """Read a scenario file, or a preset, and apply ``section.key=value`` overrides.

    Args:
        path: a TOML scenario file (None: the preset).
        preset: a preset's name (None: :data:`DEFAULT_PRESET`); not with ``path``.
        overrides: ``section.key=value`` settings applied in order.

    Raises:
        InvalidScenario: the file cannot be read or is not TOML, an unknown
            section or key, a value of the wrong type or out of range (the
            message names the file and the key path).
        InvalidParameter: an unknown preset, or both a path and a preset.

    """
    doc, source = scenario_document(path, preset)
    origin = {}
    for setting in overrides:
        apply_setting(doc, setting)
        origin[setting.partition("=")[0].strip()] = "--set"
    return scenario_from_document(doc, source, origin)


def scenario_document(
    path: str | os.PathLike[str] | None = None, preset: str | None = None
) -> tuple[dict[str, Any], str]:
    """A scenario file's (or a preset's) document as written, and where it came from.

    Raises:
        InvalidScenario: as :func:`load_scenario`.
        InvalidParameter: an unknown preset.

    """
    if path is not None and preset is not None:
        raise InvalidScenario(str(path), "", "give a scenario file or a preset, not both")
    if path is not None:
        source = os.fspath(path)
        text = _read(source)
    else:
        name = DEFAULT_PRESET if preset is None else preset
        source, text = f"preset {name}", preset_text(name)
    return parse_scenario(text, source), source


def scenario_from_document(
    doc: dict[str, Any], source: str, origin: Mapping[str, str] | None = None
) -> Scenario:
    """The scenario a document describes (SimConfig's sections and ``[recording]``).

    Args:
        doc: the document (a file's, with the command line's settings applied).
        source: where the document came from (a file's path, ``preset NAME``).
        origin: the keys the command line set, key path → the option that
            set it (``gait.period`` → ``--set``): an error in one of them
            names the option instead of ``source``.

    Raises:
        InvalidScenario: an unknown section or key, a wrong type or an
            out-of-range value, naming ``source`` (or the option) and the key path.

    """
    try:
        return _scenario(doc, source)
    except InvalidScenario as exc:
        setter = _set_by(exc.key, origin or {})
        if setter is None:
            raise
        raise InvalidScenario(setter, exc.key, exc.reason) from None


def _set_by(key: str, origin: Mapping[str, str]) -> str | None:
    """The option that set the key an error names, if one did.

    ``key`` itself or a table holding it (``contact`` for ``contact.belt``);
    else a key it names without its unit (``pelvis.body_mass`` for
    ``pelvis.body_mass_kg``); else the one key set inside the table it names,
    or beside it in its table.
    """
    if not key:
        return None
    for path, setter in origin.items():
        if key == path or key.startswith((f"{path}.", f"{path}[")):
            return setter
    for path, setter in origin.items():
        if path.startswith(f"{key}_"):  # the field named without its unit
            return setter
    inside = {s for path, s in origin.items() if path.startswith(f"{key}.")}
    if len(inside) == 1:  # a table's check, one key set in it
        return inside.pop()
    table = key.rpartition(".")[0]
    near = {s for path, s in origin.items() if table and path.rpartition(".")[0] == table}
    return near.pop() if len(near) == 1 else None


def _scenario(doc: dict[str, Any], source: str) -> Scenario:
    config, extra = config_from_document(doc, source, extras=("recording",))
    table = extra.get("recording", {})
    if not isinstance(table, dict):
        raise InvalidScenario(source, "recording", "must be a table ([recording])")
    try:
        recording = from_plain(RecordingParams, table, "recording", strict=True)
    except (ExoCtrlError, TypeError, ValueError) as exc:
        raise located_error(source, "recording", exc) from None
    return Scenario(config, recording, source)


def _read(source: str) -> str:
    """A scenario file's text (refused: missing, a directory, too large, not UTF-8)."""
    p = Path(source)
    if not p.exists():
        raise InvalidScenario(source, "", "no such file")
    if not p.is_file():
        raise InvalidScenario(source, "", "not a regular file")
    size = p.stat().st_size
    if size > MAX_SCENARIO_BYTES:
        limit = v.format_bytes(MAX_SCENARIO_BYTES)
        raise InvalidScenario(
            source, "", f"{v.format_bytes(size)}, over the {limit} a file may have"
        )
    try:
        return p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InvalidScenario(
            source, "", f"not UTF-8 text ({exc.reason} at byte {exc.start})"
        ) from None
    except OSError as exc:
        raise InvalidScenario(source, "", exc.strerror or str(exc)) from None


def preset(name: str) -> Scenario:
    """The scenario of preset ``name`` (:data:`~exo_ctrl.scenario.PRESETS`)."""
    return load_scenario(preset=name)


def scenario_template(name: str) -> str:
    """The complete commented scenario file of preset ``name``, for the user to edit."""
    doc, _ = scenario_document(preset=name)
    scenario = scenario_from_document(doc, f"preset {name}")
    gait = doc.get("gait", {})
    auto = [f"gait.{k}" for k in DEVICE_GAIT_KEYS if gait.get(k, AUTO) == AUTO]
    header = (
        f"exo_ctrl scenario, from preset {name}: {preset_description(name)}\n"
        "Run it with: exo-ctrl simulate THIS_FILE.toml  (options such as --controller,\n"
        "--duration and --set section.key=value override it).  Every key is here with its\n"
        "default; a key left out takes its default; '# key =   (unset)' lines are optional.\n"
        "Units are in the key names (_s, _m, _N, _hz, ...) or the comments; SI throughout."
    )
    return scenario.to_toml(comments=True, header=header, auto=auto)
