"""The one declared log schema: every signal a run logs, once.

Each tick writes one row of a structured array whose fields are the
:data:`SIGNALS` below (:func:`log_dtype`); the summary, the recorder,
:func:`~exo_ctrl.record.read_recording` and ``exo-ctrl estimate`` all take
their signals from this table.  Adding a signal is one entry here plus the
code that computes it (and writes it into the row: the tick writes by name,
:mod:`exo_ctrl.sim.log_rows`).

Row k holds the state at t_k and what acted over [t_k, t_k+1): command,
applied voltage, mean current, drive torque, cuff force (at mid-step).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._jit import shared_dtype

__all__ = ["FROM_STATISTICS", "SIGNALS", "Signal", "log_dtype", "signal", "signal_shapes"]


@dataclass(frozen=True)
class Signal:
    """One logged signal.

    Attributes:
        name: field name in the log (and entity name in a recording).
        shape: shape of one row's value (``()`` for a scalar).
        unit: SI unit ("" for a count or a code).
        description: what it is.
        labels: what the first axis indexes (``"joint"``, ``"cuff"``, ``"foot"``
            (left, right) or ""),
            the last axis of a (4, 2) signal being (x, z).

    """

    name: str
    shape: tuple[int, ...]
    unit: str
    description: str
    labels: str = ""


#: Every logged signal, in log order.
SIGNALS: list[Signal] = [
    Signal("q_des", (4,), "rad", "planned joint angles", "joint"),
    Signal("dq_des", (4,), "rad/s", "planned joint speeds", "joint"),
    Signal("q", (4,), "rad", "exoskeleton joint angles", "joint"),
    Signal("dq", (4,), "rad/s", "exoskeleton joint speeds", "joint"),
    Signal("q_patient", (4,), "rad", "patient joint angles", "joint"),
    Signal("dq_patient", (4,), "rad/s", "patient joint speeds", "joint"),
    Signal("voltage_cmd", (4,), "V", "controller's drive voltage command", "joint"),
    Signal("voltage", (4,), "V", "drive voltage applied (after supply saturation)", "joint"),
    Signal("current", (4,), "A", "mean drive current over the tick", "joint"),
    Signal("drive_torque", (4,), "N·m", "drive torque at the joint", "joint"),
    Signal("patient_torque", (4,), "N·m", "patient joint torque", "joint"),
    Signal("end_stop_torque", (4,), "N·m", "mechanical end stops' torque on the joint", "joint"),
    Signal("cuff_force", (4, 2), "N", "cuff force on the exoskeleton (x, z)", "cuff"),
    Signal(
        "joint_deflection",
        (4,),
        "rad",
        "drive's spring deflection θ − q at mid-step (joint compliance; 0 if rigid)",
        "joint",
    ),
    Signal(
        "safety_state",
        (),
        "",
        "safety supervisor: 0 normal, 1 stopping, 2 holding, 3 power cut, 4 yielding",
    ),
    Signal("q_meas", (4,), "rad", "encoder reading", "joint"),
    Signal("dq_meas", (4,), "rad/s", "joint speed reading (filtered encoder difference)", "joint"),
    Signal("tau_sensor", (4,), "N·m", "joint torque sensor reading", "joint"),
    # The cuffs' force sensors (--cuff-sensors normal|full; zero otherwise), as the filter got them.
    Signal(
        "cuff_sensor_normal",
        (4,),
        "N",
        "cuff sensor's reading of the normal component n · f (n of the exo link)",
        "cuff",
    ),
    Signal(
        "cuff_sensor_along",
        (4,),
        "N",
        "cuff sensor's reading of the along-link component u · f (full sensors only)",
        "cuff",
    ),
    Signal("cuff_sensor_fresh", (), "", "cuff sensors: 1 on a tick with a new sample, 0 held"),
    Signal(
        "tau_ext_est", (4,), "N·m", "external joint torque estimate (momentum observer)", "joint"
    ),
    Signal("cuff_normal_est", (4,), "N", "estimated cuff force normal to the link", "cuff"),
    Signal("cuff_force_est", (4, 2), "N", "estimated cuff force on the exoskeleton (x, z)", "cuff"),
    # Filled from the chunk by the run's statistics (exo_ctrl.estimation.errors), not the tick:
    # the estimate of row k against the true force of row k - 1 (0 in row 0).
    Signal(
        "cuff_normal_est_error",
        (4,),
        "N",
        "estimate's error of the normal component, n · f̂ − n · f (n of the exo link)",
        "cuff",
    ),
    Signal(
        "cuff_along_est_error",
        (4,),
        "N",
        "estimate's error of the along-link component, u · f̂ − u · f (u of the exo link)",
        "cuff",
    ),
    Signal("qp_active", (), "", "QP controller: active constraints"),
    Signal("qp_failures", (), "", "QP controller: fallbacks so far"),
    Signal(
        "cuff_bound_margin",
        (4,),
        "N",
        "QP controller: margin its cuff bound is tightened by (estimate, horizon, model; 0: no QP)",
        "cuff",
    ),
    # The belt and the feet on it (contact on; zero otherwise), per foot (left, right).
    Signal("ground_force", (2, 2), "N", "belt's force on each exoskeleton foot (x, z)", "foot"),
    Signal(
        "foot_slip", (2,), "m/s", "foot's speed relative to the belt surface, in contact", "foot"
    ),
    Signal("foot_penetration", (2,), "m", "foot point's depth below the belt's top", "foot"),
    Signal("contact_state", (2,), "", "foot contact state (0 free / 1 stick / 2 slide)", "foot"),
    Signal("normal_force_rate", (2,), "N/s", "rate of the belt's normal force on the foot", "foot"),
    Signal(
        "touchdown_velocity",
        (2, 2),
        "m/s",
        "foot's velocity relative to the belt (x, z) at its last touchdown",
        "foot",
    ),
    # The patient's feet on the belt (--patient-feet on; zero otherwise).
    Signal("patient_ground_force", (2, 2), "N", "belt's force on each patient foot (x, z)", "foot"),
    Signal(
        "patient_foot_slip",
        (2,),
        "m/s",
        "patient foot's speed relative to the belt surface, in contact",
        "foot",
    ),
    Signal(
        "patient_foot_penetration",
        (2,),
        "m",
        "patient foot point's depth below the belt's top (with --patient-feet on)",
        "foot",
    ),
    Signal(
        "patient_contact_state",
        (2,),
        "",
        "patient foot contact state (0 free / 1 stick / 2 slide)",
        "foot",
    ),
    Signal("belt_speed", (), "m/s", "belt speed at the end of the tick (surface moves -x)"),
    Signal("belt_speed_set", (), "m/s", "belt speed controller's set speed"),
    Signal("belt_speed_meas", (), "m/s", "belt-speed encoder reading"),
    Signal("belt_drive_force", (), "N", "belt drive's force at the belt surface"),
    Signal("foot_force_meas", (2, 2), "N", "foot plates' load cells: belt force (x, z)", "foot"),
    Signal(
        "tau_ground_meas",
        (4,),
        "N·m",
        "the load cells' joint torque J(q_meas)ᵀ F_meas, added to tau_sensor for the estimator",
        "joint",
    ),
    # The pelvis on its guide (--pelvis supported; zero with the pelvis fixed).
    Signal("pelvis_z", (), "m", "pelvis height above its nominal, end of the tick"),
    Signal("pelvis_vz", (), "m/s", "pelvis vertical speed, end of the tick"),
    Signal(
        "pelvis_stop_force",
        (),
        "N",
        "harness's force on the pelvis: travel stops, its brake after a stop (up > 0)",
    ),
    Signal(
        "path_phase",
        (),
        "",
        "path mode: the plan row of the device's phase (free timing); -1 in other modes",
    ),
]


#: The signals the run's statistics fill from each chunk when it is handed over
#: (:class:`~exo_ctrl.estimation.errors.EstimateErrorStats`), not the tick.
FROM_STATISTICS = ("cuff_normal_est_error", "cuff_along_est_error")


def signal(name: str) -> Signal:
    """The signal called ``name``.

    Raises:
        KeyError: no such signal.

    """
    for s in SIGNALS:
        if s.name == name:
            return s
    raise KeyError(name)


def signal_shapes() -> dict[str, tuple[int, ...]]:
    """Name → shape of one row, for every signal, in log order."""
    return {s.name: s.shape for s in SIGNALS}


def log_dtype() -> np.dtype:
    """The structured dtype of one log row: a float64 field per signal, in log order.

    The same object for the same signals (:func:`~exo_ctrl._jit.shared_dtype`).
    """
    return shared_dtype([(s.name, np.float64, s.shape) for s in SIGNALS])
