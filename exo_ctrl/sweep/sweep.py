"""Parameter sweeps on an Executor (local processes or a Dask cluster).

A sweep runs the closed loop (:func:`exo_ctrl.sim.loop.simulate`) once per
point of a parameter set and writes one table of the inputs and the figures
that size the drives and the cuffs (peak and RMS drive torque, peak power,
peak current per joint; peak force per cuff; tracking error; status).

**Points.**  ``--param NAME=V1,V2,...`` lists values, ``NAME=LO:HI:N`` gives
N evenly spaced values from LO to HI inclusive.  Without ``samples`` the
points are the cartesian product of the lists, the first parameter varying
slowest, each list in the order given (duplicates dropped).  With
``samples = N`` they are N random points, each numeric parameter uniform in
[min, max] of its listed values (a single value stays constant; explicit
lists only set the bounds) and ``controller`` uniform over its listed
values.  The draws come from ``numpy.random.default_rng(seed)`` one point
at a time, one draw per parameter in the order given, so the points depend
only on the seed and a larger N extends a smaller one.

**Run id.**  Each point resolves to a full run description (every gait,
patient and device value, including the ones not swept, the controller,
gains, motor and cuff constants, duration and rates); its id is the first
16 hex digits of the SHA-256 of that description as canonical JSON.  Equal
runs get equal ids across sweeps, whatever else is swept.

**Files** (for ``--out DIR/NAME.parquet``): ``NAME.parquet`` and ``NAME.csv``
(the table, written atomically at the end and every 30 s),
``NAME.journal.jsonl`` (one JSON line per finished run, flushed and synced
as it arrives), ``NAME.report.txt`` (worst cases, per-joint maxima,
failures), ``NAME.load_<param>.png`` (peak torque and power against each
swept numeric parameter) and ``NAME.urdf_cache/`` (generated patient URDFs,
named by the SHA-256 of their text so that every worker shares them).

**Resume.**  On start the journal (and an existing table) give the finished
runs: status ``completed``, ``diverged`` or ``failed`` (a configuration the
library rejects, e.g. an unreachable foot path).  Those are not run again.
Runs that ended in ``error`` (an unexpected exception) or were interrupted
are run again.

**Patient.**  The patient parameters change
:meth:`~exo_ctrl.model.urdfgen.BodyParams.patient_default`; a changed link length
keeps each cuff at its fraction of the link (0.39/0.52 thigh, 0.45/0.52
shank).  The ranges accepted are the paper's Table I ranges as read in the
design notes: link lengths 0.39-0.65 m, thigh mass 7-14 kg, shank and foot
mass 3-6 kg.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import contextlib
import dataclasses
import functools
import hashlib
import itertools
import json
import math
import multiprocessing
import os
import signal
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._io import atomic_write
from .._progress import Progress
from ..exceptions import ExoCtrlError, InvalidParameter, MissingDependency, SweepError
from ..model.body import CUFF_NAMES, JOINT_NAMES
from ..sim import loop as _simulate_module
from ..sim.loop import SimConfig, simulate

__all__ = [
    "OUTPUT_COLUMNS",
    "PARAMETERS",
    "MissingDependency",
    "ParamInfo",
    "SweepError",
    "SweepInterrupted",
    "SweepPaths",
    "SweepSpec",
    "SweepTask",
    "add_sweep_arguments",
    "base_values",
    "config_for",
    "parameter_names",
    "parse_param",
    "resolved_run",
    "run_id_of",
    "run_point",
    "run_sweep",
    "run_sweep_command",
    "write_plots",
    "write_report",
]

DASK_HINT = 'pip install "exo-ctrl[dask]"'
PLOTS_HINT = 'pip install "exo-ctrl[plots]"'

#: Statuses of runs that are final: a resumed sweep does not run them again.
FINISHED_STATUSES = ("completed", "diverged", "failed")

#: Gait cycles simulated when neither a duration nor a number of cycles is given.
DEFAULT_CYCLES = 2.0

_TABLE_EVERY_S = 30.0  # rewrite the table at least this often during a sweep [s]


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep; the finished runs are kept and the table written.

    Attributes:
        table: the table of the finished runs (pyarrow.Table).
        done: runs finished in this call.
        remaining: runs of the sweep still to do (a rerun resumes them).

    """

    def __init__(self, table: Any, done: int, remaining: int) -> None:
        super().__init__(f"sweep interrupted: {done} runs finished, {remaining} to do")
        self.table = table
        self.done = done
        self.remaining = remaining


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class ParamInfo:
    """A sweepable numeric parameter.

    Attributes:
        name: name as given to ``--param``.
        group: ``"gait"``, ``"patient"`` or ``"device"``.
        attribute: the field it sets (of GaitParams, BodyParams, CuffParams or MotorParams).
        unit: SI unit ("" for none).
        lo: lower bound of the accepted values.
        hi: upper bound.
        lo_open: lo itself is excluded.
        hi_open: hi itself is excluded.

    """

    name: str
    group: str
    attribute: str
    unit: str
    lo: float
    hi: float
    lo_open: bool = False
    hi_open: bool = False

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


def _p(name: str, group: str, fld: str, unit: str, lo: float, hi: float, **kw: bool) -> ParamInfo:
    return ParamInfo(name, group, fld, unit, lo, hi, **kw)


