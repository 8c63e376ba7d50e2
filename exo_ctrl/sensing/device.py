"""The device's sensors sampled at a control tick, in one compiled call.

At control tick k the device samples its joint encoders and joint torque
sensors (:class:`~exo_ctrl.sensing.sensors.Sensors`) and its drives'
current sensors (:class:`~exo_ctrl.sensing.current_sensor.CurrentSensor`,
the mean winding current over the last plant step, which the safety
supervisor reads), and with instrumented cuffs their force sensors
(:class:`~exo_ctrl.sensing.cuff_load.CuffSensors`).  All see the plant as
the step just taken left it, so they are read together: :func:`read_device`
runs the sensors' kernels in turn, each on its own record and noise stream, so the readings are
exactly those of the reads made apart; one compiled call instead of two
saves a dispatch and a Python method (about 0.5 µs a tick).
"""

from __future__ import annotations

import numpy as np

from .. import _validate as v
from .._jit import Status, check, kernel
from ..exceptions import InvalidParameter
from .cuff_load import CuffSensors, read_cuffs
from .current_sensor import CurrentSensor, read_current
from .readings import SensorReadings
from .sensors import Sensors, read_joints

__all__ = ["DeviceSensors", "read_device"]


class DeviceSensors:
    """The joints' sensors and the drives' current sensors, read once per control tick.

    Args:
        joints: the joint encoders and torque sensors.
        currents: the drives' current sensors.
        mean_current_A: what the current sensors measure, the plant's mean
            winding currents over the last step, (4,) float64 [A]: the
            array itself, read at every tick.
        cuffs: the cuffs' force sensors (None, or mode ``"none"``: none; their
            read then not compiled in).
        plant_cuffs: what they measure, the plant's cuff record
            (:mod:`exo_ctrl.plant.cuffs`; with ``cuffs`` only).

    Attributes:
        readings: the joints' readings (``joints.readings``, overwritten by each read).
        current: the current sensors' reading [A], (4,) (``currents.current``, likewise).

    Raises:
        InvalidParameter: ``mean_current_A`` is not a float64 array of shape (4,).

    """

    def __init__(
        self,
        joints: Sensors,
        currents: CurrentSensor,
        mean_current_A: np.ndarray,
        cuffs: CuffSensors | None = None,
        plant_cuffs: np.ndarray | None = None,
    ) -> None:
        if not (
            type(mean_current_A) is np.ndarray
            and mean_current_A.dtype == np.float64
            and mean_current_A.shape == (4,)
        ):
            raise InvalidParameter(
                "mean_current_A", mean_current_A, "a float64 array of shape (4,) [A]"
            )
        self.joints, self.currents = joints, currents
        self.readings = joints.readings
        self.current = currents.current
        self.cuffs = cuffs if cuffs is not None and cuffs.params.on else None
        if self.cuffs is not None and plant_cuffs is None:
            raise InvalidParameter("plant_cuffs", plant_cuffs, "the plant's cuff record")
        on = self.cuffs is not None
        self._args = (
            joints.record,
            mean_current_A,
            currents.record,
            plant_cuffs if on else None,
            self.cuffs.record if self.cuffs is not None else None,
            self.cuffs.readings if self.cuffs is not None else None,
        )
        self._joints_depleted = joints.record["depleted"]
        self._currents_depleted = currents.record["depleted"]

    def read(
        self, k: int, q_true: np.ndarray, dq_true: np.ndarray, tau_true: np.ndarray
    ) -> SensorReadings:
        """The readings at tick k, as :meth:`Sensors.read`; the currents into :attr:`current`.

        Args:
            k: control tick index (t_k = k Δt); ticks must not go back in time.
            q_true: true joint angles [rad], (4,).
            dq_true: true joint speeds [rad/s], (4,).
            tau_true: true torque at the sensor (plant ``sensor_torque``) [N·m], (4,).

        Returns:
            The joints' readings (the same object every call).

        Raises:
            InvalidParameter: an input that is not 4 numbers (nothing read).

        """
        if not (type(q_true) is type(dq_true) is type(tau_true) is np.ndarray):
            q_true, dq_true, tau_true = v.arrays(
                (4,), q_true=q_true, dq_true=dq_true, tau_true=tau_true
            )
        status = read_device(k, q_true, dq_true, tau_true, *self._args)
        if status:
            check(status, "Sensors.read", q_true=q_true, dq_true=dq_true, tau_true=tau_true)
        self.refill()
        return self.readings

    def read_arguments(self) -> tuple:
        """:func:`read_device`'s arguments after the truth, for a fused tick.

        (:mod:`exo_ctrl.sim.fused`; after such a call, :meth:`refill`.)
        """
        return self._args

    def refill(self) -> None:
        """Draw the next block of noise of each sensor whose block the last read used up."""
        if self._joints_depleted[0]:
            self.joints.draw()
        if self._currents_depleted[0]:
            self.currents.draw()
        if self.cuffs is not None and self.cuffs.record["depleted"][0]:
            self.cuffs.draw()


@kernel
def read_device(
    k, q_true, dq_true, tau_true, joints, current_true, currents, cuff_truth, cuffs, cuff_out
):
    """:func:`~exo_ctrl.sensing.sensors.read_joints`, then (if it read) :func:`read_current`.

    ``joints``, ``currents``: the two sensors' records; ``current_true``:
    the mean currents (4,) [A]; ``cuffs``, ``cuff_out``: the cuff sensors'
    records, read from the plant's cuff record ``cuff_truth``
    (:func:`~exo_ctrl.sensing.cuff_load.read_cuffs`), or None (not compiled
    in).  Returns the joints' read's ``Status`` value (WRONG_LENGTH: nothing read).
    """
    status = read_joints(k, q_true, dq_true, tau_true, joints)
    if status == Status.OK.value:
        read_current(current_true, currents)
        if cuffs is not None:
            read_cuffs(k, cuff_truth, cuffs, cuff_out)
    return status
