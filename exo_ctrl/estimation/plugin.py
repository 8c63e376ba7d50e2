"""A user's estimator in the run: its name, its check, its import and the tick's adapter.

A run's ``estimator`` is a built-in name (``"momentum"``, ``"kalman"``), an
:class:`~exo_ctrl.estimation.interface.Estimator` object, or the import path
``"module:Class"`` of an Estimator subclass built with no arguments
(:func:`check_estimator` when the configuration is made, :func:`load_estimator`
when the run is built; the path's import is :func:`exo_ctrl._plugin.load_plugin`).

:class:`PluginEstimator` stands where the built-in estimators stand in the
tick (:class:`~exo_ctrl.estimation.observer.CuffForceEstimator`'s
``bind``, ``force``, ``tau_ext`` and ``record``): each tick it calls the
user's :meth:`~exo_ctrl.estimation.interface.Estimator.estimate`, checks
the forces (a (4, 2) array of finite numbers, else
:class:`~exo_ctrl.exceptions.PluginError` naming the tick), and derives
from them what the run logs and the patient-load monitor reads: the normal
components f⊥ = n(q) · f (:mod:`.cuff_geometry`) and the external joint
torques τ_ext = Σ_c J_c(q)ᵀ f_c, with J_c the (x, z) rows of cuff c's
frame Jacobian on the device's exoskeleton model.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import record
from .._plugin import is_path, load_plugin, plugin_name
from ..exceptions import InvalidParameter, PluginError
from ..model import CUFF_NAMES
from ..sensing.readings import SensorReadings
from .cuff_geometry import CuffGeometry
from .errors import estimate_components
from .interface import Estimator, EstimatorDevice
from .kalman import ESTIMATORS

__all__ = [
    "ALLOWED",
    "PluginEstimator",
    "check_estimator",
    "components_of",
    "estimator_components",
    "estimator_name",
    "is_plugin_estimator",
    "load_estimator",
    "users_estimator",
]

#: What ``estimator`` may be, in words (the messages of :func:`check_estimator`).
ALLOWED = (
    "momentum, kalman, the import path 'module:Class' of an exo_ctrl.estimation.Estimator "
    "subclass, or such an Estimator object"
)

#: The adapter's record: the fields the tick's log reads from every estimator.
_FIELDS: list[tuple[Any, ...]] = [
    ("tau_ext", np.float64, (4,)),
    ("cuff_normal", np.float64, (4,)),
    ("cuff_force", np.float64, (4, 2)),
]


def estimator_name(estimator: str | Estimator) -> str:
    """A built-in name or a path as given; an object: its class's ``module:QualifiedName``."""
    return plugin_name(estimator)


def is_plugin_estimator(estimator: str | Estimator, built_in: tuple[str, ...]) -> bool:
    """Whether a run's ``estimator`` is a user's (not one of the ``built_in`` names)."""
    return not (isinstance(estimator, str) and estimator in built_in)


def check_estimator(estimator: object, built_in: tuple[str, ...]) -> None:
    """Refuse an ``estimator`` that is not a built-in name, an import path or an Estimator.

    Raises:
        InvalidParameter: naming what is wrong; a misspelt name (no colon)
            or a value of another type with the message it always had.

    """
    if isinstance(estimator, Estimator):
        return
    if isinstance(estimator, str) and (estimator in built_in or is_path(estimator)):
        return
    if isinstance(estimator, type) and issubclass(estimator, Estimator):
        detail = f"{estimator.__name__} is a class: give an object, {estimator.__name__}()"
        raise InvalidParameter("estimator", estimator, ALLOWED, detail)
    if callable(getattr(estimator, "estimate", None)):  # an estimator not on the interface
        detail = f"{type(estimator).__name__} is not a subclass of exo_ctrl.estimation.Estimator"
        raise InvalidParameter("estimator", estimator, ALLOWED, detail)
    if isinstance(estimator, str) and ":" in estimator:
        detail = "an import path is 'package.module:Class'"
        raise InvalidParameter("estimator", estimator, ALLOWED, detail)
    v.one_of("estimator", estimator, built_in)


def load_estimator(estimator: str | Estimator) -> Estimator:
    """The user's estimator of a run: the object itself, or the path's class built.

    Raises:
        InvalidParameter: as :func:`exo_ctrl._plugin.load_plugin`.

    """
    if isinstance(estimator, Estimator):
        return estimator
    return load_plugin(estimator, Estimator, "estimator", ALLOWED)