#: Numeric sweep parameters.  Gait bounds are wide sanity bounds (the reach
#: and the other limits are checked per run, and a run that violates them is
#: recorded as ``failed``); patient bounds are the paper's Table I ranges;
#: device bounds span plausible hardware (paper: 8 N/mm cuffs).
PARAMETERS: dict[str, ParamInfo] = {
    p.name: p
    for p in (
        _p("step_length", "gait", "step_length", "m", 0.0, 2.0, lo_open=True),
        _p("lift_height", "gait", "lift_height", "m", 0.0, 0.5, lo_open=True),
        _p("hip_height", "gait", "hip_height", "m", 0.0, 2.0, lo_open=True),
        _p("shape_coeff", "gait", "shape_coeff", "", 0.0, 10.0, lo_open=True),
        _p("period", "gait", "period", "s", 0.0, 10.0, lo_open=True),
        _p("duty_factor", "gait", "duty_factor", "", 0.5, 1.0, hi_open=True),
        _p("patient_thigh_mass", "patient", "thigh_mass", "kg", 7.0, 14.0),
        _p("patient_shank_mass", "patient", "shank_mass", "kg", 3.0, 6.0),
        _p("patient_thigh_length", "patient", "thigh_length", "m", 0.39, 0.65),
        _p("patient_shank_length", "patient", "shank_length", "m", 0.39, 0.65),
        _p("cuff_stiffness", "device", "stiffness_N_per_m", "N/m", 1e3, 1e5),
        _p("cuff_damping", "device", "damping_N_s_per_m", "N·s/m", 0.0, 1e3),
        _p("gear_ratio", "device", "gear_ratio", "", 1.0, 500.0),
    )
}


def _controllers() -> tuple[str, ...]:
    """The controllers :class:`SimConfig` accepts (read at call time)."""
    return tuple(_simulate_module.CONTROLLERS)


def parameter_names() -> tuple[str, ...]:
    """Every sweepable parameter name: the numeric ones, then ``controller``."""
    return (*PARAMETERS, "controller")


def _unit_suffix(unit: str) -> str:
    return f" [{unit}]" if unit else ""


def _number(info: ParamInfo, text: str) -> float:
    """Parse and check one value of a numeric parameter."""
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise InvalidParameter(info.name, text, f"a finite number{_unit_suffix(info.unit)}")
    return _checked(info, x)


