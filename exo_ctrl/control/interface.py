"""The public controller interface: a user's controller on the same device as the built-in ones.

A controller is a subclass of :class:`Controller`.  The run builds it once
per run with what the device knows (:meth:`Controller.setup`, given a
:class:`Device`), then calls :meth:`Controller.command` at every control
tick with the time, the plan's row (:class:`PlanRow`), the sensor readings
and the estimator's cuff-force estimate.  It returns four numbers in
:data:`~exo_ctrl.model.JOINT_NAMES` order, whose meaning the class declares
in :attr:`Controller.command_kind`:

- ``"voltage"``: drive voltages [V], applied as the built-in PD's are;
- ``"torque"``: joint torques [N·m], turned into current references
  (:mod:`exo_ctrl.control.current_loop`) that the drivers' current loop
  follows (:mod:`exo_ctrl.plant.current_mode`).

Either way the command then meets what every controller meets: the supply
voltage and the driver's current limit (the plant's drives), the safety
supervisor (which may replace the voltages by its stop command), the log
(``voltage_cmd`` is the voltage the drives were asked for), the summary and
the recording.  A controller never sees the plant: only the readings.

Given as an object (``SimConfig(controller=MyController(...))``) the same
object is set up again at the start of every run that uses it; given as
``"module:Class"`` (a scenario file's ``run.controller``, ``exo-ctrl simulate
--controller mypkg.ctl:Impedance``) the class is imported and built with no
arguments when the run starts.  A run's summary and recording name the
controller by that ``module:Class`` path
(:func:`~exo_ctrl.control.plugin.controller_name`).

The built-in PD and CT are classes on this interface
(:class:`~exo_ctrl.control.builtin.PD`, :class:`~exo_ctrl.control.builtin.CT`,
:mod:`exo_ctrl.control.builtin`): subclass them to change their command
through ``super().command(...)``.

Example (a joint PD in volts, equal to the built-in ``pd``)::

    class MyPD(Controller):
        command_kind = "voltage"

        def __init__(self, kp=300.0, kd=5.0):
            self.kp, self.kd = kp, kd  # [V/rad], [V·s/rad]

        def command(self, t_s, plan, sensors, cuff_force_est_N):
            return self.kp * (plan.q - sensors.q) + self.kd * (plan.dq - sensors.dq)
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from ..model import BodyModel
from ..plan.kinematics import JointTrajectory
from ..plant.drive import MotorParams
from ..sensing.readings import SensorReadings
from .stance_load import StanceLoad

__all__ = ["COMMAND_KINDS", "Controller", "Device", "PlanRow"]

#: What :meth:`Controller.command` returns: drive voltages [V] or joint torques [N·m].
COMMAND_KINDS = ("voltage", "torque")


@dataclass(frozen=True)
class Device:
    """What the device knows, given once to :meth:`Controller.setup`.

    These are the device's beliefs (:mod:`exo_ctrl.sim.belief`), the models
    the built-in controllers, the estimator and the supervisor hold; never
    the plant's truth unless the run asks for it (``belief``).

    Attributes:
        exo: the device's exoskeleton model (``exo.model`` is a Pinocchio
            model; ``exo.q_index`` its q indices in JOINT_NAMES order).
        patient: the device's nominal patient model, likewise.
        plan: the joint plan (``plan.q``, ``plan.dq``, ``plan.ddq`` [rad,
            rad/s, rad/s²]; ``plan.row(k)`` the row of tick k).  The
            synchronised plan of a run with the belt is one row, rewritten
            each tick: read it through :class:`PlanRow`.
        motor: the drive's datasheet (``supply_voltage_V``,
            ``current_limit_A``, ``torque_per_amp_Nm_per_A``, ...).
        dt_s: the control period Δt [s].
        stance_load: what the device knows of the weight its stance legs
            carry with the pelvis on its guide (moving mass [kg], support
            [N], gravity [m/s²]; :mod:`exo_ctrl.control.stance_load`); None:
            the pelvis fixed, no load.
        lift_off_blend_s: T_b, the time over which the built-in CT blends in
            the swing leg's planned acceleration after lift-off [s]
            (:mod:`exo_ctrl.control.lift_off`; 0 without the belt).

    """

    exo: BodyModel
    patient: BodyModel
    plan: JointTrajectory
    motor: MotorParams
    dt_s: float
    stance_load: StanceLoad | None = None
    lift_off_blend_s: float = 0.0


@dataclass
class PlanRow:
    """The plan's row of one control tick, (4,) each in JOINT_NAMES order.

    The arrays are overwritten at every tick: copy them to keep them.

    Attributes:
        q: planned joint angles q* [rad].
        dq: planned joint speeds q̇* [rad/s].
        ddq: planned joint accelerations q̈* [rad/s²].
        row: the plan row they come from.

    """

    q: np.ndarray = field(default_factory=lambda: np.zeros(4))
    dq: np.ndarray = field(default_factory=lambda: np.zeros(4))
    ddq: np.ndarray = field(default_factory=lambda: np.zeros(4))
    row: int = 0


class Controller(abc.ABC):
    """A user's controller: the plan, sensors and cuff-force estimate in, a command out.

    Subclasses implement :meth:`command` and may override :meth:`setup`
    (module docstring).

    Attributes:
        command_kind: what :meth:`command` returns, one of
            :data:`COMMAND_KINDS` (class attribute; default ``"voltage"``).

    """

    command_kind: ClassVar[str] = "voltage"

    def setup(self, device: Device) -> None:  # noqa: B027 - a hook, empty by default
        """Called once at the start of every run, before the first tick.

        Build what the ticks need here (Pinocchio data, buffers) and reset
        any state a previous run left.  The default does nothing.

        Args:
            device: what the device knows (:class:`Device`).

        """

    @abc.abstractmethod
    def command(
        self,
        t_s: float,
        plan: PlanRow,
        sensors: SensorReadings,
        cuff_force_est_N: np.ndarray,
    ) -> ArrayLike:
        """The command of one control tick.

        Args:
            t_s: the tick's time t_k = k Δt [s].
            plan: the plan's row for the tick (q*, q̇*, q̈*).
            sensors: the readings: ``q`` [rad], ``dq`` [rad/s], ``tau``
                (the joint torque sensors) [N·m], ``belt_speed`` [m/s] with
                the belt; arrays overwritten each tick.
            cuff_force_est_N: the estimator's cuff forces on the
                exoskeleton, (4, 2) [N]: (x, z) per cuff in
                :data:`~exo_ctrl.model.CUFF_NAMES` order; overwritten each tick.

        Returns:
            Four finite numbers, in JOINT_NAMES order: drive voltages [V]
            or joint torques [N·m] (:attr:`command_kind`).  Any other shape,
            or a NaN or infinity, stops the run with a
            :class:`~exo_ctrl.exceptions.PluginError` naming the tick.

        """
