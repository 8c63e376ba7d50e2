"""The signals a recording leaves out: those of the features that are off in the run.

The log schema (:data:`exo_ctrl.sim.schema.SIGNALS`) has a row for every
feature, and a run logs every signal whatever its settings; a feature that
is off writes one constant into its signals at every tick (the tick's
``write_applied``, :mod:`exo_ctrl.sim.tick`: the contact's (with its belt),
the patient's feet's and the pelvis's records are zero when off, the foot
plates are read with the belt only, the patient's torque is zero without a
patient torque model, the cuff sensors' readings are zero without them (the
along axis without ``full``), the path mode's phase row is -1 in other modes).  Each
such signal costs a recording as much as any other (an entity per series:
its row ids, its two timelines and its list offsets, about 36 B per tick
before compression, and rerun's work per entity and chunk), so the recorder
stores none of them (:data:`FEATURES`): their constants are in the
recording's ``raw/meta`` (``"left_out"``, name → value), and
:func:`~.reader.read_recording` fills them back in, so a run reads back as
it was logged.

A left-out signal is still checked at every chunk: if its rows are not all
its constant (a feature this table calls off that was on after all), the
recorder stores it from that chunk on, and the reader takes the stored rows
where the file has them and the constant before.  Nothing is lost if this
table is wrong; only the saving (and the signal's panel, which the default
blueprint, made at the start, does not have).  tests/record/test_omitted.py
checks the table against runs with each feature off and on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..sim import SimConfig

__all__ = ["FEATURES", "Feature", "left_out_signals"]


@dataclass(frozen=True)
class Feature:
    """A feature of the run that can be off, and the signals it then holds constant.

    Attributes:
        name: what the feature is.
        off: true when the run's configuration has it off.
        signals: the log-schema signals that are then constant.
        value: their constant.

    """

    name: str
    off: Callable[[SimConfig], bool]
    signals: tuple[str, ...]
    value: float = 0.0


def _modes(config: SimConfig) -> set[str]:
    """The interaction modes the run can be in (its mode, and its session's segments')."""
    modes = {config.mode}
    if config.session is not None:
        modes.update(segment.mode for segment in config.session.segments)
    return modes


#: The features whose signals are left out when off (module docstring).
FEATURES: tuple[Feature, ...] = (
    Feature(
        "foot-belt contact (--contact off)",
        lambda c: not c.contact.enabled,
        (
            "ground_force",
            "foot_slip",
            "foot_penetration",
            "contact_state",
            "normal_force_rate",
            "touchdown_velocity",
            "foot_force_meas",  # the foot plates are read with the belt only
            "tau_ground_meas",
            "belt_speed",  # no belt is simulated without the contact
            "belt_speed_set",
            "belt_speed_meas",
            "belt_drive_force",
        ),
    ),
    Feature(
        "the patient's feet on the belt (--patient-feet off)",
        lambda c: not c.contact.patient_feet,
        (
            "patient_ground_force",
            "patient_foot_slip",
            "patient_foot_penetration",
            "patient_contact_state",
        ),
    ),
    Feature(
        "the pelvis on its guide (--pelvis fixed)",
        lambda c: not c.pelvis.supported,
        ("pelvis_z", "pelvis_vz", "pelvis_stop_force"),
    ),
    Feature(
        "the patient's own torques (--patient-torque none: the paper's passive patient)",
        lambda c: c.patient_torque == "none",
        ("patient_torque",),
    ),
    Feature(
        "compliant joints (rigid drives)",
        lambda c: not c.joint_compliance.enabled,
        ("joint_deflection",),
    ),
    Feature(
        "the QP controller (--controller pd or ct)",
        lambda c: c.controller != "qp",
        ("qp_active", "qp_failures", "cuff_bound_margin"),
    ),
    Feature(
        "the cuffs' force sensors (--cuff-sensors none)",
        lambda c: not c.cuff_sensors.on,
        ("cuff_sensor_normal", "cuff_sensor_fresh"),
    ),
    Feature(
        "the cuff sensors' along axis (--cuff-sensors none or normal)",
        lambda c: c.cuff_sensors.mode != "full",
        ("cuff_sensor_along",),
    ),
    Feature(
        "the path mode (no --mode path, no path segment)",
        lambda c: "path" not in _modes(c),
        ("path_phase",),
        -1.0,
    ),
)


def left_out_signals(config: SimConfig, signals: set[str] | None = None) -> dict[str, float]:
    """Name → constant of the signals of the features off in ``config``.

    Args:
        config: the run's configuration.
        signals: the signals being recorded (default: every one named in
            :data:`FEATURES`); others are skipped.

    """
    out: dict[str, float] = {}
    for feature in FEATURES:
        if feature.off(config):
            for name in feature.signals:
                if signals is None or name in signals:
                    out[name] = feature.value
    return out