def _checked(info: ParamInfo, value: Any) -> float:
    """Check a numeric value (already parsed) against ``info``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidParameter(info.name, value, f"a finite number{_unit_suffix(info.unit)}")
    x = float(value)
    if not math.isfinite(x):
        raise InvalidParameter(info.name, value, f"a finite number{_unit_suffix(info.unit)}")
    if not info.accepts(x):
        raise InvalidParameter(info.name, x, info.interval())
    return x


def _controller(value: Any) -> str:
    allowed = _controllers()
    if value not in allowed:
        raise InvalidParameter("controller", value, f"one of {', '.join(allowed)}")
    return str(value)


def _round(x: float) -> float:
    """``x`` to 12 significant digits (so 0.3:0.5:3 gives 0.4, not 0.39999999999999997)."""
    return float(f"{x:.12g}")


def _unique(values: Sequence[Any]) -> tuple[Any, ...]:
    return tuple(dict.fromkeys(values))


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
        return name, _unique([_controller(v.strip()) for v in rhs.split(",")])
    info = PARAMETERS[name]
    if ":" not in rhs:
        return name, _unique([_number(info, v.strip()) for v in rhs.split(",")])
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
    return name, _unique([_round(x) for x in np.linspace(lo, hi, n)])


# --------------------------------------------------------------------------- spec


@dataclass(frozen=True)
class SweepTask:
    """One run of a sweep.

    Attributes:
        index: position in the sweep's point order (0-based).
        run_id: stable hash of the resolved run (see the module docstring).
        point: the swept parameters' values of this run.
        values: every sweepable parameter's value for this run (swept or
            from the base), plus ``duration_s`` [s] (input of :func:`run_point`).
        run: the resolved run as plain data: the base :class:`SimConfig` as a
            dict with ``values`` applied, plus ``patient_body`` (what the id hashes).

    """

    index: int
    run_id: str
    point: dict[str, Any]
    values: dict[str, Any]
    run: dict[str, Any]

    @property
    def label(self) -> str:
        """The point in words, e.g. ``step_length=0.4 m, controller=ct``."""
        return _label(self.point)


def _label(point: dict[str, Any]) -> str:
    parts = []
    for name, value in point.items():
        if name == "controller":
            parts.append(f"{name}={value}")
        else:
            unit = PARAMETERS[name].unit
            parts.append(f"{name}={value:.10g}" + (f" {unit}" if unit else ""))
    return ", ".join(parts)


@dataclass(frozen=True)
class SweepSpec:
    """What to sweep: parameters and their values, grid or random samples.

    Attributes:
        params: ``(name, values)`` pairs, in the order given (see
            :func:`parse_param`); names must be distinct.
        samples: None for the full grid, else the number of random points.
        seed: seed of the random points [-] (integer >= 0).
        duration_s: simulated time per run [s]; exclusive with ``cycles``.
        cycles: gait cycles per run (duration = cycles × the run's period);
            when neither is given, :data:`DEFAULT_CYCLES`.
        base: the run every point starts from (values not swept, gains,
            motor and cuff constants, exo and patient, rates).  Patient
            parameters can only be swept with ``base.patient`` None.

    Raises:
        InvalidParameter: on any invalid field.

    """

    params: tuple[tuple[str, tuple[Any, ...]], ...]
    samples: int | None = None
    seed: int = 0
    duration_s: float | None = None
    cycles: float | None = None
    base: SimConfig = field(default_factory=SimConfig)

    def __post_init__(self) -> None:
        params = tuple((str(name), tuple(values)) for name, values in self.params)
        if not params:
            raise InvalidParameter("--param", "", "given at least once (NAME=V1,V2,...)")
        seen: set[str] = set()
        checked = []
        for name, values in params:
            if name not in parameter_names():
                raise InvalidParameter(
                    "sweep parameter", name, f"one of {', '.join(parameter_names())}"
                )
            if name in seen:
                raise InvalidParameter("sweep parameter", name, "given once")
            seen.add(name)
            if not values:
                raise InvalidParameter(name, values, "at least one value")
            if name == "controller":
                vals = _unique([_controller(x) for x in values])
            else:
                vals = _unique([_checked(PARAMETERS[name], x) for x in values])
            checked.append((name, vals))
        object.__setattr__(self, "params", tuple(checked))
        self._check_run_fields(seen)

    def _check_run_fields(self, names: set[str]) -> None:
        if self.samples is not None and (
            isinstance(self.samples, bool) or not isinstance(self.samples, int) or self.samples < 1
        ):
            raise InvalidParameter("samples", self.samples, "an integer >= 1")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidParameter("seed", self.seed, "an integer >= 0")
        if self.duration_s is not None and self.cycles is not None:
            raise InvalidParameter("cycles", self.cycles, "unset when a duration is given")
        for name, value, unit in (("duration", self.duration_s, "s"), ("cycles", self.cycles, "")):
            if value is not None and not (
                isinstance(value, (int, float)) and math.isfinite(value) and value > 0
            ):
                raise InvalidParameter(name, value, f"a finite number > 0{_unit_suffix(unit)}")
        patient = sorted(n for n in names if n in PARAMETERS and PARAMETERS[n].group == "patient")
        if patient and self.base.patient is not None:
            raise InvalidParameter(
                patient[0],
                self.base.patient,
                "swept only with the generated patient (no patient URDF given)",
            )

    @classmethod
    def parse(
        cls,
        texts: Sequence[str],
        *,
        samples: int | None = None,
        seed: int = 0,
        duration_s: float | None = None,
        cycles: float | None = None,
        base: SimConfig | None = None,
    ) -> SweepSpec:
        """Build a spec from ``--param`` texts (see :func:`parse_param`)."""
        params = []
        seen: set[str] = set()
        for text in texts:
            name, values = parse_param(text)
            if name in seen:
                raise InvalidParameter("sweep parameter", name, "given once")
            seen.add(name)
            params.append((name, values))
        return cls(
            params=tuple(params),
            samples=samples,
            seed=seed,
            duration_s=duration_s,
            cycles=cycles,
            base=base if base is not None else SimConfig(),
        )

    @property
    def names(self) -> tuple[str, ...]:
        """The swept parameters, in the order given."""
        return tuple(name for name, _ in self.params)

    def points(self) -> list[dict[str, Any]]:
        """The swept values of every run, in run order (see the module docstring)."""
        if self.samples is None:
            combos = itertools.product(*(values for _, values in self.params))
            return [dict(zip(self.names, combo, strict=True)) for combo in combos]
        rng = np.random.default_rng(self.seed)
        points = []
        for _ in range(self.samples):
            point: dict[str, Any] = {}
            for name, values in self.params:
                u = float(rng.random())
                if name == "controller":
                    point[name] = values[min(int(u * len(values)), len(values) - 1)]
                else:
                    lo, hi = min(values), max(values)
                    point[name] = _round(lo + u * (hi - lo))
            points.append(point)
        return points

    def tasks(self) -> list[SweepTask]:
        """The runs, in run order; points that resolve to the same run appear once."""
        tasks: list[SweepTask] = []
        seen: set[str] = set()
        for point in self.points():
            values = self.resolve(point)
            run = resolved_run(self.base, values)
            run_id = run_id_of(run)
            if run_id not in seen:
                seen.add(run_id)
                tasks.append(SweepTask(len(tasks), run_id, point, values, run))
        return tasks

    def resolve(self, point: dict[str, Any]) -> dict[str, Any]:
        """Every sweepable value of a point's run (swept or the base's), and its duration.

        Returns:
            name → value for every parameter of :func:`parameter_names`
            (the patient ones only when ``base.patient`` is None), plus
            ``duration_s`` [s].  Values are not cross-checked here (e.g.
            lift vs hip height): the worker builds the run and records a
            rejected one as ``failed``.

        """
        values = base_values(self.base)
        values.update(point)
        if self.duration_s is not None:
            values["duration_s"] = float(self.duration_s)
        else:
            cycles = self.cycles if self.cycles is not None else DEFAULT_CYCLES
            values["duration_s"] = _round(cycles * float(values["period"]))
        return values

    def describe(self) -> dict[str, Any]:
        """The spec as plain data (stored in the table's metadata)."""
        return {
            "params": {name: list(values) for name, values in self.params},
            "samples": self.samples,
            "seed": self.seed,
            "duration_s": self.duration_s,
            "cycles": self.cycles,
            "base": self.base.to_dict(),
        }


_PATIENT_FIELDS = ("thigh_mass", "shank_mass", "thigh_length", "shank_length")


def base_values(base: SimConfig) -> dict[str, Any]:
    """The value of every sweepable parameter in ``base`` (patient: the generated default)."""
    values: dict[str, Any] = {}
    for name, info in PARAMETERS.items():
        if info.group == "gait":
            values[name] = getattr(base.gait, info.attribute)
        elif info.group == "patient":
            if base.patient is None:
                values[name] = getattr(_default_patient(), info.attribute)
        elif hasattr(base.motor, info.attribute):
            values[name] = getattr(base.motor, info.attribute)
        else:
            values[name] = getattr(base.cuffs, info.attribute)
    values["controller"] = base.controller
    return values


def resolved_run(base: SimConfig, values: dict[str, Any]) -> dict[str, Any]:
    """The run as plain data: ``base.to_dict()`` with ``values`` applied.

    The patient parameters, when swept, appear as ``patient_body`` (the
    generated URDF's path depends on where the sweep writes; its content
    does not).
    """
    run = base.to_dict()
    run["patient_body"] = None
    for name, value in values.items():
        info = PARAMETERS.get(name)
        if info is None:  # controller, duration_s
            run[name] = value
        elif info.group == "patient":
            run["patient_body"] = run["patient_body"] or {}
            run["patient_body"][info.attribute] = value
        elif info.group == "gait":
            run["gait"][info.attribute] = value
        else:
            run["motor" if info.attribute in run["motor"] else "cuffs"][info.attribute] = value
    return run


def run_id_of(run: dict[str, Any]) -> str:
    """Stable id of a resolved run: 16 hex digits of SHA-256 of its canonical JSON."""
    text = json.dumps(run, sort_keys=True, separators=(",", ":"), allow_nan=False, default=repr)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


# --------------------------------------------------------------------------- worker

_METRICS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("peak_drive_torque_Nm", JOINT_NAMES),
    ("rms_drive_torque_Nm", JOINT_NAMES),
    ("peak_mechanical_power_W", JOINT_NAMES),
    ("peak_motor_current_A", JOINT_NAMES),
    ("peak_motor_voltage_V", JOINT_NAMES),
    ("peak_cuff_force_N", CUFF_NAMES),
    ("rms_tracking_error_rad", JOINT_NAMES),
    ("max_tracking_error_rad", JOINT_NAMES),
)

