"""A run as a TOML scenario file: :class:`~exo_ctrl.sim.SimConfig` written and read.

The file's sections mirror SimConfig's parts.  A field holding a parameter
dataclass (``gait``, ``motor``, ``cuffs``, ``contact``, ...) is a section of
its own named by the field, its keys the dataclass's fields; SimConfig's
plain fields are grouped by topic (:data:`GROUPS`: ``[run]``, ``[urdf]``,
...), each key a SimConfig field.  Names, units (in the key names) and
defaults are the dataclasses', and the comments are their docstrings'
``Attributes:`` entries, so the file cannot drift from the code.

A field left out takes its default; a field whose value is None (unset) is
written as a comment.  :func:`scenario_toml` writes a complete file (every
field present) whose reading gives back the same SimConfig, value for value
(floats are written with ``repr``, which round-trips).  Paths in ``[urdf]``
and elsewhere are taken relative to the current directory, as on the
command line.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import re
import textwrap
import types
import typing
from collections.abc import Iterable, Sequence
from typing import Any

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from ..exceptions import ExoCtrlError, InvalidParameter, InvalidScenario
from ..model import load_exo
from ..plan import GaitParams
from .config import SimConfig
from .plain import coerce, field_types, from_plain, is_dataclass_type

__all__ = [
    "GROUPS",
    "apply_setting",
    "config_from_document",
    "document_from_config",
    "field_docs",
    "located_error",
    "parse_scenario",
    "plain_text",
    "scenario_toml",
]

#: SimConfig's plain fields by section: (section, what it holds, fields).
GROUPS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    (
        "run",
        "what the run does and for how long",
        (
            "controller",
            "exercise",
            "duration_s",
            "ramp_in_s",
            "ramp_out_s",
            "cuff_fit",
            "control_rate_hz",
            "plant_substeps",
            "chunk_ticks",
        ),
    ),
    ("urdf", "the truth's models: the plant simulates these URDFs", ("exo", "patient")),
    (
        "interaction",
        "the interaction mode and the patient's own torques",
        ("mode", "patient_torque"),
    ),
    (
        "estimation",
        "the live cuff-force estimator",
        ("estimator", "observer_gain_per_s", "cuff_stiffness_ratio"),
    ),
    ("qp", "the QP controller's cuff bound", ("cuff_force_limit_N", "qp_estimate_bandwidth_per_s")),
    ("treadmill", "the belt's set speed and the plan's synchronisation", ("speed_profile", "sync")),
    (
        "safety",
        "the safety supervisor",
        ("safety", "safety_use_estimate", "stop_reaction", "estop_at_s"),
    ),
)

#: The order of the sections in a written file (groups and SimConfig's parts).
ORDER: tuple[str, ...] = (
    "run",
    "urdf",
    "gait",
    "gains",
    "motor",
    "cuffs",
    "misalignment",
    "belief",
    "estimation",
    "qp",
    "contact",
    "treadmill",
    "pelvis",
    "sensors",
    "current_sensor",
    "belt_encoder",
    "foot_load",
    "end_stops",
    "joint_compliance",
    "interaction",
    "patient_active",
    "modes",
    "path",
    "session",
    "safety",
    "safety_limits",
    "faults",
)

#: A key path (``gait.step_length``, ``faults[0].at_s``).
_KEY_PATH = re.compile(r"[A-Za-z_]\w*(\[\d+\])?(\.[A-Za-z_]\w*(\[\d+\])?)*")

#: What a scenario writes for a key that follows the device.
AUTO = "auto"

#: The gait's keys that follow the device when a scenario leaves them out or
#: sets them ``"auto"`` (:func:`_device_gait`): hip height and step length
#: scale with the exoskeleton's leg length.
DEVICE_GAIT_KEYS = ("hip_height", "step_length")

_GROUP_OF = {name: group for group, _, names in GROUPS for name in names}


def _parts() -> tuple[str, ...]:
    """SimConfig's fields that are sections of their own (parameter dataclasses, faults)."""
    return tuple(f.name for f in dataclasses.fields(SimConfig) if f.name not in _GROUP_OF)


def field_docs(cls: type) -> dict[str, str]:
    """The ``Attributes:`` entries of a class's docstring, by name, as one line each."""
    docs: dict[str, str] = {}
    lines = (cls.__doc__ or "").splitlines()
    inside, indent, name = False, 0, ""
    for line in lines:
        stripped = line.strip()
        if stripped == "Attributes:":
            inside, indent = True, len(line) - len(line.lstrip()) + 4
            continue
        if not inside:
            continue
        if stripped and len(line) - len(line.lstrip()) < indent:
            break  # the next section
        head, sep, rest = stripped.partition(":")
        if sep and len(line) - len(line.lstrip()) == indent and head.isidentifier():
            name = head
            docs[name] = rest.strip()
        elif name and stripped:
            docs[name] += " " + stripped
    return docs


