"""What every controller sees and returns on the tick (the internal interface).

The run's tick calls every controller through :class:`TickController`; the
built-in ones implement it with compiled kernels, a user's
(:class:`~exo_ctrl.control.interface.Controller`, the public interface)
through :class:`~exo_ctrl.control.plugin.PluginController`.

A controller is built with the plan (joint targets sampled at the control
rate) and, per tick, gets the tick index and the sensor readings; it returns
the four drive voltages [V] in JOINT_NAMES order.  It never reads the plant.

Each controller keeps what a tick produced in :attr:`TickController.record`, a
structured array of one element (:func:`exo_ctrl._jit.record`) whose fields
start with :data:`COMMAND_FIELDS`; the loop logs them by name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES
from ..sensing.readings import SensorReadings

__all__ = ["COMMAND_FIELDS", "CommandCounters", "PDGains", "TickController"]

#: The fields every controller's record has (numpy dtype syntax):
#:
#: - ``u_cmd`` [V], (4,): the voltages :meth:`TickController.command` returned last;
#: - ``active_constraints``: the QP's active bounds in the last tick (0 for PD/CT);
#: - ``failures``: the QP's fallbacks so far (0 for PD/CT);
#: - ``margin`` [N], (4,): the QP's margin m_c on each cuff's bound this tick
#:   (:mod:`~exo_ctrl.control.qp.margin`; 0 for PD/CT).
COMMAND_FIELDS: list[tuple[Any, ...]] = [
    ("u_cmd", np.float64, (4,)),
    ("active_constraints", np.float64),
    ("failures", np.float64),
    ("margin", np.float64, (4,)),
]


class CommandCounters:
    """The QP counters of a controller's record (:data:`COMMAND_FIELDS`), for every controller."""

    record: np.ndarray

    @property
    def active_constraints(self) -> int:
        """Active QP bounds in the last tick (0: no QP)."""
        return int(self.record["active_constraints"][0])

    @property
    def failures(self) -> int:
        """QP fallbacks so far (0: no QP; a session: over every segment's controller)."""
        return int(self.record["failures"][0])


class TickController(Protocol):
    """Plan and sensors in, drive voltages out: what the tick calls."""

    name: str
    #: One element with at least the :data:`COMMAND_FIELDS`.
    record: np.ndarray

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """Drive voltages [V], (4,), for control tick ``k`` (a buffer the caller may not keep)."""
        ...


@dataclass(frozen=True)
class PDGains:
    """Gains of the paper's PD voltage law U = k_p (q* - q) + k_d (q̇* - q̇).

    Chosen by simulation on the default scenario (the paper gives no values):
    with the default drive the steady-state joint speed per volt is
    k_E / i_G ≈ 0.216 rad/(V·s), so k_p = 300 V/rad closes a position loop of
    about 65 rad/s; k_d = 5 V·s/rad damps it.  (The paper's printed drive,
    0.52 rad/(V·s), was run with k_p = 100, k_d = 2: :meth:`paper_printed`.)

    Attributes:
        kp: proportional gain per joint [V/rad].
        kd: derivative gain per joint [V·s/rad].

    Both are stored as 4 floats, in JOINT_NAMES order.

    Raises:
        InvalidParameter: a gain that is not one number or four, an item
            that is text, a bool or not finite, kp <= 0 or kd < 0.

    """

    kp: tuple[float, ...] | float = 300.0
    kd: tuple[float, ...] | float = 5.0

    def __post_init__(self) -> None:
        for name, unit in (("kp", "V/rad"), ("kd", "V·s/rad")):
            given = getattr(self, name)
            gains = tuple(v.non_negative(name, x, unit) for x in _items(name, given))
            if name == "kp" and not all(x > 0 for x in gains):
                raise InvalidParameter("kp", given, "> 0 V/rad for every joint")
            object.__setattr__(self, name, gains)

    @classmethod
    def paper_printed(cls) -> PDGains:
        """The gains tuned for the paper's printed drive (``MotorParams.paper_printed()``)."""
        return cls(kp=100.0, kd=2.0)


def _items(name: str, value: object) -> list[object]:
    """A gain's per-joint items: one number for every joint, or one each.

    Raises:
        InvalidParameter: neither a single item nor one per joint.

    """
    try:
        arr = np.asarray(value, dtype=object)
    except ValueError:  # e.g. nested sequences of different lengths
        arr = None
    if arr is not None and arr.ndim == 0:
        return [arr.item()] * len(JOINT_NAMES)
    if arr is not None and arr.shape == (len(JOINT_NAMES),):
        return arr.tolist()
    raise InvalidParameter(
        name,
        value,
        f"a number or {len(JOINT_NAMES)} numbers (one per joint: {', '.join(JOINT_NAMES)})",
    )
