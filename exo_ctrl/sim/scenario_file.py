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
import json
import math
import re
import textwrap
import types
import typing
from collections.abc import Iterable, Sequence
from typing import Any

from .config import SimConfig
from .plain import field_types, is_dataclass_type

__all__ = [
    "AUTO",
    "DEVICE_GAIT_KEYS",
    "GROUPS",
    "GROUP_NAMES",
    "GROUP_OF",
    "ORDER",
    "dataclass_of",
    "document_from_config",
    "field_docs",
    "item_class",
    "part_fields",
    "plain_text",
    "scenario_toml",
    "table_class",
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
    (
        "qp",
        "the QP controller's cuff bound",
        ("cuff_force_limit_N", "qp_estimate_bandwidth_per_s", "qp_tighten_bound"),
    ),
    ("treadmill", "the belt's set speed and the plan's synchronisation", ("speed_profile", "sync")),
    (
        "safety",
        "the safety supervisor",
        ("safety", "safety_use_estimate", "safety_widen", "stop_reaction", "estop_at_s"),
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
    "cuff_scatter",
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
    "cuff_sensors",
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

#: What a scenario writes for a key that follows the device.
AUTO = "auto"

#: The gait's keys that follow the device when a scenario leaves them out or
#: sets them ``"auto"`` (:func:`_device_gait`): hip height and step length
#: scale with the exoskeleton's leg length.
DEVICE_GAIT_KEYS = ("hip_height", "step_length")

GROUP_OF = {name: group for group, _, names in GROUPS for name in names}

#: The group sections' names.
GROUP_NAMES = frozenset(group for group, _, _ in GROUPS)


def part_fields() -> tuple[str, ...]:
    """SimConfig's fields that are sections of their own (parameter dataclasses, faults)."""
    return tuple(f.name for f in dataclasses.fields(SimConfig) if f.name not in GROUP_OF)


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
        sub = dataclass_of(hints.get(f.name)) or item_class(hints.get(f.name))
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


def dataclass_of(hint: Any) -> type | None:
    """The dataclass an annotation holds (``X`` or ``X | None``), else None."""
    if is_dataclass_type(hint):
        return hint
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        classes = [a for a in typing.get_args(hint) if is_dataclass_type(a)]
        return classes[0] if len(classes) == 1 else None
    return None


def table_class(tables: Sequence[str]) -> type | None:
    """The dataclass whose fields are the keys of table ``tables`` (``("contact", "belt")``).

    A group section (``run``, ...) holds SimConfig's own fields; None for a
    path that is no table.
    """
    if tables and tables[0] in GROUP_NAMES:
        return SimConfig if len(tables) == 1 else None
    cls: type | None = SimConfig
    for table in tables:
        cls = dataclass_of(field_types(cls).get(table)) if cls is not None else None
    return cls


def item_class(hint: Any) -> type | None:
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
        if name in GROUP_OF:
            doc[GROUP_OF[name]][name] = value
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
        item = item_class(hint)
        if item is not None:  # an array of tables (faults)
            if comments:
                out.append("")
                out += _comment(sim_docs.get(section, ""))
            if not value:
                out.append(f"# [[{section}]]   (none: add one table of {item.__name__} each)")
            for entry in value:
                _table(out, section, item, entry, comments, True)
            continue
        cls = dataclass_of(hint)
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
