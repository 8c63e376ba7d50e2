"""A user's class given by its import path ``module:Class``: its name, its form, its import.

Shared by the user's controllers (:mod:`exo_ctrl.control.plugin`) and
estimators (:mod:`exo_ctrl.estimation.plugin`): a run names a user's object
by its class's ``module:QualifiedName`` (:func:`plugin_name`), checks a path's
form when the configuration is made (:func:`is_path`) and imports it when
the run is built (:func:`load_plugin`).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import re
import sys
from typing import Any

from .exceptions import InvalidParameter

__all__ = ["import_from_cwd", "is_path", "load_plugin", "plugin_name"]

#: The form of an import path: a dotted module, a colon, the attribute path (no spaces).
_PATH = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:\S+")


def plugin_name(value: object) -> str:
    """A string as given; an object: its class's ``module:QualifiedName``."""
    if isinstance(value, str):
        return value
    cls = type(value)
    return f"{cls.__module__}:{cls.__qualname__}"


def is_path(value: str) -> bool:
    """Whether ``value`` has the form of an import path ``module:Class``."""
    return _PATH.fullmatch(value) is not None


def load_plugin(path: str, base: type, name: str, allowed: str) -> Any:
    """Import the class at ``path`` and build it with no arguments.

    Args:
        path: ``module:Class``.
        base: the abstract base class it must subclass.
        name: the parameter's name in messages (``"controller"``).
        allowed: what the parameter may be, in words (messages).

    Raises:
        InvalidParameter: the module cannot be imported, has no such class,
            the class is not a ``base`` subclass or leaves an abstract
            method unimplemented, or cannot be built with no arguments.

    """
    module, _, qualname = path.partition(":")
    base_name = f"{base.__module__.rsplit('.', 1)[0]}.{base.__name__}"
    try:
        found: Any = importlib.import_module(module)
    except ImportError as exc:
        raise InvalidParameter(name, path, allowed, f"cannot import {module}: {exc}") from None
    except Exception as exc:  # the user's module failed while it was imported
        reason = f"importing {module} raised {type(exc).__name__}: {exc}"
        raise InvalidParameter(name, path, allowed, reason) from None
    for part in qualname.split("."):
        found = getattr(found, part, None)
        if found is None:
            detail = f"module {module} has no attribute {qualname}"
            raise InvalidParameter(name, path, allowed, detail)
    if not (isinstance(found, type) and issubclass(found, base)):
        raise InvalidParameter(name, path, allowed, f"{path} is not a subclass of {base_name}")
    missing = sorted(getattr(found, "__abstractmethods__", ()))
    if missing:
        detail = f"{path} does not implement {', '.join(m + '()' for m in missing)}"
        raise InvalidParameter(name, path, allowed, detail)
    try:
        return found()
    except TypeError as exc:
        detail = f"{path} cannot be built with no arguments: {exc}"
        raise InvalidParameter(name, path, allowed, detail) from None


def import_from_cwd() -> None:
    """Let a user's path (``--controller mypkg.ctl:Impedance``) import from here.

    For the command line: the current directory goes first on ``sys.path``,
    as ``python -m`` puts it (the ``exo-ctrl`` script's own path is its bin
    directory); a sweep's spawned workers inherit it.
    """
    with contextlib.suppress(OSError):  # a current directory that no longer exists
        cwd = os.getcwd()
        if cwd not in sys.path and "" not in sys.path:
            sys.path.insert(0, cwd)
