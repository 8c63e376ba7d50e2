"""The public estimator interface: a user's cuff-force estimate in place of the built-in ones.

An estimator is a subclass of :class:`Estimator`.  The run builds it once per
run with what the device knows (:meth:`Estimator.setup`, given an
:class:`EstimatorDevice`), then calls :meth:`Estimator.estimate` at every
control tick, before the controller, with the time and the sensor
readings.  It returns the four cuff forces on the exoskeleton, (4, 2) [N],
(x, z) per cuff in :data:`~exo_ctrl.model.CUFF_NAMES` order.  The run uses
them where it uses the built-in estimate: the controllers see them
(``sensors.cuff_force_est``; the QP rebuilds its cuff state from them), the
safety supervisor checks them against its cuff-force limits, the patient-load
monitor reads the external joint torques they make (τ_ext = Σ J_cᵀ f_c on
the device's exoskeleton model), and the log records them
(``cuff_force_est``, their normal components ``cuff_normal_est``, and
``tau_ext_est``).

Given as an object (``SimConfig(estimator=MyEstimator())``) the same object
is set up again at the start of every run; as ``"module:Class"`` (a scenario
file's ``estimation.estimator``) the class is imported and built with no
arguments when the run starts (:mod:`exo_ctrl.estimation.plugin`).
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar

from numpy.typing import ArrayLike

from ..model import BodyModel
from ..sensing.readings import SensorReadings
from .observer import DEFAULT_GAIN_PER_S

__all__ = ["Estimator", "EstimatorDevice"]


@dataclass(frozen=True)
class EstimatorDevice:
    """What the device knows, given once to :meth:`Estimator.setup`.

    Attributes:
        exo: the device's exoskeleton model (``exo.model`` is a Pinocchio
            model, ``exo.cuff_frame_ids`` its cuff frames in CUFF_NAMES order).
        patient: the device's nominal patient model.
        dt_s: the control period Δt [s].

    """

    exo: BodyModel
    patient: BodyModel
    dt_s: float


class Estimator(abc.ABC):
    """A user's live cuff-force estimator: sensor readings in, cuff forces out.

    Attributes:
        bandwidth_per_s: how fast the estimate follows the cuff force [1/s]
            (class attribute; default the momentum observer's gain, 100/s):
            the QP filters the patient torque it infers from the estimate at
            this bandwidth, as it does the built-in estimators'.
        components: where each component of the estimate comes from, per
            cuff: ``{cuff: {"normal": text, "along": text}}`` (class
            attribute; the summary's ``cuff_force_estimate_components``;
            None: "the user's estimator" for each).

    """

    bandwidth_per_s: ClassVar[float] = DEFAULT_GAIN_PER_S
    components: ClassVar[dict[str, dict[str, str]] | None] = None

    def setup(self, device: EstimatorDevice) -> None:  # noqa: B027 - a hook, empty by default
        """Called once at the start of every run, before the first tick.

        Args:
            device: what the device knows (:class:`EstimatorDevice`).

        """

    @abc.abstractmethod
    def estimate(self, t_s: float, sensors: SensorReadings) -> ArrayLike:
        """The cuff-force estimate of one control tick.

        Args:
            t_s: the tick's time t_k = k Δt [s].
            sensors: the readings: ``q`` [rad], ``dq`` [rad/s], ``tau`` (the
                joint torque sensors, with the belt the foot plates' joint
                torque added) [N·m]; arrays overwritten each tick.

        Returns:
            The cuff forces on the exoskeleton, (4, 2) finite numbers [N],
            (x, z) per cuff in CUFF_NAMES order.  Any other shape, or a NaN,
            stops the run with a :class:`~exo_ctrl.exceptions.PluginError`
            naming the tick.

        """
