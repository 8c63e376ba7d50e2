"""Which configuration keys differ between runs, and refusing runs that differ beyond the compared.

A configuration is flattened to dotted keys (``gait.step_length``,
``belief.patient_mass_kg``, ``faults.0.kind``) from
:meth:`~exo_ctrl.sim.SimConfig.to_dict`; two runs differ at every key whose
values are not equal (a key one run lacks counts as a difference).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from ..exceptions import InvalidParameter

__all__ = ["COMPARED", "check_same", "config_differences", "flatten", "is_compared"]

#: The keys a comparison compares: runs may differ there (and under them) without
#: ``allow_different``.  A controller's gains are part of it (``PD(kp=200)`` against ``"pd"``).
COMPARED = ("controller", "gains")

#: Most differing keys an error message names (then "and N more").
_NAMED = 12


def flatten(data: Any, prefix: str = "") -> dict[str, Any]:
    """A nested dict/list as dotted key → leaf value (an empty dict or list is a leaf)."""
    if isinstance(data, dict) and data:
        items: Iterable[tuple[Any, Any]] = data.items()
    elif isinstance(data, (list, tuple)) and data:
        items = enumerate(data)
    else:
        return {prefix: data}
    out: dict[str, Any] = {}
    for key, value in items:
        out.update(flatten(value, f"{prefix}.{key}" if prefix else str(key)))
    return out


def config_differences(configs: Sequence[dict[str, Any]]) -> dict[str, list[Any]]:
    """The dotted keys whose values differ between the configurations, each with its values.

    Args:
        configs: :meth:`~exo_ctrl.sim.SimConfig.to_dict` of each run.

    Returns:
        key → one value per run (None where a run lacks the key), keys sorted.

    """
    flat = [flatten(c) for c in configs]
    keys = sorted(set().union(*flat)) if flat else []
    missing = object()
    out: dict[str, list[Any]] = {}
    for key in keys:
        values = [f.get(key, missing) for f in flat]
        if any(v is missing or v != values[0] for v in values[1:]) or values[0] is missing:
            out[key] = [None if v is missing else v for v in values]
    return out


def is_compared(key: str) -> bool:
    """Whether a dotted configuration key is one of :data:`COMPARED` or lies under one."""
    return any(key == c or key.startswith(c + ".") for c in COMPARED)


def check_same(
    differences: dict[str, list[Any]], labels: Sequence[str], allow_different: bool
) -> None:
    """Refuse runs that differ beyond :data:`COMPARED`, unless ``allow_different``.

    Args:
        differences: :func:`config_differences` of the runs.
        labels: the runs' labels, in the same order (named in the message).
        allow_different: accept any difference.

    Raises:
        InvalidParameter: ``runs``, naming each differing key with its values per run.

    """
    beyond = [k for k in differences if not is_compared(k)]
    if allow_different or not beyond:
        return
    shown = []
    for key in beyond[:_NAMED]:
        values = ", ".join(f"{lab}: {v!r}" for lab, v in zip(labels, differences[key], strict=True))
        shown.append(f"{key} ({values})")
    more = f" and {len(beyond) - _NAMED} more" if len(beyond) > _NAMED else ""
    raise InvalidParameter(
        "runs",
        list(labels),
        "of one configuration but the controller and its gains "
        "(--allow-different, or allow_different=True, compares them anyway)",
        f"they differ in {len(beyond)} key{'s' if len(beyond) > 1 else ''}: "
        + "; ".join(shown)
        + more,
    )