#: Output columns of the table after the run id and the swept parameters:
#: name → Arrow type name.  Per-joint and per-cuff figures are flat columns
#: ``<summary key>_<joint or cuff>`` (units in the name); ``safety_events``
#: counts the supervisor's violations and e-stops, ``safety_state`` is its
#: final state, ``qp_failures`` the QP controller's fallbacks (0 and "" when
#: the summary has no such key); ``sim_duration_s`` is the simulated time
#: reached; ``wall_time_s`` the run's wall-clock time, set-up included.
OUTPUT_COLUMNS: dict[str, str] = {
    **{f"{key}_{n}": "float64" for key, names in _METRICS for n in names},
    "belt_speed_mps": "float64",
    "sim_duration_s": "float64",
    "safety_events": "int64",
    "safety_state": "string",
    "qp_failures": "int64",
    "status": "string",
    "error": "string",
    "wall_time_s": "float64",
}


def _empty_outputs() -> dict[str, Any]:
    out: dict[str, Any] = {c: math.nan for c, t in OUTPUT_COLUMNS.items() if t == "float64"}
    out.update(safety_events=0, safety_state="", qp_failures=0, status="error", error="")
    return out


def _count(events: Any) -> int:
    """A summary's safety events as a count (a number, or a list/dict of events)."""
    if events is None:
        return 0
    if isinstance(events, (int, float, np.integer, np.floating)):
        return int(events)
    return len(events)


def _flatten(summary: dict[str, Any]) -> dict[str, Any]:
    out = {f"{key}_{n}": float(summary[key][n]) for key, names in _METRICS for n in names}
    out["belt_speed_mps"] = float(summary["belt_speed_mps"])
    out["sim_duration_s"] = float(summary["duration_s"])
    out["safety_events"] = _count(summary.get("safety_events", 0))
    out["safety_state"] = str(summary.get("safety_state", ""))
    out["qp_failures"] = int(summary.get("qp_failures", 0))
    return out


@functools.cache
def _default_patient() -> Any:
    """:meth:`BodyParams.patient_default` (urdfgen imports yourdfpy: ~1 s, so lazily)."""
    from ..model.urdfgen import BodyParams

    return BodyParams.patient_default()


def _patient_urdf(body: dict[str, float], cache_dir: str) -> str | None:
    """The patient URDF of ``body`` in the cache (None: the default patient)."""
    from ..model.urdfgen import BodyParams, urdf_xml, write_urdf

    default = _default_patient()
    if all(getattr(default, k) == v for k, v in body.items()):
        return None
    changes = dict(body)
    for seg in ("thigh", "shank"):  # a cuff keeps its fraction of its link
        length = changes[f"{seg}_length"]
        ref = getattr(default, f"{seg}_length")
        changes[f"{seg}_cuff"] = getattr(default, f"{seg}_cuff") / ref * length
    params = BodyParams.patient_default(**changes)
    digest = hashlib.sha256(urdf_xml(params).encode("utf-8")).hexdigest()[:16]
    for folder in (Path(cache_dir), Path(tempfile.gettempdir()) / "exo_ctrl_sweep"):
        path = folder / f"patient-{digest}.urdf"
        if path.is_file():
            return str(path)
        with contextlib.suppress(OSError):  # e.g. a remote worker without the folder
            folder.mkdir(parents=True, exist_ok=True)
            return str(write_urdf(params, path))
    raise SweepError(f"cannot write the patient URDF into {cache_dir}")


def config_for(base: SimConfig, values: dict[str, Any], cache_dir: str) -> SimConfig:
    """The :class:`SimConfig` of a run: ``base`` with ``values`` (:meth:`SweepSpec.resolve`).

    Generates the patient URDF into ``cache_dir`` when patient values differ
    from the default patient.

    Raises:
        ExoCtrlError: a value or combination the library rejects.

    """
    groups: dict[str, dict[str, Any]] = {"gait": {}, "patient": {}, "motor": {}, "cuffs": {}}
    for name, value in values.items():
        info = PARAMETERS.get(name)
        if info is None:
            continue
        group = info.group
        if group == "device":
            group = "motor" if hasattr(base.motor, info.attribute) else "cuffs"
        groups[group][info.attribute] = value
    patient = base.patient
    if base.patient is None and groups["patient"]:
        patient = _patient_urdf(groups["patient"], cache_dir)
    return dataclasses.replace(
        base,
        gait=dataclasses.replace(base.gait, **groups["gait"]),
        patient=patient,
        controller=values.get("controller", base.controller),
        motor=dataclasses.replace(base.motor, **groups["motor"]),
        cuffs=dataclasses.replace(base.cuffs, **groups["cuffs"]),
        duration_s=values.get("duration_s", base.duration_s),
    )


