"""Compare controllers on one scenario: one run each, a table of their summaries' figures.

:func:`compare` runs the scenario once per controller, each run keeping no
history (``keep_history`` off) but the one gait cycle the figure draws
(:class:`~.cycle.CycleKeeper`), and returns a
:class:`~.table.CompareTable` whose figures are the runs' own summaries'.
Recordings are compared by :func:`exo_ctrl.comparison.recordings.compare_recordings`.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from .. import _validate as v
from ..control import Controller, controller_name
from ..control.plugin import check_controller
from ..exceptions import InvalidParameter, Terminated
from ..scenario import Scenario, load_scenario
from ..sim import CONTROLLERS, SimConfig, simulate
from ..sim.config import MAX_DURATION_S
from .cycle import CycleKeeper
from .differences import check_same, config_differences
from .table import CompareRow, CompareTable, row_from

__all__ = ["compare", "controller_list", "run_config"]

#: Called after each run: (run number from 1, number of runs, its row).
RunNotice = Callable[[int, int, CompareRow], None]


def _base_config(scenario: Any) -> SimConfig:
    """The scenario's configuration: the one place a scenario is turned into a SimConfig.

    A :class:`~exo_ctrl.sim.SimConfig`, a :class:`~exo_ctrl.scenario.Scenario`
    or a scenario file's path (read by :func:`~exo_ctrl.scenario.load_scenario`).

    Raises:
        InvalidParameter: ``scenario`` is none of these.
        InvalidScenario: the file cannot be read or is not a valid scenario.

    """
    if isinstance(scenario, SimConfig):
        return scenario
    if isinstance(scenario, Scenario):
        return scenario.config
    if isinstance(scenario, (str, os.PathLike)):
        return load_scenario(scenario).config
    raise InvalidParameter(
        "scenario", scenario, "a SimConfig, a Scenario or a scenario file's path"
    )


def controller_list(controllers: Any) -> tuple[tuple[str, str | Controller], ...]:
    """The controllers to compare, each with its row's label, at least one.

    ``controllers`` is ``"pd,ct,qp"``, a sequence, or a mapping label →
    controller.  Each controller is a built-in name, a user's ``module:Class``
    path or a :class:`~exo_ctrl.control.Controller` object (in a sequence
    or a mapping).  In a string or a sequence a controller's label is its
    name (:func:`~exo_ctrl.control.controller_name`), so two with one name
    (``PD(kp=200)`` and ``"pd"``) are one twice; a mapping labels them
    itself (``{"soft": PD(kp=200), "stiff": PD(kp=600)}``).

    Raises:
        InvalidParameter: ``controllers`` empty, naming an unknown controller
            or one twice, or a label that is not non-empty text.

    """
    allowed = f"one or more of {', '.join(CONTROLLERS)}, each once"
    if isinstance(controllers, Mapping):
        pairs = tuple(controllers.items())
        for label, _ in pairs:
            if not isinstance(label, str) or not label.strip():
                raise InvalidParameter(
                    "controllers",
                    controllers,
                    "a mapping of labels (non-empty text) to controllers",
                    f"label {label!r}",
                )
    else:
        if isinstance(controllers, str):
            chosen = tuple(c.strip() for c in controllers.split(","))
        else:
            try:
                chosen = tuple(controllers)
            except TypeError:
                raise InvalidParameter("controllers", controllers, allowed) from None
        pairs = tuple(
            (controller_name(c) if isinstance(c, (str, Controller)) else repr(c), c) for c in chosen
        )
    labels = [label for label, _ in pairs]
    if not pairs or len(set(labels)) != len(labels):
        raise InvalidParameter("controllers", controllers, allowed)
    for _, controller in pairs:
        try:
            check_controller(controller, CONTROLLERS)
        except InvalidParameter:
            raise InvalidParameter(
                "controllers", controllers, allowed, f"{controller!r} is not one"
            ) from None
    return pairs


def run_config(
    scenario: Any, cycles: float | None = None, duration_s: float | None = None
) -> SimConfig:
    """The scenario's configuration with the run's length set.

    Args:
        scenario: the scenario (:func:`_base_config`).
        cycles: gait cycles at full speed after the ramp-in and before the
            ramp-out (the duration is ramp-in + cycles T_s + ramp-out, as
            ``exo-ctrl simulate --cycles``); None: the scenario's duration.
        duration_s: the whole run [s], ramps included; None: the scenario's.

    Raises:
        InvalidParameter: both given, or either out of range.

    """
    base = _base_config(scenario)
    if cycles is not None and duration_s is not None:
        raise InvalidParameter("cycles", cycles, "not given with duration", "give one of the two")
    if duration_s is not None:
        return dataclasses.replace(base, duration_s=duration_s)
    if cycles is None:
        return base
    cycles = v.positive("cycles", cycles)
    lead = base.gait.period if base.ramp_in_s is None else base.ramp_in_s
    duration = lead + cycles * base.gait.period + base.ramp_out_s
    if duration > MAX_DURATION_S:
        most = (MAX_DURATION_S - lead - base.ramp_out_s) / base.gait.period
        raise InvalidParameter("cycles", cycles, f"at most {most:.6g}")
    return dataclasses.replace(base, duration_s=duration)


def compare(
    scenario: Any,
    controllers: str | Sequence[str | Controller] | Mapping[str, str | Controller] = CONTROLLERS,
    *,
    cycles: float | None = None,
    duration_s: float | None = None,
    allow_different: bool = False,
    on_run: RunNotice | None = None,
    progress: bool = False,
    warmup: bool = False,
) -> CompareTable:
    """Run the scenario once per controller and tabulate the runs' summaries.

    Args:
        scenario: the scenario, a :class:`~exo_ctrl.sim.SimConfig`, a
            :class:`~exo_ctrl.scenario.Scenario` or a scenario file's path
            (its controller is replaced by each of ``controllers``).
        controllers: the controllers, in the table's order (``("pd", "ct")``
            or ``"pd,ct"``; a user's as ``"module:Class"`` or a
            :class:`~exo_ctrl.control.Controller` object); each row is
            labelled by its controller's name, or by its key in a mapping
            label → controller (two tunings of one controller:
            ``{"soft": PD(kp=200), "stiff": PD(kp=600)}``).
        cycles: gait cycles at full speed (:func:`run_config`); None: the scenario's duration.
        duration_s: the whole run [s]; None: the scenario's.
        allow_different: compare runs whose configurations differ beyond
            the controller (they cannot here; the check is the one
            recordings pass, :func:`~.differences.check_same`).
        on_run: called after each run with (its number from 1, the number
            of runs, its row): the command line's progress line.
        progress: draw each run's progress bar on stderr.
        warmup: compile the kernels in two processes on a first run
            (:func:`exo_ctrl.sim.simulate`'s; the command line's choice).

    Returns:
        The table, one row per controller (figures: :data:`~.table.FIGURES`,
        each equal to the run's :meth:`~exo_ctrl.sim.SimResult.summary`).
        A run that diverges keeps its row (status ``"diverged"``).

    Raises:
        InvalidParameter: a bad scenario, controller list or run length.
        KeyboardInterrupt: a run was interrupted (Ctrl-C; :class:`Terminated`
            for SIGTERM); the runs after it are not started.

    """
    chosen = controller_list(controllers)
    names = [label for label, _ in chosen]
    base = run_config(scenario, cycles, duration_s)
    configs = [dataclasses.replace(base, controller=c) for _, c in chosen]
    differences = config_differences([c.to_dict() for c in configs])
    check_same(differences, names, v.flag("allow_different", allow_different))
    rows: list[CompareRow] = []
    for i, (name, config) in enumerate(zip(names, configs, strict=True)):
        keeper = CycleKeeper()
        result = simulate(
            config, observers=[keeper], progress=progress, keep_history=False, warmup=warmup
        )
        row = row_from(name, result.summary(), config.to_dict(), "simulated", keeper.trace())
        rows.append(row)
        if on_run is not None:
            on_run(i + 1, len(names), row)
        if result.status == "interrupted":
            if result.error.startswith("terminated by SIGTERM"):
                raise Terminated("SIGTERM")
            raise KeyboardInterrupt(result.error)
    return CompareTable(rows, differences)