def _summary_line(cls: type) -> str:
    """The first line of a class's docstring."""
    return (cls.__doc__ or cls.__name__).strip().splitlines()[0].rstrip(".")


# --- writing -----------------------------------------------------------------------


def _value(value: Any) -> str:
    """A TOML value (numbers by ``repr``: exact; strings as basic strings)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r} to TOML")


def _key_line(name: str, value: Any) -> str:
    """``name = value``, or a commented line for an unset (None) value."""
    return f"# {name} =   (unset)" if value is None else f"{name} = {_value(value)}"


_ROLE = re.compile(r":\w+:`~?([^`]+)`")


def plain_text(text: str) -> str:
    """A docstring's text without its markup (``:mod:`a.b``` → ``a.b``, double backquotes)."""
    return _ROLE.sub(r"\1", text).replace("``", "")


def _comment(text: str, prefix: str = "# ") -> list[str]:
    """``text`` (markup removed) as wrapped comment lines."""
    text = plain_text(text)
    return textwrap.wrap(text, 96, initial_indent=prefix, subsequent_indent=prefix) or []


def _table(
    out: list[str],
    header: str,
    cls: type,
    values: dict[str, Any],
    comments: bool,
    array: bool,
    auto: frozenset[str] = frozenset(),
) -> None:
    """Write one table (its plain keys, then its sub-tables) of dataclass ``cls``."""
    docs = field_docs(cls) if comments else {}
    hints = field_types(cls)
    out.append("")
    if comments:
        out += _comment(f"{_summary_line(cls)}.")
    out.append(f"[[{header}]]" if array else f"[{header}]")
    later = []
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        value = values.get(f.name)
        sub = _dataclass_of(hints.get(f.name)) or _item_class(hints.get(f.name))
        if sub is not None:
            later.append((f.name, sub, value))
            continue
        if comments and docs.get(f.name):
            out += _comment(docs[f.name])
        if f"{header}.{f.name}" in auto:
            if comments:
                about = "follows the device's leg length (thigh + shank)"
                out += _comment(f"{AUTO!r}: {about}: {value!r} m for this one")
            value = AUTO
        out.append(_key_line(f.name, value))
    for name, sub, value in later:
        if isinstance(value, (list, tuple)):  # an array of tables ([[session.segments]])
            for entry in value:
                _table(out, f"{header}.{name}", sub, entry, comments, True)
            continue
        if value is None:
            if comments:
                out.append("")
                out += _comment(docs.get(name, ""))
                out.append(f"# [{header}.{name}]   (unset: a table of {sub.__name__})")
            continue
        _table(out, f"{header}.{name}", sub, value, comments, False)


def _dataclass_of(hint: Any) -> type | None:
    """The dataclass an annotation holds (``X`` or ``X | None``), else None."""
    if is_dataclass_type(hint):
        return hint
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        classes = [a for a in typing.get_args(hint) if is_dataclass_type(a)]
        return classes[0] if len(classes) == 1 else None
    return None


def _item_class(hint: Any) -> type | None:
    """The dataclass of a ``tuple[X, ...]`` annotation's items, else None."""
    args = typing.get_args(hint)
    if typing.get_origin(hint) is tuple and args and is_dataclass_type(args[0]):
        return args[0]
    return None


def document_from_config(config: SimConfig) -> dict[str, Any]:
    """The scenario document (sections of plain values) of a configuration."""
    plain = config.to_dict()
    session_speeds = config.session is not None and (
        config.session.speed_profile(config.gait.belt_speed) is not None
    )
    if session_speeds:  # derived from the session's belt speeds, which SimConfig sets it from
        plain["speed_profile"] = None
    elif config.speed_profile is not None:
        profile = config.speed_profile
        pairs = zip(profile.times, profile.speeds, strict=True)
        plain["speed_profile"] = ",".join(f"{t!r}:{s!r}" for t, s in pairs)
    doc: dict[str, Any] = {group: {} for group, _, _ in GROUPS}
    for name, value in plain.items():
        if name in _GROUP_OF:
            doc[_GROUP_OF[name]][name] = value
        else:
            doc[name] = value
    return doc