def run_point(
    base: SimConfig, values: dict[str, Any], cache_dir: str, label: str = ""
) -> dict[str, Any]:
    """Run one point; never raises for a bad run (runs in a worker).

    Args:
        base: the sweep's base run.
        values: the point's resolved values (:meth:`SweepSpec.resolve`).
        cache_dir: folder for generated patient URDFs.
        label: the point in words, appended to an error message.

    Returns:
        The output columns (:data:`OUTPUT_COLUMNS`).  ``status`` is the
        simulation's (``completed``, ``diverged``, ``interrupted``),
        ``failed`` when the library rejects the configuration
        (:class:`~exo_ctrl.exceptions.ExoCtrlError`, e.g. an unreachable
        foot path), or ``error`` for any other exception; ``error`` then
        holds ``<exception type>: <message> [<point>]``.  ``wall_time_s`` is
        the whole run's wall-clock time [s], model building included.

    """
    start = time.perf_counter()
    out = _empty_outputs()
    try:
        result = simulate(config_for(base, values, cache_dir), keep_history=False)
        out.update(_flatten(result.summary()))
        out["status"], out["error"] = result.status, result.error
    except ExoCtrlError as exc:
        out["status"], out["error"] = "failed", f"{type(exc).__name__}: {exc}"
    except Exception as exc:
        out["status"], out["error"] = "error", f"{type(exc).__name__}: {exc}"
    if out["error"] and label:
        out["error"] += f" [{label}]"
    out["wall_time_s"] = time.perf_counter() - start
    return out


def _ignore_sigint() -> None:
    """Pool worker initializer: Ctrl-C is the parent's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class _InlineExecutor(cf.Executor):
    """Runs each submitted call at once in this process (``workers = 1``)."""

    def submit(self, fn, /, *args, **kwargs):
        future: cf.Future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as exc:
            future.set_exception(exc)
        return future


# --------------------------------------------------------------------------- files


@dataclass(frozen=True)
class SweepPaths:
    """The files of a sweep, all beside the output table."""

    table: Path
    csv: Path
    journal: Path
    report: Path
    cache: Path

    @classmethod
    def for_output(cls, out_path: str | os.PathLike[str]) -> SweepPaths:
        """Paths for an output ``DIR/NAME.parquet``."""
        table = Path(out_path)
        if table.suffix != ".parquet" or not table.stem:
            raise InvalidParameter("out", str(out_path), "a path ending in .parquet")
        stem = table.with_suffix("")
        return cls(
            table=table,
            csv=table.with_suffix(".csv"),
            journal=Path(f"{stem}.journal.jsonl"),
            report=Path(f"{stem}.report.txt"),
            cache=Path(f"{stem}.urdf_cache"),
        )

    def plot(self, name: str) -> Path:
        """The load diagram of a swept parameter."""
        return Path(f"{self.table.with_suffix('')}.load_{name}.png")


def _require(module: str, message: str) -> Any:
    """Import an optional module, or raise :class:`MissingDependency` with ``message``."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingDependency(message) from None


def _pyarrow() -> Any:
    return _require("pyarrow", "the sweep table needs pyarrow: pip install pyarrow")


def _read_previous(paths: SweepPaths) -> dict[str, dict[str, Any]]:
    """Results of earlier runs by run id: the old table, then the journal (later wins)."""
    results: dict[str, dict[str, Any]] = {}
    if paths.table.is_file():
        import pyarrow.parquet as pq

        with contextlib.suppress(Exception):  # an unreadable old table: rely on the journal
            old = pq.read_table(paths.table)
            if {"run_id", *OUTPUT_COLUMNS} <= set(old.column_names):
                for row in old.select(["run_id", *OUTPUT_COLUMNS]).to_pylist():
                    results[row.pop("run_id")] = _fill(row)
    if paths.journal.is_file():
        with paths.journal.open(encoding="utf-8") as handle:
            for line in handle:
                try:
                    entry = json.loads(line)
                    results[entry["run_id"]] = _fill(entry["outputs"])
                except (ValueError, KeyError, TypeError):
                    continue  # a line torn by a kill
    return results


def _fill(row: dict[str, Any]) -> dict[str, Any]:
    out = _empty_outputs()
    out.update({k: row[k] for k in OUTPUT_COLUMNS if k in row and row[k] is not None})
    return out


class _Journal:
    """Append-only JSON lines, one per finished run, flushed and synced per line."""

    def __init__(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        torn = False
        if path.is_file() and path.stat().st_size:
            with path.open("rb") as handle:
                handle.seek(-1, os.SEEK_END)
                torn = handle.read(1) != b"\n"
        self._handle = path.open("a", encoding="utf-8")
        if torn:  # end a line torn by a kill, so the next entry starts clean
            self._handle.write("\n")

    def write(self, task: SweepTask, outputs: dict[str, Any]) -> None:
        entry = {"run_id": task.run_id, "point": task.point, "outputs": outputs}
        entry["run"] = task.run
        self._handle.write(json.dumps(entry) + "\n")
        self._handle.flush()
        os.fsync(self._handle.fileno())

    def close(self) -> None:
        self._handle.close()


def _table(spec: SweepSpec, tasks: list[SweepTask], results: dict[str, dict[str, Any]]) -> Any:
    """The table of the runs of ``tasks`` that have a result, in run order."""
    pa = _pyarrow()
    rows = [(t, results[t.run_id]) for t in tasks if t.run_id in results]
    types = {"float64": pa.float64(), "int64": pa.int64(), "string": pa.string()}
    columns: dict[str, Any] = {
        "run_index": pa.array([t.index for t, _ in rows], pa.int64()),
        "run_id": pa.array([t.run_id for t, _ in rows], pa.string()),
    }
    for name in spec.names:
        kind = pa.string() if name == "controller" else pa.float64()
        columns[name] = pa.array([t.point[name] for t, _ in rows], kind)
    for name, kind in OUTPUT_COLUMNS.items():
        columns[name] = pa.array([r[name] for _, r in rows], types[kind])
    meta = {"exo_ctrl.sweep": json.dumps(spec.describe())}
    return pa.table(columns).replace_schema_metadata(meta)


def _write_table(table: Any, paths: SweepPaths) -> None:
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    with atomic_write(paths.table, "wb") as handle:
        pq.write_table(table, handle)
    with atomic_write(paths.csv, "wb") as handle:
        pcsv.write_csv(table, handle)


# --------------------------------------------------------------------------- running


def _pool(workers: int) -> cf.ProcessPoolExecutor:
    # spawn: a clean interpreter per worker (fork after pyarrow/rerun threads
    # exist can deadlock); workers ignore Ctrl-C, the parent handles it.
    return cf.ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_ignore_sigint,
    )


