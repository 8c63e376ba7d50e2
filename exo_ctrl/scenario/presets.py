"""The presets: scenario files shipped in ``exo_ctrl/scenario/presets/``.

Each preset is a short TOML file giving only what differs from the defaults,
its first line a comment that describes it (what ``exo-ctrl scenario
--list`` prints).
"""

from __future__ import annotations

from importlib import resources

from ..exceptions import InvalidParameter

__all__ = ["PRESETS", "preset_description", "preset_text"]

#: The presets' names, in the order ``exo-ctrl scenario --list`` shows them.
PRESETS: tuple[str, ...] = (
    "paper",
    "paper-free-air",
    "clinic-bws",
    "clinic-spastic",
    "spastic-qp",
    "active-transparent",
    "calibration",
)


def preset_text(name: str) -> str:
    """The TOML text of preset ``name``.

    Raises:
        InvalidParameter: ``name`` is not one of :data:`PRESETS`.

    """
    if name not in PRESETS:
        raise InvalidParameter("preset", name, "one of " + ", ".join(PRESETS))
    return resources.files(__package__).joinpath("presets", f"{name}.toml").read_text("utf-8")


def preset_description(name: str) -> str:
    """The one-line description of preset ``name`` (its first comment line)."""
    first = preset_text(name).splitlines()[0]
    return first.removeprefix("#").strip()