def scenario_toml(
    config: SimConfig,
    comments: bool = True,
    header: str = "",
    extra: Sequence[tuple[str, Any]] = (),
    auto: Iterable[str] = (),
) -> str:
    """The complete scenario file of ``config``: every field, defaults filled.

    Args:
        config: the run.
        comments: document every section and key from the dataclasses'
            docstrings (a template to edit); False: the values only.
        header: comment lines put at the top (a preset's description).
        extra: further sections after SimConfig's, (name, dataclass instance)
            each (the scenario's ``[recording]``).
        auto: key paths (``gait.hip_height``) written as ``"auto"``: they
            follow the device (:data:`DEVICE_GAIT_KEYS`).

    """
    doc = document_from_config(config)
    hints = field_types(SimConfig)
    group_doc = {group: about for group, about, _ in GROUPS}
    sim_docs = field_docs(SimConfig) if comments else {}
    out = [f"# {line}" if line else "#" for line in header.splitlines()]
    for section in ORDER:
        if section in group_doc:
            out.append("")
            if comments:
                out += _comment(f"{group_doc[section]}.")
            out.append(f"[{section}]")
            for name, value in doc[section].items():
                if comments and sim_docs.get(name):
                    out += _comment(sim_docs[name])
                out.append(
                    f"# {name} =   (unset)" if value is None else f"{name} = {_value(value)}"
                )
            continue
        hint, value = hints[section], doc[section]
        item = _item_class(hint)
        if item is not None:  # an array of tables (faults)
            if comments:
                out.append("")
                out += _comment(sim_docs.get(section, ""))
            if not value:
                out.append(f"# [[{section}]]   (none: add one table of {item.__name__} each)")
            for entry in value:
                _table(out, section, item, entry, comments, True)
            continue
        cls = _dataclass_of(hint)
        if value is None:
            if comments:
                out.append("")
                out += _comment(sim_docs.get(section, ""))
                out.append(f"# [{section}]   (unset: a table of {cls.__name__})")
            continue
        _table(out, section, cls, value, comments, False, frozenset(auto))
    for name, part in extra:
        _table(out, name, type(part), dataclasses.asdict(part), comments, False)
    return "\n".join(out).lstrip("\n") + "\n"


# --- reading -----------------------------------------------------------------------


def parse_scenario(text: str, source: str) -> dict[str, Any]:
    """The document of a scenario file's text.

    Raises:
        InvalidScenario: the text is not TOML (the parser's message, with its line).

    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InvalidScenario(source, "", f"not a valid TOML file ({exc})") from None


def apply_setting(doc: dict[str, Any], setting: str, source: str = "--set") -> None:
    """Apply one ``section.key=value`` (a TOML value, or a bare string) to ``doc`` in place.

    ``value`` ``default`` removes the key (its default applies).

    Raises:
        InvalidScenario: not of the form ``section.key=value``.

    """
    path, sep, text = setting.partition("=")
    keys = path.strip().split(".")
    if not sep or len(keys) < 2 or not all(k.strip() for k in keys):
        raise InvalidScenario(source, setting, "expected section.key=value, e.g. gait.period=1.1")
    text = text.strip()
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text  # a bare string: --set run.controller=ct
    table = doc
    for key in keys[:-1]:
        table = table.setdefault(key.strip(), {})
        if not isinstance(table, dict):
            raise InvalidScenario(source, path, "names a value, not a section")
    if text == "default":
        table.pop(keys[-1].strip(), None)
    else:
        table[keys[-1].strip()] = value


def config_from_document(
    doc: dict[str, Any], source: str, extras: Sequence[str] = ()
) -> tuple[SimConfig, dict[str, Any]]:
    """The SimConfig a scenario document describes, and its ``extras`` sections as they are.

    Args:
        doc: the parsed file (:func:`parse_scenario`), overrides applied.
        source: the file's name, for messages.
        extras: sections that are not SimConfig's (``recording``), returned
            to the caller unchecked.

    Raises:
        InvalidScenario: an unknown section or key, a value of the wrong type
            or out of its range, naming the file and the key path.

    """
    doc = _device_gait(doc, source)
    parts = set(_parts())
    hints = field_types(SimConfig)
    groups = {group: names for group, _, names in GROUPS}
    kwargs: dict[str, Any] = {}
    extra: dict[str, Any] = {}
    for section, table in doc.items():
        if section in extras:
            extra[section] = table
            continue
        if section not in groups and section not in parts:
            allowed = ", ".join(ORDER + tuple(extras))
            raise InvalidScenario(source, section, f"is not a section; the sections: {allowed}")
        if table is None:  # unset (a written document's None): the field's None
            kwargs[section] = None
            continue
        if section in groups:
            _group(kwargs, section, table, groups[section], source, hints)
            continue
        try:
            kwargs[section] = _part(section, hints[section], table)
        except (ExoCtrlError, TypeError, ValueError) as exc:
            raise located_error(source, section, exc) from None
    try:
        return SimConfig(**kwargs), extra
    except (ExoCtrlError, TypeError, ValueError) as exc:
        name = getattr(exc, "name", None)
        if name in _GROUP_OF:  # a plain field's own check: its section is known
            raise located_error(source, _GROUP_OF[name], exc) from None
        raise InvalidScenario(source, "", str(exc)) from None


def _device_gait(doc: dict[str, Any], source: str) -> dict[str, Any]:
    """``doc`` with the gait keys of :data:`DEVICE_GAIT_KEYS` it leaves out or sets ``"auto"``.

    They follow the device (``urdf.exo``): the default's value times the
    device's leg length (thigh + shank) over the default exoskeleton's, so the
    paper's device gets exactly the defaults.
    """
    gait = doc.get("gait", {})
    if not isinstance(gait, dict):
        return doc
    missing = [k for k in DEVICE_GAIT_KEYS if gait.get(k, AUTO) == AUTO]
    if not missing:
        return doc
    urdf = doc.get("urdf", {})
    exo = urdf.get("exo") if isinstance(urdf, dict) else None
    try:
        scale = device_leg_scale(exo)
    except (ExoCtrlError, TypeError, ValueError, OSError) as exc:
        raise InvalidScenario(source, "urdf.exo", str(exc)) from None
    defaults = GaitParams()
    gait = {**gait, **{k: getattr(defaults, k) * scale for k in missing}}
    return {**doc, "gait": gait}


def device_leg_scale(exo: str | None) -> float:
    """An exoskeleton's leg length (thigh + shank) over the default exoskeleton's [-]."""
    if exo is None:
        return 1.0
    return _leg_length(str(exo)) / _leg_length(None)


@functools.lru_cache(maxsize=8)
def _leg_length(exo: str | None) -> float:
    """The left leg's thigh + shank of an exoskeleton URDF [m] (None: the default)."""
    leg = load_exo(exo).legs["left"]
    return leg.thigh_length + leg.shank_length