def _stop_pool(pool: cf.Executor, now: bool) -> None:
    """Shut an owned pool down; ``now``: cancel queued runs and kill running ones."""
    if not now:
        pool.shutdown(wait=True)
        return
    procs = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in procs:
        with contextlib.suppress(Exception):
            proc.terminate()
    for proc in procs:
        with contextlib.suppress(Exception):
            proc.join(timeout=5)


def _outputs_of(future: cf.Future) -> dict[str, Any]:
    try:
        return future.result()
    except Exception as exc:  # the worker itself was lost (e.g. killed)
        out = _empty_outputs()
        out["error"] = f"{type(exc).__name__}: {exc}"
        return out


def run_sweep(
    spec: SweepSpec,
    out_path: str | os.PathLike[str],
    executor: cf.Executor | None = None,
    workers: int | None = None,
    progress: bool = True,
    *,
    plots: bool = True,
    report: bool = True,
) -> Any:
    """Run a sweep, resuming from the files of an earlier one at ``out_path``.

    Args:
        spec: what to sweep.
        out_path: the output table, ``DIR/NAME.parquet``; the CSV, journal,
            report, plots and URDF cache go beside it (see the module docstring).
        executor: where to run (any :class:`concurrent.futures.Executor`,
            e.g. a Dask ``Client.get_executor()``); not shut down here.
            None: a local process pool of ``workers`` (one worker: in this
            process).
        workers: pool size (default ``os.cpu_count()``); with an
            ``executor``, the number of its workers (at most 2 × workers runs
            are queued at a time; None: all at once).
        progress: draw a progress bar (done, failed, ETA) on stderr.
        plots: write the load diagrams (needs matplotlib).
        report: write the text report.

    Returns:
        The table (pyarrow.Table), one row per run in run order: ``run_index``,
        ``run_id``, the swept parameters, then :data:`OUTPUT_COLUMNS`.

    Raises:
        SweepInterrupted: on Ctrl-C, after writing the table of the runs
            finished so far (a rerun resumes).
        MissingDependency: pyarrow, or matplotlib for plots, is missing.

    """
    _pyarrow()
    if plots:
        _require("matplotlib", f"the load plots need matplotlib: {PLOTS_HINT}")
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise InvalidParameter("workers", workers, "an integer >= 1")
    paths = SweepPaths.for_output(out_path)
    tasks = spec.tasks()
    results = _read_previous(paths)
    todo = [t for t in tasks if results.get(t.run_id, {}).get("status") not in FINISHED_STATUSES]
    owned = None
    if executor is None and todo:
        n = min(workers or os.cpu_count() or 1, len(todo))
        executor = owned = _InlineExecutor() if n == 1 else _pool(n)
        workers = n
    window = 2 * workers if workers else max(len(todo), 1)
    if progress:
        where = "in this process" if isinstance(executor, _InlineExecutor) else "on "
        if where == "on ":
            where += f"{workers} workers" if workers else "the given executor"
        print(
            f"sweep: {len(tasks)} runs, {len(tasks) - len(todo)} already done "
            f"({paths.journal.name}), {len(todo)} to run {where}",
            file=sys.stderr,
        )
    state = _State(spec, tasks, paths, results, len(todo), progress)
    interrupted = clean = False
    try:
        if executor is not None:
            state.drive(executor, todo, window)
        clean = True
    except KeyboardInterrupt:
        interrupted = True
    finally:
        state.journal.close()
        if owned is not None:
            _stop_pool(owned, now=not clean)
        state.bar.close(state.done, state.note())
        table = state.write_table()
    if interrupted:
        raise SweepInterrupted(table, state.done, len(todo) - state.done)
    if report:
        write_report(table, spec, paths.report)
    if plots:
        write_plots(table, spec, paths)
    return table


