"""Reading a scenario file: TOML text → document → :class:`~exo_ctrl.sim.SimConfig`.

The layout (sections, groups) is :mod:`.scenario_file`'s.  A document is
checked key by key against the dataclasses: an unknown section or key, a
value of the wrong type or out of its range is refused with the file and the
key path (:class:`~exo_ctrl.exceptions.InvalidScenario`).  The gait keys that
follow the device (:data:`~.scenario_file.DEVICE_GAIT_KEYS`) are filled in
from the exoskeleton's leg length when left out or ``"auto"``.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable, Sequence
from typing import Any

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from .. import _validate as v
from ..exceptions import ExoCtrlError, InvalidParameter, InvalidScenario
from ..model import load_exo
from ..plan import GaitParams
from .config import SimConfig
from .plain import coerce, field_types, from_plain
from .scenario_file import (
    AUTO,
    DEVICE_GAIT_KEYS,
    GROUP_OF,
    GROUPS,
    ORDER,
    dataclass_of,
    item_class,
    part_fields,
    table_class,
)

#: A key path (``gait.step_length``, ``faults[0].at_s``).
_KEY_PATH = re.compile(r"[A-Za-z_]\w*(\[\d+\])?(\.[A-Za-z_]\w*(\[\d+\])?)*")

__all__ = [
    "apply_setting",
    "config_from_document",
    "device_leg_scale",
    "located_error",
    "parse_scenario",
]


def parse_scenario(text: str, source: str) -> dict[str, Any]:
    """The document of a scenario file's text.

    Raises:
        InvalidScenario: the text is not TOML (the parser's message, with its line),
            or nests arrays or inline tables deeper than the parser can recurse.

    """
    deep = v.toml_depth_problem(text)
    if deep:
        raise InvalidScenario(source, "", deep)
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
    deep = v.toml_depth_problem(text)
    if deep:
        raise InvalidScenario(source, path.strip(), f"the value is {deep}")
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
    parts = set(part_fields())
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
        field = name if name in GROUP_OF else _unit_field(name)
        if field is not None:  # a plain field's own check: its key is known
            reason = str(exc).removeprefix(str(name)).strip()
            raise InvalidScenario(source, f"{GROUP_OF[field]}.{field}", reason) from None
        raise InvalidScenario(source, "", str(exc)) from None


def _unit_field(name: object) -> str | None:
    """SimConfig's plain field a check names without its unit (``duration``: ``duration_s``)."""
    found = [f for f in GROUP_OF if isinstance(name, str) and f.startswith(f"{name}_")]
    return found[0] if len(found) == 1 else None


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
    except ExoCtrlError:
        raise  # the model's own message names its URDF
    except (TypeError, ValueError, OSError) as exc:
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
        return InvalidScenario(source, _with_unit(key), reason)
    return InvalidScenario(source, where, str(exc))


def _with_unit(key: str) -> str:
    """``key`` with its field's unit where a check named it without (``pelvis.bws``).

    A key path that is no field of its table but the start of exactly one
    (``pelvis.bws_fraction``) is that field's; any other is left as it is.
    """
    *tables, name = key.split(".")
    if not tables or "[" in key:
        return key
    cls = table_class(tables)
    fields = field_types(cls) if cls is not None else {}
    if name in fields:
        return key
    found = [f for f in fields if f.startswith(f"{name}_")]
    return ".".join((*tables, found[0])) if len(found) == 1 else key


def _part(section: str, hint: Any, table: Any) -> Any:
    """A SimConfig part (a parameter dataclass, or a tuple of them) from its table(s)."""
    item = item_class(hint)
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
    cls = dataclass_of(hint)
    if not isinstance(table, dict):
        raise InvalidScenario("", section, f"must be a table ([{section}])")
    return from_plain(cls, table, section, True)