def _group(
    kwargs: dict[str, Any],
    section: str,
    table: Any,
    names: Iterable[str],
    source: str,
    hints: dict[str, Any],
) -> None:
    """SimConfig's plain fields of one group section into ``kwargs``."""
    if not isinstance(table, dict):
        raise InvalidScenario(source, section, "must be a table ([section])")
    for key, value in table.items():
        if key not in names:
            allowed = ", ".join(names)
            raise InvalidScenario(
                source, f"{section}.{key}", f"is not a key here; allowed: {allowed}"
            )
        try:
            if key == "speed_profile" and isinstance(value, str):  # its text form
                kwargs[key] = value
            else:
                kwargs[key] = coerce(hints[key], value, f"{section}.{key}", strict=True)
        except (ExoCtrlError, TypeError, ValueError) as exc:
            raise located_error(source, f"{section}.{key}", exc) from None


def located_error(source: str, where: str, exc: Exception) -> InvalidScenario:
    """``exc`` raised while reading section or key ``where``, as an error naming its key path.

    A parameter error names its field: ``gait`` and ``step_length`` give the
    key path ``gait.step_length``; a strict type error names its whole path;
    a name that is not a key (``fault kind``) stays in the message.
    """
    if isinstance(exc, InvalidScenario):
        return InvalidScenario(source, exc.key or where, exc.reason)
    name = str(getattr(exc, "name", ""))
    if isinstance(exc, InvalidParameter) and _KEY_PATH.fullmatch(name):
        key = name if "." in name or name.startswith(where) else f"{where}.{name}"
        reason = str(exc).removeprefix(name).strip()
        return InvalidScenario(source, key, reason)
    return InvalidScenario(source, where, str(exc))


def _part(section: str, hint: Any, table: Any) -> Any:
    """A SimConfig part (a parameter dataclass, or a tuple of them) from its table(s)."""
    item = _item_class(hint)
    if item is not None:
        if not isinstance(table, (list, tuple)):
            raise InvalidScenario("", section, f"must be an array of tables ([[{section}]])")
        items = []
        for i, entry in enumerate(table):
            try:
                items.append(from_plain(item, entry, f"{section}[{i}]", True))
            except (ExoCtrlError, TypeError, ValueError) as exc:
                raise located_error("", f"{section}[{i}]", exc) from None
        return tuple(items)
    cls = _dataclass_of(hint)
    if not isinstance(table, dict):
        raise InvalidScenario("", section, f"must be a table ([{section}])")
    return from_plain(cls, table, section, True)
