"""The built-in PD and CT as public :class:`~exo_ctrl.control.interface.Controller` classes.

:class:`PD` is the paper's PD voltage law, :class:`CT` the same law plus the
computed-torque feedforward voltage (:mod:`exo_ctrl.control.computed_torque`).
Both take their gains when built (:class:`~exo_ctrl.control.base.PDGains`
checks them) and compute their command with the built-in compiled law
(:func:`~exo_ctrl.control.pd.pd_law`).

The built-in names stand for these classes: ``SimConfig(controller="pd")``
runs ``PD`` with the configuration's ``gains``, ``"ct"`` runs ``CT``.  An
object whose type is exactly :class:`PD` or :class:`CT` runs as its name
does, with its own gains: the run builds the compiled tick controller of
:meth:`PD.compiled` (:class:`~exo_ctrl.control.pd.PDController`,
:class:`~exo_ctrl.control.computed_torque.ComputedTorqueController`), so
``SimConfig(controller=PD())`` and ``SimConfig(controller="pd")`` run the
same compiled tick.  A subclass is a user's controller: it runs through
the Python adapter (:class:`~exo_ctrl.control.plugin.PluginController`),
and its ``super().command(...)`` is the built-in law on the tick's plan row
and readings.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from .._jit import Status
from ..exceptions import InvalidParameter
from ..sensing.readings import SensorReadings
from .base import PDGains
from .computed_torque import ComputedTorqueController, Feedforward
from .interface import Controller, Device, PlanRow
from .pd import PDController, pd_law

__all__ = ["BUILT_IN_CLASSES", "CT", "PD", "built_in", "built_in_name", "compiled_type"]

#: The plan-row rule of a single row (:func:`~exo_ctrl.plan.rows.plan_row`: lead, period, tail).
_ONE_ROW = (0, 0, 0)


class PD(Controller):
    """The paper's PD voltage law U = k_p (q* - q) + k_d (q̇* - q̇) per drive [V].

    Args:
        kp: proportional gain k_p [V/rad]: one number for every joint or
            four in JOINT_NAMES order, each > 0 (default 300).
        kd: derivative gain k_d [V·s/rad]: one number or four, each >= 0
            (default 5).

    Attributes:
        gains: the gains (:class:`~exo_ctrl.control.base.PDGains`).

    Raises:
        InvalidParameter: a gain that is not one number or four, an item
            that is text, a bool or not finite, kp <= 0 or kd < 0 (the
            message names the gain, the value and what is allowed).

    """

    command_kind: ClassVar[str] = "voltage"
    #: The built-in name this class stands for (``SimConfig(controller="pd")``).
    name: ClassVar[str] = "pd"

    def __init__(
        self, kp: float | tuple[float, ...] = 300.0, kd: float | tuple[float, ...] = 5.0
    ) -> None:
        self.gains = PDGains(kp, kd)
        self._kp = np.array(self.gains.kp, dtype=np.float64)
        self._kd = np.array(self.gains.kd, dtype=np.float64)
        self._u = np.zeros(4)
        #: The feedforward voltage of the tick's row [V], (1, 4): zero for the PD.
        self._u_ff = np.zeros((1, 4))

    @classmethod
    def from_gains(cls, gains: PDGains) -> PD:
        """The controller with ``gains`` (the run's ``SimConfig.gains`` for a built-in name)."""
        return cls(gains.kp, gains.kd)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(kp={self.gains.kp!r}, kd={self.gains.kd!r})"

    def compiled(self, device: Device) -> PDController:
        """The compiled tick controller of this law and gains on ``device`` (what "pd" runs)."""
        return PDController(device.plan, self.gains)

    def command(
        self,
        t_s: float,
        plan: PlanRow,
        sensors: SensorReadings,
        cuff_force_est_N: np.ndarray,
    ) -> np.ndarray:
        """k_p (q* - q) + k_d (q̇* - q̇) + U_ff [V], (4,): a buffer overwritten each tick.

        U_ff is zero for the PD and the feedforward voltage of the plan's row
        for the CT.  The arithmetic is the built-in compiled law's
        (:func:`~exo_ctrl.control.pd.pd_law`).

        Raises:
            InvalidParameter: readings that are not 4 joint values.

        """
        q_des, dq_des = plan.q.reshape(1, 4), plan.dq.reshape(1, 4)
        q, dq = sensors.q, sensors.dq
        kp, kd, u = self._kp, self._kd, self._u
        status, _ = pd_law(kp, kd, *_ONE_ROW, q_des, dq_des, self._u_ff, 0, q, dq, u)
        if status != Status.OK.value:
            shapes = (np.shape(sensors.q), np.shape(sensors.dq))
            raise InvalidParameter("sensors q and dq shapes", shapes, "(4,) each")
        return self._u


class CT(PD):
    """PD plus the computed-torque feedforward voltage U_ff of the plan's row [V].

    U_ff is :mod:`exo_ctrl.control.computed_torque`'s: the drive voltage
    the planned motion needs on the device's exoskeleton and nominal
    patient (``device.exo``, ``device.patient``, ``device.motor``), with
    the stance legs' load (``device.stance_load``) and the swing leg's
    lift-off blend (``device.lift_off_blend_s``).

    Args:
        kp: proportional gain k_p [V/rad], as :class:`PD`'s.
        kd: derivative gain k_d [V·s/rad], as :class:`PD`'s.

    Raises:
        InvalidParameter: as :class:`PD`.

    """

    name: ClassVar[str] = "ct"

    def __init__(
        self, kp: float | tuple[float, ...] = 300.0, kd: float | tuple[float, ...] = 5.0
    ) -> None:
        super().__init__(kp, kd)
        self._ff: Feedforward | None = None
        self._lift: np.ndarray | None = None
        self._tau_ff = np.zeros(4)

    def compiled(self, device: Device) -> ComputedTorqueController:
        """The compiled tick controller of this law and gains on ``device`` (what "ct" runs)."""
        return ComputedTorqueController(
            device.plan,
            device.exo,
            device.patient,
            device.motor,
            self.gains,
            stance_load=device.stance_load,
            lift_off_blend_s=device.lift_off_blend_s,
        )

    def setup(self, device: Device) -> None:
        """Build the feedforward's models and buffers on what the device knows."""
        self._ff = Feedforward(
            device.exo, device.patient, device.motor, device.stance_load, device.lift_off_blend_s
        )
        self._lift = device.plan.lift_off_s

    def command(
        self,
        t_s: float,
        plan: PlanRow,
        sensors: SensorReadings,
        cuff_force_est_N: np.ndarray,
    ) -> np.ndarray:
        """The PD voltage plus U_ff of the plan's row [V], (4,): a buffer overwritten each tick.

        U_ff is computed from the row as the compiled CT tabulates it (two
        RNEA calls and one kernel).

        Raises:
            InvalidParameter: called before :meth:`setup`, or readings
                that are not 4 joint values.

        """
        ff = self._ff
        if ff is None:
            raise InvalidParameter("CT.command", "called before setup", "after setup(device)")
        lift = None if self._lift is None else self._lift[plan.row]
        ff.row(plan.q, plan.dq, plan.ddq, self._tau_ff, self._u_ff[0], lift)
        return super().command(t_s, plan, sensors, cuff_force_est_N)


#: The classes the built-in names stand for.
BUILT_IN_CLASSES: dict[str, type[PD]] = {"pd": PD, "ct": CT}


def compiled_type(controller: object) -> bool:
    """Whether ``controller`` is exactly a :class:`PD` or :class:`CT` (the compiled path)."""
    return type(controller) in BUILT_IN_CLASSES.values()


def built_in_name(controller: object) -> str | None:
    """The built-in name (``"pd"``, ``"ct"``) of an exact PD or CT object, else None."""
    return type(controller).name if compiled_type(controller) else None  # type: ignore[attr-defined]


def built_in(name: str, gains: PDGains) -> PD:
    """The object a built-in name stands for, with the run's ``gains`` (``"pd"``: ``PD``)."""
    return BUILT_IN_CLASSES[name].from_gains(gains)