class _State:
    """A sweep in progress: results by run id, the journal, the progress bar."""

    def __init__(
        self,
        spec: SweepSpec,
        tasks: list[SweepTask],
        paths: SweepPaths,
        results: dict[str, dict[str, Any]],
        total: int,
        progress: bool,
    ) -> None:
        self.spec, self.tasks, self.paths, self.results = spec, tasks, paths, results
        self.total = total
        self.done = self.failed = 0
        self.journal = _Journal(paths.journal)
        self.bar = Progress(total, "sweep", enabled=progress)
        self._pending: dict[cf.Future, SweepTask] = {}

    def note(self) -> str:
        """Progress note: done and failed runs."""
        return f"{self.done}/{self.total} done, {self.failed} failed"

    def write_table(self) -> Any:
        """Write (atomically) and return the table of the results so far."""
        table = _table(self.spec, self.tasks, self.results)
        _write_table(table, self.paths)
        return table

    def drive(self, executor: cf.Executor, todo: list[SweepTask], window: int) -> None:
        """Submit ``todo`` (at most ``window`` in flight); journal results as they come.

        On Ctrl-C: keep the runs already finished, cancel the rest, re-raise.
        """
        queue = iter(todo)
        pending = self._pending
        cache = str(self.paths.cache)
        last_write = time.monotonic()
        try:
            while True:
                while len(pending) < window and (task := next(queue, None)) is not None:
                    future = executor.submit(
                        run_point, self.spec.base, task.values, cache, task.label
                    )
                    pending[future] = task
                if not pending:
                    return
                done, _ = cf.wait(pending, timeout=1.0, return_when=cf.FIRST_COMPLETED)
                for future in done:
                    self._take(future)
                self.bar.update(self.done, self.note())
                if time.monotonic() - last_write > _TABLE_EVERY_S:
                    self.write_table()
                    last_write = time.monotonic()
        except KeyboardInterrupt:
            for future in list(pending):
                if future.done() and not future.cancelled() and future.exception() is None:
                    with contextlib.suppress(KeyboardInterrupt):
                        self._take(future)
                else:
                    future.cancel()
            raise

    def _take(self, future: cf.Future) -> None:
        task = self._pending.pop(future)
        outputs = _outputs_of(future)
        if outputs["status"] == "interrupted":  # Ctrl-C inside an in-process run
            raise KeyboardInterrupt
        self.results[task.run_id] = outputs
        self.journal.write(task, outputs)
        self.done += 1
        self.failed += outputs["status"] != "completed"


# --------------------------------------------------------------------------- report, plots


def _columns(table: Any) -> dict[str, np.ndarray]:
    return {name: np.asarray(table.column(name).to_pylist()) for name in table.column_names}


def _worst(cols: dict[str, np.ndarray], key: str, names: Sequence[str], ok: np.ndarray) -> Any:
    """(row, name, value, ties) of the largest ``key_<name>`` over completed rows."""
    values = np.column_stack([cols[f"{key}_{n}"].astype(float) for n in names])
    per_row = np.where(ok, np.nanmax(np.where(np.isnan(values), -np.inf, values), axis=1), -np.inf)
    row = int(np.argmax(per_row))
    col = int(np.argmax(values[row]))
    return row, names[col], float(values[row, col]), int(np.sum(per_row == per_row[row]))


def write_report(table: Any, spec: SweepSpec, path: str | os.PathLike[str]) -> Path:
    """Write the text report: worst cases with their parameters, maxima, failures.

    The worst case of a figure is the completed run with its largest value
    over the joints (cuffs); ties go to the first in run order.
    """
    cols = _columns(table)
    status = cols["status"].astype(str) if len(table) else np.array([], dtype=str)
    ok = status == "completed"
    lines = [
        f"exo-ctrl sweep: {len(table)} runs, {int(ok.sum())} completed, "
        f"{int((~ok).sum())} not completed",
        "swept: "
        + ", ".join(f"{n} ({len(v)} values)" for n, v in spec.params)
        + (f"; {spec.samples} random samples, seed {spec.seed}" if spec.samples else "; grid"),
    ]

    def point(row: int) -> str:
        return _label({n: cols[n][row].item() for n in spec.names})

    if ok.any():
        for title, key, names, unit in (
            ("peak drive torque", "peak_drive_torque_Nm", JOINT_NAMES, "N·m"),
            ("peak cuff force", "peak_cuff_force_N", CUFF_NAMES, "N"),
        ):
            row, name, value, ties = _worst(cols, key, names, ok)
            lines.append(
                f"worst {title}: {value:.6g} {unit} at {name}, run {int(cols['run_index'][row])} "
                f"({cols['run_id'][row]}): {point(row)}"
            )
            if ties > 1:
                lines.append(f"  ({ties} completed runs reach the same value)")
        lines.append("maxima over completed runs:")
        lines.append(f"  {'joint':<12}{'torque [N·m]':>14}{'power [W]':>12}{'current [A]':>13}")
        for j in JOINT_NAMES:
            tau, pw, cur = (
                float(np.nanmax(cols[f"{k}_{j}"][ok].astype(float)))
                for k in ("peak_drive_torque_Nm", "peak_mechanical_power_W", "peak_motor_current_A")
            )
            lines.append(f"  {j:<12}{tau:>14.4g}{pw:>12.4g}{cur:>13.4g}")
        flagged = int((cols["safety_events"][ok].astype(int) > 0).sum())
        lines.append(f"completed runs with safety events: {flagged}")
    else:
        lines.append("no run completed: no worst case")
    failed = np.flatnonzero(~ok)
    lines.append(f"failures ({len(failed)}):")
    for row in failed:
        lines.append(
            f"  run {int(cols['run_index'][row])} ({cols['run_id'][row]}): "
            f"{cols['status'][row]}: {cols['error'][row]}"
        )
    with atomic_write(path) as handle:
        handle.write("\n".join(lines) + "\n")
    return Path(path)


