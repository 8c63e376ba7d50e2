"""The sweepable parameters: names, units, accepted ranges, and the ``--param`` syntax.

``--param NAME=V1,V2,...`` lists values, ``NAME=LO:HI:N`` gives N evenly
spaced values from LO to HI inclusive (rounded to 12 significant digits, so
``0.3:0.5:3`` gives 0.4, not 0.39999999999999997); ``controller`` takes
controller names.  Duplicates are dropped, the order given is kept.

**Patient.**  The patient parameters change
:meth:`~exo_ctrl.model.BodyParams.patient_default`; a changed link length
keeps each cuff at its fraction of the link (0.39/0.52 thigh, 0.45/0.52
shank).  The ranges accepted are the paper's Table I ranges as read in the
design notes: link lengths 0.39-0.65 m, thigh mass 7-14 kg, shank and foot
mass 3-6 kg.

**Exoskeleton.**  The ``exo_*`` parameters change
:meth:`~exo_ctrl.model.BodyParams.exo_default` (link lengths, link masses,
cuff positions); a generated URDF per run is kept in the sweep's folder
(``NAME.urdf_cache/``, beside the table).  A changed link length keeps a cuff at its
default position at the cuff's fraction of the link.

**Units.**  Every value is in SI units, as everywhere in the package: the
cuff stiffness in N/m (the paper's 8 N/mm is 8000 N/m), the PD gains in
V/rad and V·s/rad.  :func:`parameter_listing` gives each name with its
unit, accepted range and default (``exo-ctrl sweep --help``).

**Gains.**  ``kp`` and ``kd`` set the same gain on all four joints
(:class:`~exo_ctrl.control.PDGains`; a base with per-joint gains keeps them
while the gain is not swept).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..control.plugin import check_controller as check_plugin
from ..control.plugin import controller_name
from ..exceptions import InvalidParameter
from ..model import BodyParams
from ..plan.gait import MIN_PERIOD_S
from ..plan.landing import MAX_LANDING_DEPTH_M, MAX_LANDING_SPEED_MPS
from ..sim import CONTROLLERS, SimConfig

__all__ = [
    "MAX_RUNS",
    "PARAMETERS",
    "ParamInfo",
    "check_controller",
    "check_value",
    "default_exo",
    "default_patient",
    "parameter_listing",
    "parameter_names",
    "parse_param",
    "point_label",
    "round_12",
    "unique",
    "unit_suffix",
    "value_in",
]

#: The most runs a sweep makes (a range's N, random samples, the grid's size):
#: 100,000 runs of a second each keep two cores busy for 14 hours.
MAX_RUNS = 100_000


@dataclass(frozen=True)
class ParamInfo:
    """A sweepable numeric parameter.

    Attributes:
        name: name as given to ``--param``.
        group: ``"gait"``, ``"patient"``, ``"device"`` (exoskeleton, drive,
            cuffs) or ``"control"``.
        attribute: the field it sets (of GaitParams, BodyParams, CuffParams,
            MotorParams or PDGains).
        unit: SI unit ("" for none).
        lo: lower bound of the accepted values.
        hi: upper bound.
        lo_open: lo itself is excluded.
        hi_open: hi itself is excluded.
        target: what the field belongs to: the :class:`~exo_ctrl.sim.SimConfig`
            field (``"gait"``, ``"motor"``, ``"cuffs"``, ``"gains"``) or
            ``"patient"`` or ``"exo"`` (the generated body's BodyParams).
        text: what it is, in words, for :func:`parameter_listing`.

    """

    name: str
    group: str
    attribute: str
    unit: str
    lo: float
    hi: float
    lo_open: bool = False
    hi_open: bool = False
    target: str = ""
    text: str = ""

    def interval(self) -> str:
        """The accepted values in words, e.g. ``in (0, 2] m``."""
        left = "(" if self.lo_open else "["
        right = ")" if self.hi_open else "]"
        unit = f" {self.unit}" if self.unit else ""
        return f"in {left}{self.lo:g}, {self.hi:g}{right}{unit}"

    def accepts(self, x: float) -> bool:
        """Whether ``x`` lies in the accepted interval."""
        above = x > self.lo if self.lo_open else x >= self.lo
        below = x < self.hi if self.hi_open else x <= self.hi
        return above and below


def _p(
    name: str, target: str, fld: str, unit: str, lo: float, hi: float, text: str, **kw: bool
) -> ParamInfo:
    group = {"motor": "device", "cuffs": "device", "exo": "device", "gains": "control"}.get(
        target, target
    )
    return ParamInfo(name, group, fld, unit, lo, hi, target=target, text=text, **kw)


#: Numeric sweep parameters.  Gait bounds are wide sanity bounds (the reach
#: and the other limits are checked per run, and a run that violates them is
#: recorded as ``failed``); patient bounds are the paper's Table I ranges;
#: device bounds span plausible hardware (paper: 8 N/mm = 8000 N/m cuffs);
#: gain bounds span about 0-4x the defaults (PDGains(): 300 V/rad, 5 V·s/rad).
PARAMETERS: dict[str, ParamInfo] = {
    p.name: p
    for p in (
        _p("step_length", "gait", "step_length", "m", 0.0, 2.0, "step length s", lo_open=True),
        _p("lift_height", "gait", "lift_height", "m", 0.0, 0.5, "top of swing", lo_open=True),
        _p("hip_height", "gait", "hip_height", "m", 0.0, 2.0, "hip above belt", lo_open=True),
        _p("pelvis_excursion", "gait", "pelvis_excursion", "m", 0.0, 0.5, "hip's rise and fall"),
        _p("shape_coeff", "gait", "shape_coeff", "", 0.0, 10.0, "k_v = v_f / v_b", lo_open=True),
        _p("period", "gait", "period", "s", MIN_PERIOD_S, 10.0, "gait cycle T_s"),
        _p("duty_factor", "gait", "duty_factor", "", 0.5, 1.0, "stance fraction β", hi_open=True),
        _p(
            "landing_speed",
            "gait",
            "landing_speed_mps",
            "m/s",
            0.0,
            MAX_LANDING_SPEED_MPS,
            "landing approach v_a (0: the paper's landing)",
        ),
        _p(
            "landing_depth",
            "gait",
            "landing_depth_m",
            "m",
            0.0,
            MAX_LANDING_DEPTH_M,
            "landing approach's depth a",
            lo_open=True,
        ),
        _p("patient_thigh_mass", "patient", "thigh_mass", "kg", 7.0, 14.0, "Table I range"),
        _p("patient_shank_mass", "patient", "shank_mass", "kg", 3.0, 6.0, "with the foot"),
        _p("patient_thigh_length", "patient", "thigh_length", "m", 0.39, 0.65, "hip to knee"),
        _p("patient_shank_length", "patient", "shank_length", "m", 0.39, 0.65, "knee to foot"),
        _p("exo_thigh_length", "exo", "thigh_length", "m", 0.3, 0.7, "device hip to knee"),
        _p("exo_shank_length", "exo", "shank_length", "m", 0.3, 0.7, "device knee to foot"),
        _p("exo_thigh_mass", "exo", "thigh_mass", "kg", 0.5, 15.0, "device thigh link"),
        _p("exo_shank_mass", "exo", "shank_mass", "kg", 0.5, 15.0, "device shank link"),
        _p("exo_thigh_cuff", "exo", "thigh_cuff", "m", 0.05, 0.7, "hip to thigh cuff"),
        _p("exo_shank_cuff", "exo", "shank_cuff", "m", 0.05, 0.7, "knee to shank cuff"),
        _p(
            "cuff_stiffness",
            "cuffs",
            "stiffness_N_per_m",
            "N/m",
            1e3,
            1e5,
            "8000 N/m = the paper's 8 N/mm",
        ),
        _p("cuff_damping", "cuffs", "damping_N_s_per_m", "N·s/m", 0.0, 1e3, "all four cuffs"),
        _p("gear_ratio", "motor", "gear_ratio", "", 1.0, 500.0, "motor / joint speed"),
        _p("kp", "gains", "kp", "V/rad", 0.0, 1e3, "PD gain, all joints", lo_open=True),
        _p("kd", "gains", "kd", "V·s/rad", 0.0, 20.0, "PD gain, all joints"),
    )
}


def parameter_names() -> tuple[str, ...]:
    """Every sweepable parameter name: the numeric ones, then ``controller``."""
    return (*PARAMETERS, "controller")


def parameter_listing(base: SimConfig | None = None) -> str:
    """Every sweepable parameter with its unit, accepted values and default, one a line.

    Args:
        base: the run the defaults are read from (default: ``SimConfig()``).

    Returns:
        Lines ``NAME  [UNIT]  ACCEPTED  default VALUE  (WHAT)`` under a
        heading, for ``exo-ctrl sweep --help`` (a pre-formatted epilog).

    """
    base = base if base is not None else SimConfig()
    rows = []
    for info in PARAMETERS.values():
        accepted = info.interval().removeprefix("in ").removesuffix(f" {info.unit}")
        default = value_in(info, base)
        items = set(np.ravel(default).tolist()) if default is not None else set()
        shown = f"{items.pop():g}" if len(items) == 1 else "per joint" if items else "URDF"
        rows.append((info.name, f"[{info.unit or '-'}]", accepted, shown, info.text))
    accepted = ", ".join((*CONTROLLERS, "MODULE:CLASS"))  # a user's: docs/controllers.md
    rows.append(("controller", "", accepted, controller_name(base.controller), "names"))
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines = ["sweep parameters (name, unit, accepted values, default):"]
    for row in rows:
        cells = [cell.ljust(width) for cell, width in zip(row[:4], widths, strict=True)]
        lines.append(f"  {'  '.join(cells)}  {row[4]}".rstrip())
    return "\n".join(lines)


def value_in(info: ParamInfo, base: SimConfig) -> Any:
    """The value ``base`` gives the parameter ``info``.

    Returns:
        The field's value (a PD gain as its per-joint tuple), or None for a
        patient parameter when ``base`` names a patient URDF.

    """
    if info.target == "patient":
        return getattr(default_patient(), info.attribute) if base.patient is None else None
    if info.target == "exo":
        return getattr(default_exo(), info.attribute) if base.exo is None else None
    return getattr(getattr(base, info.target), info.attribute)


@functools.cache
def default_patient() -> BodyParams:
    """The patient the patient parameters change: :meth:`BodyParams.patient_default`."""
    return BodyParams.patient_default()


@functools.cache
def default_exo() -> BodyParams:
    """The exoskeleton the exo parameters change: :meth:`BodyParams.exo_default`."""
    return BodyParams.exo_default()


def unit_suffix(unit: str) -> str:
    """`` [unit]`` for a message, or "" without a unit."""
    return f" [{unit}]" if unit else ""


def _number(info: ParamInfo, text: str) -> float:
    """Parse and check one value of a numeric parameter."""
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise InvalidParameter(info.name, text, f"a finite number{unit_suffix(info.unit)}")
    return check_value(info, x)


def check_value(info: ParamInfo, value: Any) -> float:
    """Check a numeric value (already parsed) against ``info``; returns it as float.

    Raises:
        InvalidParameter: not a finite real number (bool excluded), or outside
            the accepted interval.

    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidParameter(info.name, value, f"a finite number{unit_suffix(info.unit)}")
    x = float(value)
    if not math.isfinite(x):
        raise InvalidParameter(info.name, value, f"a finite number{unit_suffix(info.unit)}")
    if not info.accepts(x):
        raise InvalidParameter(info.name, x, info.interval())
    return x


def check_controller(value: Any) -> str:
    """Check a controller name: a built-in one, or a user's ``module:Class`` path.

    (:func:`~exo_ctrl.control.plugin.check_controller`; a user's object has
    no place in a sweep's plain data: its name is swept, as in its base.)
    """
    if not isinstance(value, str):
        raise InvalidParameter("controller", value, f"one of {', '.join(CONTROLLERS)}")
    check_plugin(value, CONTROLLERS)
    return value


def round_12(x: float) -> float:
    """``x`` to 12 significant digits (so 0.3:0.5:3 gives 0.4, not 0.39999999999999997)."""
    return float(f"{x:.12g}")


def unique(values: Sequence[Any]) -> tuple[Any, ...]:
    """``values`` without duplicates, first occurrences in order."""
    return tuple(dict.fromkeys(values))


def point_label(point: dict[str, Any]) -> str:
    """A point in words, e.g. ``step_length=0.4 m, controller=ct``."""
    parts = []
    for name, value in point.items():
        if name == "controller":
            parts.append(f"{name}={value}")
        else:
            unit = PARAMETERS[name].unit
            parts.append(f"{name}={value:.10g}" + (f" {unit}" if unit else ""))
    return ", ".join(parts)


def parse_param(text: str) -> tuple[str, tuple[float | str, ...]]:
    """Parse one ``--param`` argument.

    Args:
        text: ``NAME=V1,V2,...`` (a list) or ``NAME=LO:HI:N`` (N evenly spaced
            values, LO and HI included, LO < HI, N >= 2); ``controller``
            takes names (``controller=pd,ct``).

    Returns:
        The name and its values (floats, or controller names), duplicates
        dropped, in the order given.

    Raises:
        InvalidParameter: malformed text, an unknown name (the message lists
            the allowed ones), a value that is not a finite number or lies
            outside the parameter's range.

    """
    name, sep, rhs = (part.strip() for part in text.partition("="))
    if not sep or not name or not rhs:
        raise InvalidParameter("--param", text, "NAME=V1,V2,... or NAME=LO:HI:N")
    if name not in parameter_names():
        raise InvalidParameter("sweep parameter", name, f"one of {', '.join(parameter_names())}")
    if name == "controller":
        return name, unique([check_controller(v.strip()) for v in rhs.split(",")])
    info = PARAMETERS[name]
    if ":" not in rhs:
        return name, unique([_number(info, v.strip()) for v in rhs.split(",")])
    parts = [p.strip() for p in rhs.split(":")]
    syntax = "V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2"
    if len(parts) != 3:
        raise InvalidParameter(name, rhs, syntax)
    lo, hi = _number(info, parts[0]), _number(info, parts[1])
    try:
        n = int(parts[2])
    except ValueError:
        raise InvalidParameter(name, rhs, syntax) from None
    if n < 2 or not lo < hi:
        raise InvalidParameter(name, rhs, syntax)
    if n > MAX_RUNS:
        raise InvalidParameter(name, rhs, f"at most {MAX_RUNS:,} values (N)")
    return name, unique([round_12(x) for x in np.linspace(lo, hi, n)])
