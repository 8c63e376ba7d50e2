"""What a sweep runs: its points, each resolved to a full run with a stable id.

**Points.**  Without ``samples`` the points are the cartesian product of the
parameters' value lists, the first parameter varying slowest, each list in
the order given.  With ``samples = N`` they are N random points, each
numeric parameter uniform in [min, max] of its listed values (a single
value stays constant; explicit lists only set the bounds) and
``controller`` uniform over its listed values.  The draws come from
``numpy.random.default_rng(seed)`` one point at a time, one draw per
parameter in the order given, so the points depend only on the seed and a
larger N extends a smaller one.

**Run id.**  Each point resolves to a full run description (every gait,
patient and device value, including the ones not swept, the controller,
gains, motor and cuff constants, duration and rates); its id is the first
16 hex digits of the SHA-256 of that description as canonical JSON.  Equal
runs get equal ids across sweeps, whatever else is swept.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..control import controller_name
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES
from ..sim import SimConfig
from .parameters import (
    MAX_RUNS,
    PARAMETERS,
    check_controller,
    check_value,
    parameter_names,
    parse_param,
    point_label,
    round_12,
    unique,
    unit_suffix,
    value_in,
)

__all__ = [
    "DEFAULT_CYCLES",
    "SweepSpec",
    "SweepTask",
    "base_values",
    "resolved_run",
    "run_id_of",
]

#: Gait cycles simulated when neither a duration nor a number of cycles is given.
DEFAULT_CYCLES = 2.0


@dataclass(frozen=True)
class SweepTask:
    """One run of a sweep.

    Attributes:
        index: position in the sweep's point order (0-based).
        run_id: stable hash of the resolved run (see the module docstring).
        point: the swept parameters' values of this run.
        values: every sweepable parameter's value for this run (swept or
            from the base; PD gains only when swept), plus ``duration_s`` [s] (input of
            :func:`~exo_ctrl.sweep.run.run_point`).
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
        return point_label(self.point)


@dataclass(frozen=True)
class SweepSpec:
    """What to sweep: parameters and their values, grid or random samples.

    Attributes:
        params: ``(name, values)`` pairs, in the order given (see
            :func:`~exo_ctrl.sweep.parameters.parse_param`); names must be distinct.
        samples: None for the full grid, else the number of random points.
        seed: seed of the random points [-] (integer >= 0).
        duration_s: simulated time per run [s]; exclusive with ``cycles``.
        cycles: gait cycles at full speed per run (duration = the ramp-in +
            cycles × the run's period + the ramp-out);
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
                vals = unique([check_controller(x) for x in values])
            else:
                vals = unique([check_value(PARAMETERS[name], x) for x in values])
            checked.append((name, vals))
        object.__setattr__(self, "params", tuple(checked))
        self._check_run_fields(seen)

    def _check_run_fields(self, names: set[str]) -> None:
        if self.samples is not None and (
            isinstance(self.samples, bool) or not isinstance(self.samples, int) or self.samples < 1
        ):
            raise InvalidParameter("samples", self.samples, "an integer >= 1")
        if self.samples is not None and self.samples > MAX_RUNS:
            raise InvalidParameter("samples", self.samples, f"at most {MAX_RUNS:,}")
        if self.samples is None:
            grid = math.prod(len(vals) for _, vals in self.params)
            if grid > MAX_RUNS:
                raise InvalidParameter(
                    "sweep parameters",
                    " × ".join(f"{len(vals)} {name}" for name, vals in self.params),
                    f"a grid of at most {MAX_RUNS:,} runs",
                    f"this one has {grid:,}; --samples N draws N points instead",
                )
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InvalidParameter("seed", self.seed, "an integer >= 0")
        if self.duration_s is not None and self.cycles is not None:
            raise InvalidParameter("cycles", self.cycles, "unset when a duration is given")
        for name, value, unit in (("duration", self.duration_s, "s"), ("cycles", self.cycles, "")):
            if value is not None and not (
                isinstance(value, (int, float)) and math.isfinite(value) and value > 0
            ):
                raise InvalidParameter(name, value, f"a finite number > 0{unit_suffix(unit)}")
        for body in ("patient", "exo"):
            swept = sorted(n for n in names if n in PARAMETERS and PARAMETERS[n].target == body)
            if swept and getattr(self.base, body) is not None:
                raise InvalidParameter(
                    swept[0],
                    getattr(self.base, body),
                    f"swept only with the generated {body} (no {body} URDF given)",
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
        """Build a spec from ``--param`` texts (see :func:`~exo_ctrl.sweep.parse_param`)."""
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
                    point[name] = round_12(lo + u * (hi - lo))
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
            name → value for every parameter of
            :func:`~exo_ctrl.sweep.parameters.parameter_names` (the patient
            ones only when ``base.patient`` is None, the PD gains only when
            swept), plus ``duration_s`` [s]
            (the base's ramp-in, one period of the run's gait unless set,
            ``cycles`` × the run's period at full speed and the base's
            ramp-out, rounded to 12 significant digits, when no duration is
            given: as ``exo-ctrl simulate --cycles``).  Values are not cross-checked here
            (e.g. lift vs hip height): the worker builds the run and records a
            rejected one as ``failed``.

        """
        values = base_values(self.base)
        values.update(point)
        if self.duration_s is not None:
            values["duration_s"] = float(self.duration_s)
        else:
            cycles = self.cycles if self.cycles is not None else DEFAULT_CYCLES
            period = float(values["period"])
            ramp_in = self.base.ramp_in_s if self.base.ramp_in_s is not None else period
            values["duration_s"] = round_12(ramp_in + cycles * period + self.base.ramp_out_s)
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


