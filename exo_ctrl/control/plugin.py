"""A user's controller in the run: its name, its import and the tick's adapter.

A run's ``controller`` is a built-in name (``"pd"``, ``"ct"``, ``"qp"``,
whose compiled controllers the run builds), a
:class:`~exo_ctrl.control.interface.Controller` object, or the import path
``"module:Class"`` of a Controller subclass built with no arguments.  An
object of exactly :class:`~exo_ctrl.control.builtin.PD` or
:class:`~exo_ctrl.control.builtin.CT` is not a user's: it runs, and is
named, as its built-in name (:mod:`exo_ctrl.control.builtin`).
:func:`check_controller` judges the value when the configuration is made
(an object's type and command kind; a path's form only, so that a
recording of a user's run can be read where the user's code is not
installed); :func:`load_controller` imports a path when the run is built.

:class:`PluginController` puts the user's controller on the tick's internal
interface (:class:`~exo_ctrl.control.base.TickController`): it fills the
plan's row, calls :meth:`~exo_ctrl.control.interface.Controller.command`
with the time, the readings and the cuff-force estimate, checks what comes
back (four finite numbers, else :class:`~exo_ctrl.exceptions.PluginError`
naming the tick) and, for torque commands, turns them into the drivers'
current references (:mod:`exo_ctrl.control.current_loop`), written into the
drives' current-mode inputs the run binds (:meth:`PluginController.bind_driver`);
the command it passes on is then their feedforward voltage.  The voltages then
go the way every controller's go: the supervisor, the drives, the log.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import kernel, record
from .._plugin import is_path, load_plugin, plugin_name
from ..exceptions import InvalidParameter, PluginError
from ..plan.rows import plan_row
from ..sensing.readings import SensorReadings
from .base import COMMAND_FIELDS, CommandCounters, PDGains
from .builtin import BUILT_IN_CLASSES, built_in, built_in_name
from .current_loop import current_reference, reference_params
from .interface import COMMAND_KINDS, Controller, Device, PlanRow

__all__ = [
    "ALLOWED",
    "PLUGIN_FIELDS",
    "PluginController",
    "check_controller",
    "controller_name",
    "fill_row",
    "finite_copy",
    "is_plugin",
    "load_controller",
]

#: What ``controller`` may be, in words (the messages of :func:`check_controller`).
ALLOWED = (
    "pd, ct, qp, the import path 'module:Class' of an exo_ctrl.control.Controller "
    "subclass, or such a Controller object"
)

#: A user controller's part of its record (after :data:`~exo_ctrl.control.base.COMMAND_FIELDS`):
#: its last command as returned (``command``: [V] or [N·m]) and, for torque
#: commands, the drivers' current references (``current_ref`` [A]; 0 for voltages).
PLUGIN_FIELDS: list[tuple[Any, ...]] = [
    ("command", np.float64, (4,)),
    ("current_ref", np.float64, (4,)),
]


def controller_name(controller: str | Controller) -> str:
    """The name a summary and a recording give a run's controller.

    A built-in name or an import path as given; an object of exactly
    :class:`~exo_ctrl.control.builtin.PD` or ``CT``: its built-in name
    (``"pd"``, ``"ct"``); any other object: its class's
    ``module:QualifiedName``.
    """
    return built_in_name(controller) or plugin_name(controller)


def is_plugin(controller: str | Controller, built_in: tuple[str, ...]) -> bool:
    """Whether a run's ``controller`` is a user's: no ``built_in`` name, PD or CT object."""
    return controller_name(controller) not in built_in


def check_controller(controller: object, built_in: tuple[str, ...]) -> None:
    """Refuse a ``controller`` that is not a built-in name, an import path or a Controller.

    Raises:
        InvalidParameter: naming what is wrong (module docstring).

    """
    if isinstance(controller, str):
        if controller in built_in or is_path(controller):
            return
        if ":" not in controller:  # a misspelt built-in name, as before user controllers
            v.one_of("controller", controller, built_in)
        detail = "an import path is 'package.module:Class'"
        raise InvalidParameter("controller", controller, ALLOWED, detail)
    if isinstance(controller, Controller):
        _check_kind(type(controller))
        return
    if isinstance(controller, type):
        detail = f"{controller.__name__} is a class: give an object, {controller.__name__}()"
        if not issubclass(controller, Controller):
            detail = f"{controller.__name__} is not a subclass of exo_ctrl.control.Controller"
    elif callable(getattr(controller, "command", None)):  # a controller not on the interface
        name = type(controller).__name__
        detail = f"{name} is not a subclass of exo_ctrl.control.Controller"
    else:  # neither a name nor a controller: the built-in names, as before user controllers
        v.one_of("controller", controller, built_in)
        detail = ""
    raise InvalidParameter("controller", controller, ALLOWED, detail)


def load_controller(controller: str | Controller, gains: PDGains | None = None) -> Controller:
    """The controller object of a run: the object itself, or the name's or the path's class built.

    A built-in name with a class (:data:`~exo_ctrl.control.builtin.BUILT_IN_CLASSES`:
    ``"pd"``, ``"ct"``) gives that class with ``gains`` (None: the defaults).

    Raises:
        InvalidParameter: the module cannot be imported, has no such class,
            the class is not a Controller subclass or leaves an abstract
            method unimplemented, cannot be built with no arguments, or its
            ``command_kind`` is not one of :data:`COMMAND_KINDS`
            (:func:`exo_ctrl._plugin.load_plugin`).

    """
    if isinstance(controller, Controller):
        return controller
    if controller in BUILT_IN_CLASSES:
        return built_in(controller, gains or PDGains())
    user = load_plugin(controller, Controller, "controller", ALLOWED)
    _check_kind(type(user))
    return user


def _check_kind(cls: type) -> None:
    """Refuse a Controller class whose ``command_kind`` is not one of :data:`COMMAND_KINDS`."""
    kind = getattr(cls, "command_kind", None)
    if kind not in COMMAND_KINDS:
        allowed = " or ".join(repr(k) for k in COMMAND_KINDS)
        name = f"{cls.__module__}:{cls.__qualname__}"
        raise InvalidParameter(f"command_kind of {name}", kind, allowed)


class PluginController(CommandCounters):
    """A user's :class:`~exo_ctrl.control.interface.Controller` on the tick's interface.

    Built at the start of a run: calls the user's
    :meth:`~exo_ctrl.control.interface.Controller.setup` with ``device``.

    Args:
        user: the user's controller.
        device: what the device knows (its plan is the run's).

    Attributes:
        name: the controller's ``module:Class`` (:func:`controller_name`).
        kind: ``"voltage"`` or ``"torque"``.
        record: :data:`~exo_ctrl.control.base.COMMAND_FIELDS` and :data:`PLUGIN_FIELDS`.
        driver: the datasheet the drivers turn torques into currents with
            (:func:`~exo_ctrl.control.current_loop.reference_params`; None for voltages).

    """

    def __init__(self, user: Controller, device: Device) -> None:
        self.user = user
        self.name = controller_name(user)
        self.kind = type(user).command_kind
        self.plan = device.plan
        self._dt = device.dt_s
        self.record = record(COMMAND_FIELDS + PLUGIN_FIELDS)
        self._u = self.record["u_cmd"][0]
        self._command = self.record["command"][0]
        self._current_ref = self.record["current_ref"][0]
        self._row = PlanRow()
        self._rule = device.plan.row_rule
        self._no_estimate = np.zeros((4, 2))
        self.driver: np.ndarray | None = None
        self._i_ref, self._u_ff = np.zeros(4), np.zeros(4)
        if self.kind == "torque":
            self.driver = reference_params(device.motor)
        user.setup(device)

    def bind_driver(self, current_ref_A: np.ndarray, u_ff_V: np.ndarray) -> None:
        """Write the current references into the drives' ``current_ref_A``, (4,) [A].

        And their feedforward voltages into ``u_ff_V``, (4,) [V]: the drives'
        :attr:`~exo_ctrl.plant.motor.MotorBank.current_command`.
        """
        self._i_ref, self._u_ff = current_ref_A, u_ff_V

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """The voltages of tick k [V], (4,): the user's command, or its current references' U_ff.

        Raises:
            PluginError: the user's command is not four finite numbers.
            InvalidParameter: a tick beyond the plan.

        """
        plan, row = self.plan, self._row
        r = fill_row(k, *self._rule, plan.q, plan.dq, plan.ddq, row.q, row.dq, row.ddq)
        if r < 0:
            raise InvalidParameter("k", k, f"a control tick on the plan's {plan.q.shape[0]} rows")
        row.row = r
        t = k * self._dt
        est = sensors.cuff_force_est
        out = self.user.command(t, row, sensors, self._no_estimate if est is None else est)
        self._accept(out, k, t)
        driver = self.driver
        if driver is None:
            self._u[:] = self._command
        else:
            current_reference(driver, self._command, sensors.dq, self._i_ref, self._u, self._u_ff)
            self._current_ref[:] = self._i_ref
        return self._u

    def _accept(self, out: object, k: int, t: float) -> None:
        """Copy the user's command into the record's ``command`` if it is 4 finite floats.

        Raises:
            PluginError: naming the tick, what came back and what is allowed.

        """
        what = "4 drive voltages [V]" if self.kind == "voltage" else "4 joint torques [N·m]"
        try:
            cmd = np.asarray(out, dtype=np.float64)
        except (TypeError, ValueError):
            raise PluginError(self.name, k, t, f"command must return {what}; got {out!r}") from None
        if cmd.shape != (4,):
            raise PluginError(self.name, k, t, f"command must return {what}; got shape {cmd.shape}")
        if not finite_copy(cmd, self._command):
            raise PluginError(
                self.name, k, t, f"command must return finite numbers; got {cmd.tolist()}"
            )


@kernel
def fill_row(k, lead, period, tail, q, dq, ddq, out_q, out_dq, out_ddq):  # pragma: no cover
    """Copy the plan's row of tick k (:func:`~exo_ctrl.plan.rows.plan_row`) into ``out_*``.

    Returns the row, or -1 (nothing copied) for a tick beyond the plan's rows.
    """
    row = plan_row(k, lead, period, tail)
    if row < 0 or row >= q.shape[0]:
        return -1
    for j in range(4):
        out_q[j] = q[row, j]
        out_dq[j] = dq[row, j]
        out_ddq[j] = ddq[row, j]
    return row


@kernel
def finite_copy(cmd, out):  # pragma: no cover - compiled
    """Copy the 4 numbers of ``cmd`` into ``out`` if all are finite; whether they were."""
    for j in range(4):
        if not math.isfinite(cmd[j]):
            return False
    for j in range(4):
        out[j] = cmd[j]
    return True
