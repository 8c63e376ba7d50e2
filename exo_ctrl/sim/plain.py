"""Dataclasses from their plain-data form (``asdict``, JSON, TOML) and back.

:func:`from_plain` rebuilds a (nested) parameter dataclass, such as
:class:`~exo_ctrl.sim.SimConfig`, from the dicts, lists and scalars that
``dataclasses.asdict`` writes: each field is converted by its annotation, so
nested dataclasses, ``X | None`` ones and tuples of them come back as they
were written.  The dataclasses' own checks then judge the values.

With ``strict=True`` (scenario files) a key that names no field, or a value
whose type the field cannot take (a string for a number, a number for a
switch), is refused with its key path (``gait.step_length``); without it
(recordings of other versions) unknown keys are ignored.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import types
import typing
from typing import Any

from ..exceptions import InvalidParameter

__all__ = ["coerce", "field_types", "from_plain", "is_dataclass_type", "named_copy"]


@functools.cache
def field_types(cls: type) -> dict[str, Any]:
    """The resolved annotations of a dataclass's fields (``{}`` if they cannot be resolved)."""
    try:
        return typing.get_type_hints(cls)
    except (NameError, TypeError):  # an annotation naming what the module cannot see
        return {}


def named_copy(obj: Any, **names: Any) -> Any:
    """A shallow copy of a frozen dataclass with fields set to names, its checks not run.

    For the plain form of a configuration holding a user's objects (a
    controller, an estimator): each by its ``module:Class`` name (and
    whatever else stands in for an object: a PD's gains).
    """
    plain = copy.copy(obj)
    for name, value in names.items():
        object.__setattr__(plain, name, value)
    return plain


def _default_type(f: dataclasses.Field) -> type | None:
    """The dataclass a field holds, judged from its default (factory or value)."""
    factory = f.default_factory
    if isinstance(factory, type) and dataclasses.is_dataclass(factory):
        return factory
    if dataclasses.is_dataclass(f.default) and not isinstance(f.default, type):
        return type(f.default)
    return None


def is_dataclass_type(hint: Any) -> bool:
    """Whether ``hint`` is a dataclass (the class, not an instance)."""
    return isinstance(hint, type) and dataclasses.is_dataclass(hint)


def _describe(hint: Any) -> str:
    """A field's type in words, for messages (``"a number"``, ``"a list of numbers"``)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        words = [_describe(a) for a in args if a is not type(None)]
        return " or ".join(words) + (" (or left out)" if type(None) in args else "")
    if origin is tuple:
        inner = args[0] if args else Any
        return f"a list of {_describe(inner).removeprefix('a ')}s"
    if is_dataclass_type(hint):
        return f"a table of {hint.__name__}"
    return {bool: "true or false", int: "an integer", float: "a number", str: "a string"}.get(
        hint, "a value"
    )


def _type_ok(hint: Any, value: Any) -> bool:
    """Whether a plain ``value`` has a type the annotation ``hint`` can take (strict mode)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return (value is None and type(None) in args) or any(_type_ok(a, value) for a in args)
    if hint is Any or hint is object:
        return True
    if origin is tuple:
        return isinstance(value, (list, tuple))
    if is_dataclass_type(hint):
        return isinstance(value, dict)
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if hint is str:
        return isinstance(value, str)
    return True


def coerce(hint: Any, value: Any, path: str = "", strict: bool = False, typed: bool = False) -> Any:
    """``value`` from its plain form back to the type the annotation ``hint`` names.

    With ``strict`` or ``typed``, a value of a type ``hint`` cannot take is
    refused by its key path ``path`` (:class:`~exo_ctrl.exceptions.InvalidParameter`);
    ``strict`` also refuses unknown keys in nested tables (:func:`from_plain`).
    """
    if (strict or typed) and value is not None and not _type_ok(hint, value):
        raise InvalidParameter(path, value, _describe(hint))
    if is_dataclass_type(hint):
        return from_plain(hint, value, path, strict, typed) if isinstance(value, dict) else value
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None:
            return None
        if isinstance(value, dict):
            classes = [a for a in args if is_dataclass_type(a)]
            if len(classes) == 1:
                return from_plain(classes[0], value, path, strict, typed)
            return value
        if isinstance(value, list):
            tuples = [a for a in args if a is tuple or typing.get_origin(a) is tuple]
            if len(tuples) == 1:
                return coerce(tuples[0], value, path, strict, typed)
            return tuple(value)
        if float in args and isinstance(value, int) and not isinstance(value, bool):
            return float(value)
        return value
    if isinstance(value, list):
        if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
            return tuple(
                coerce(args[0], item, f"{path}[{i}]", strict, typed) for i, item in enumerate(value)
            )
        if origin is tuple and args and len(args) == len(value):
            return tuple(
                coerce(a, item, f"{path}[{i}]", strict, typed)
                for i, (a, item) in enumerate(zip(args, value, strict=True))
            )
        return tuple(value)
    if hint is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def from_plain(
    cls: type, data: dict[str, Any], path: str = "", strict: bool = False, typed: bool = False
) -> Any:
    """Build a (nested) dataclass from its plain form.

    Args:
        cls: the dataclass.
        data: its fields by name (nested dataclasses as dicts, tuples as lists).
        path: the key path of ``data`` in the whole document, for messages.
        strict: refuse unknown keys and values of the wrong type by key path
            (:class:`~exo_ctrl.exceptions.InvalidParameter`); else ignore
            unknown keys and leave the types to the dataclass's checks.
        typed: refuse values of the wrong type by key path, but ignore
            unknown keys (a recording's config, written by another version).

    A field whose annotation cannot be resolved falls back to the dataclass of
    its default.

    """
    hints = field_types(cls)
    names = {f.name: f for f in dataclasses.fields(cls) if f.init}
    if strict:
        for key in data:
            if key not in names:
                where = f"{path}.{key}" if path else key
                allowed = ", ".join(names)
                raise InvalidParameter(where, data[key], f"a key of {cls.__name__} ({allowed})")
    kwargs = {}
    for name, f in names.items():
        if name not in data:
            continue
        where = f"{path}.{name}" if path else name
        hint = hints.get(name, _default_type(f))
        kwargs[name] = coerce(hint, data[name], where, strict, typed)
    return cls(**kwargs)