def base_values(base: SimConfig) -> dict[str, Any]:
    """The value of every sweepable parameter in ``base`` (patient: the generated default).

    Left out: the patient (exoskeleton) parameters when ``base`` names a
    patient (exoskeleton) URDF, and
    the PD gains (the base's gains, per joint, are in the run as they are;
    a swept gain comes with the point).
    """
    values: dict[str, Any] = {}
    for name, info in PARAMETERS.items():
        value = value_in(info, base)
        if value is not None and info.target != "gains":
            values[name] = value
    values["controller"] = controller_name(base.controller)  # plain data: a user's by its name
    return values


def resolved_run(base: SimConfig, values: dict[str, Any]) -> dict[str, Any]:
    """The run as plain data: ``base.to_dict()`` with ``values`` applied.

    The patient and exoskeleton parameters, when swept, appear as
    ``patient_body`` and ``exo_body`` (the generated URDF's path depends on
    where the sweep writes; its content does not).  A swept PD gain is stored per joint, as
    :class:`~exo_ctrl.control.PDGains` holds it, so sweeping the base's
    value is the same run as not sweeping it.
    """
    run = base.to_dict()
    run["patient_body"] = None
    if any(PARAMETERS[n].target == "exo" for n in values if n in PARAMETERS):
        run["exo_body"] = None  # only then: the ids of sweeps without it stay as they were
    for name, value in values.items():
        info = PARAMETERS.get(name)
        if info is None:  # controller, duration_s
            run[name] = value
        elif info.target in ("patient", "exo"):
            key = f"{info.target}_body"
            run[key] = run[key] or {}
            run[key][info.attribute] = value
        elif info.target == "gains":
            per_joint = value if isinstance(value, tuple) else (float(value),) * len(JOINT_NAMES)
            run["gains"][info.attribute] = per_joint
        else:
            run[info.target][info.attribute] = value
    return run


def run_id_of(run: dict[str, Any]) -> str:
    """Stable id of a resolved run: 16 hex digits of SHA-256 of its canonical JSON."""
    text = json.dumps(run, sort_keys=True, separators=(",", ":"), allow_nan=False, default=repr)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]