def write_plots(table: Any, spec: SweepSpec, paths: SweepPaths) -> list[Path]:
    """Write one load diagram per swept numeric parameter; returns the files.

    Each figure has peak drive torque [N·m] (top) and peak mechanical power
    [W] (bottom) of the four joints against the parameter, one point per
    completed run; with several runs per value (other parameters swept too)
    a line joins the largest value at each, the envelope to size against.
    """
    _require("matplotlib", f"the load plots need matplotlib: {PLOTS_HINT}")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    cols = _columns(table)
    ok = cols["status"].astype(str) == "completed" if len(table) else np.zeros(0, bool)
    written = []
    for name in spec.names:
        if name == "controller" or not ok.any():
            continue
        x = cols[name][ok].astype(float)
        fig = Figure(figsize=(8.0, 6.5), layout="constrained")
        FigureCanvasAgg(fig)
        axes = fig.subplots(2, 1, sharex=True)
        for ax, key, ylabel in (
            (axes[0], "peak_drive_torque_Nm", "peak drive torque [N·m]"),
            (axes[1], "peak_mechanical_power_W", "peak mechanical power [W]"),
        ):
            for joint, marker in zip(JOINT_NAMES, "os^v", strict=True):
                y = cols[f"{key}_{joint}"][ok].astype(float)
                dots = ax.plot(x, y, marker, ms=5, mfc="none", label=joint)[0]
                xs = np.unique(x)
                if len(xs) < len(x):
                    env = [np.nanmax(y[x == v]) for v in xs]
                    ax.plot(xs, env, "-", color=dots.get_color(), alpha=0.6)
            ax.set_ylabel(ylabel)
            ax.grid(True, alpha=0.3)
        axes[0].legend(fontsize="small", ncols=2)
        unit = PARAMETERS[name].unit
        axes[1].set_xlabel(name + (f" [{unit}]" if unit else ""))
        fig.suptitle(f"drive loads against {name} ({int(ok.sum())} completed runs)")
        target = paths.plot(name)
        with atomic_write(target, "wb") as handle:
            fig.savefig(handle, format="png", dpi=100)
        written.append(target)
    return written


# --------------------------------------------------------------------------- CLI


def add_sweep_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``exo-ctrl sweep`` options to ``parser``."""
    controllers = _controllers()
    parser.add_argument(
        "--param",
        action="append",
        required=True,
        metavar="NAME=V1,V2,...|NAME=LO:HI:N",
        help="a swept parameter: a list, or N evenly spaced values LO..HI (repeatable); "
        f"names: {', '.join(parameter_names())}",
    )
    parser.add_argument(
        "--samples",
        type=int,
        default=None,
        metavar="N",
        help="N random points, uniform in each parameter's [min, max] (default: the full grid)",
    )
    parser.add_argument(
        "--seed", type=int, default=0, metavar="S", help="seed of --samples (default 0)"
    )
    parser.add_argument(
        "--out",
        required=True,
        metavar="PATH.parquet",
        help="output table; PATH.csv, PATH.journal.jsonl (resume), PATH.report.txt and "
        "PATH.load_*.png go beside it",
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="local worker processes (default: the CPU count; 1: in this process)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="tcp://HOST:PORT",
        help=f"run on this Dask scheduler instead (needs {DASK_HINT})",
    )
    span = parser.add_mutually_exclusive_group()
    span.add_argument(
        "--cycles",
        type=float,
        default=None,
        metavar="N",
        help=f"gait cycles per run (default {DEFAULT_CYCLES:g})",
    )
    span.add_argument(
        "--duration", type=float, default=None, metavar="SEC", help="simulated time per run [s]"
    )
    parser.add_argument(
        "--controller",
        choices=controllers,
        default=None,
        help="controller when not swept (default pd)",
    )
    parser.add_argument(
        "--rate", type=float, default=1000.0, metavar="HZ", help="control rate [Hz] (default 1000)"
    )
    parser.add_argument(
        "--substeps", type=int, default=1, metavar="N", help="plant steps per tick (default 1)"
    )
    parser.add_argument("--no-plots", action="store_true", help="do not write the load diagrams")


def _dask_executor(address: str) -> tuple[cf.Executor, int, Any]:
    try:
        from distributed import Client
    except ImportError:
        raise MissingDependency(f"--scheduler needs Dask: {DASK_HINT}") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise SweepError(f"cannot connect to the Dask scheduler at {address}: {exc}") from None
    workers = max(sum(client.nthreads().values()), 1)
    return client.get_executor(pure=False), workers, client


def run_sweep_command(args: argparse.Namespace) -> int:
    """Run ``exo-ctrl sweep``; returns the exit code (0 done, 130 interrupted).

    Bad input raises :class:`~exo_ctrl.exceptions.ExoCtrlError` (the CLI
    prints it in one line and exits 2).
    """
    names = [p.partition("=")[0].strip() for p in args.param]
    if args.controller is not None and "controller" in names:
        raise InvalidParameter(
            "controller", args.controller, "given once: --controller or --param controller=..."
        )
    if args.scheduler is not None and args.workers is not None:
        raise InvalidParameter("workers", args.workers, "unset with --scheduler")
    base = SimConfig(
        controller=args.controller or "pd",
        control_rate_hz=args.rate,
        plant_substeps=args.substeps,
    )
    spec = SweepSpec.parse(
        args.param,
        samples=args.samples,
        seed=args.seed,
        duration_s=args.duration,
        cycles=args.cycles,
        base=base,
    )
    executor, workers, client = None, args.workers, None
    if args.scheduler is not None:
        executor, workers, client = _dask_executor(args.scheduler)
    try:
        table = run_sweep(
            spec, args.out, executor=executor, workers=workers, plots=not args.no_plots
        )
    except SweepInterrupted as exc:
        print(
            f"exo-ctrl sweep: interrupted: {exc.done} runs finished, {exc.remaining} to do; "
            f"{len(exc.table)} rows written to {args.out} (run the same command to resume)",
            file=sys.stderr,
        )
        return 130
    finally:
        if client is not None:
            client.close()
    paths = SweepPaths.for_output(args.out)
    status = table.column("status").to_pylist()
    print(
        f"wrote {len(table)} runs ({status.count('completed')} completed) to {paths.table} "
        f"and {paths.csv}"
    )
    if paths.report.is_file():
        print(f"report: {paths.report}")
        for line in paths.report.read_text(encoding="utf-8").splitlines():
            if line.startswith("worst"):
                print("  " + line)
    return 0