def users_estimator(estimator: str | Estimator, built_in: tuple[str, ...]) -> Estimator | None:
    """A run's user estimator (:func:`load_estimator`), or None for a ``built_in`` name."""
    if not is_plugin_estimator(estimator, built_in):
        return None
    return load_estimator(estimator)


def components_of(
    estimator: str | Estimator, cuff_sensors: str = "none"
) -> dict[str, dict[str, str]]:
    """Per cuff and component, where a run's estimate comes from (the summary's table).

    A built-in's :func:`~exo_ctrl.estimation.errors.estimate_components`
    with the run's cuff sensors (``SimConfig.cuff_sensors.mode``); a user's
    :func:`estimator_components`.
    """
    if isinstance(estimator, str) and estimator in ESTIMATORS:
        return estimate_components(estimator, cuff_sensors)
    return estimator_components(estimator)


def estimator_components(estimator: str | Estimator) -> dict[str, dict[str, str]]:
    """Where each component of a user's estimate comes from, per cuff (its ``components``).

    The class's :attr:`~exo_ctrl.estimation.interface.Estimator.components`,
    or "the user's estimator" for each component when it does not say.
    """
    name = estimator_name(estimator)
    declared = None if isinstance(estimator, str) else type(estimator).components
    if declared is not None:
        return {cuff: dict(parts) for cuff, parts in declared.items()}
    said = f"the user's estimator {name}"
    return {cuff: {"normal": said, "along": said} for cuff in CUFF_NAMES}


class PluginEstimator:
    """A user's :class:`~exo_ctrl.estimation.interface.Estimator` where the tick takes one.

    Built at the start of a run: calls the user's
    :meth:`~exo_ctrl.estimation.interface.Estimator.setup` with ``device``.

    Args:
        user: the user's estimator.
        device: what the device knows.

    Attributes:
        name: the estimator's ``module:Class``.
        record: fields ``tau_ext`` (4,) [N·m], ``cuff_normal`` (4,) [N],
            ``cuff_force`` (4, 2) [N] of the last tick.
        force, normal, tau_ext: views of those fields, overwritten in place.

    """

    def __init__(self, user: Estimator, device: EstimatorDevice) -> None:
        self.user = user
        self.name = estimator_name(user)
        self._dt = device.dt_s
        self.record = record(_FIELDS)
        self.force = self.record["cuff_force"][0]
        self.normal = self.record["cuff_normal"][0]
        self.tau_ext = self.record["tau_ext"][0]
        exo = device.exo
        self._model, self._data = exo.model, exo.model.createData()
        self._q = pin.neutral(exo.model)
        self._index = np.asarray(exo.q_index)
        self._frames = tuple(exo.cuff_frame_ids)
        self._geometry = CuffGeometry.from_body(exo)
        self._tick = 0
        user.setup(device)

    def bind(self, sensors: SensorReadings) -> Callable[[], np.ndarray]:
        """The tick's update on ``sensors`` as a call without arguments (the built-ins' form).

        Each call is the next control tick, from 0.
        """

        def update() -> np.ndarray:
            k = self._tick
            self._tick += 1
            return self.step(k, sensors)

        return update

    def step(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """Tick k: the user's forces [N], (4, 2), with their normal components and τ_ext.

        Raises:
            PluginError: the forces are not a (4, 2) array of finite numbers.

        """
        t = k * self._dt
        out = self.user.estimate(t, sensors)
        what = "estimate must return (4, 2) cuff forces [N]"
        try:
            forces = np.asarray(out, dtype=np.float64)
        except (TypeError, ValueError):
            raise PluginError(self.name, k, t, f"{what}; got {out!r}", "estimator") from None
        if forces.shape != (4, 2):
            raise PluginError(self.name, k, t, f"{what}; got shape {forces.shape}", "estimator")
        if not np.isfinite(forces).all():
            reason = f"estimate must return finite numbers; got {forces.tolist()}"
            raise PluginError(self.name, k, t, reason, "estimator")
        self.force[:] = forces
        q = sensors.q
        psi = self._geometry.cuff_directions(q)
        self.normal[:] = -np.sin(psi) * forces[:, 0] + np.cos(psi) * forces[:, 1]
        self._q[self._index] = q
        model, data = self._model, self._data
        pin.computeJointJacobians(model, data, self._q)
        pin.updateFramePlacements(model, data)
        tau = np.zeros(model.nv)
        for c, frame in enumerate(self._frames):
            jac = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
            tau += jac[0] * forces[c, 0] + jac[2] * forces[c, 1]
        self.tau_ext[:] = tau[self._index]
        return self.force
