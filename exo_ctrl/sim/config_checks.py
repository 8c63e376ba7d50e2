"""The checks of a :class:`~exo_ctrl.sim.config.SimConfig` that span several of its parts.

Each function takes the configuration being made (a ``SimConfig`` with its
fields set, before it is returned; typed ``Any``, as this module is below
``config`` in the imports) and raises :class:`~exo_ctrl.exceptions.InvalidParameter`
naming the field, its value and what is allowed.
"""

from __future__ import annotations

import functools
import types
import typing
from dataclasses import fields, is_dataclass
from typing import Any

import numpy as np

from .. import _validate as v
from ..control import PD, PDGains
from ..control.modes import MODES
from ..control.plugin import check_controller as check_plugin
from ..control.plugin import is_plugin
from ..estimation.plugin import check_estimator as check_user_estimator
from ..estimation.plugin import is_plugin_estimator
from ..exceptions import InvalidParameter
from ..plan import PLAN_BYTES_PER_SAMPLE, SpeedProfile
from ..plan.ramp import ramp_time
from ..plant import PelvisParams
from .faults import BELT_STOP_NEEDS

__all__ = [
    "MAX_DURATION_S",
    "MAX_PLANT_SUBSTEPS",
    "PLAN_ROW_BYTES",
    "check_controller",
    "check_estimator",
    "check_estop",
    "check_mode",
    "check_parts",
    "check_plan_size",
    "check_ramp_in",
    "check_sync",
]

#: The longest run [s] (10⁷ s, 116 days of simulated time, some 2 days of
#: wall time at a real-time factor of 50): a longer one is a typing error,
#: and 1e300 would never end.
MAX_DURATION_S = 1e7

#: The most plant steps per control tick: 1000 steps of 1 µs at 1 kHz, well
#: past what the stiffest contact needs (tests/plant/test_contact*.py).
MAX_PLANT_SUBSTEPS = 1000

#: Memory per row of a run's joint plan [bytes]: its time (8 B), the plan
#: (:data:`~exo_ctrl.plan.PLAN_BYTES_PER_SAMPLE`) and the computed-torque
#: tables of feedforward torque and voltage (4 + 4 numbers).
PLAN_ROW_BYTES = 8 + PLAN_BYTES_PER_SAMPLE + 2 * 4 * 8


def check_controller(config: Any, built_in: tuple[str, ...]) -> None:
    """Refuse a controller that is none of the allowed kinds, or a user's outside tracking.

    A user's controller (:mod:`exo_ctrl.control.plugin`) runs in the tracking
    mode without a session: the modes and a session's segments build the
    built-in controllers.

    A :class:`~exo_ctrl.control.PD` or ``CT`` object carries its gains:
    ``gains`` is then left at its default.
    """
    check_plugin(config.controller, built_in)
    if isinstance(config.controller, PD) and config.gains != PDGains():
        raise InvalidParameter(
            "gains",
            config.gains,
            "the default PDGains() with a PD or CT object",
            f"the object carries its gains: {config.controller!r}",
        )
    if is_plugin(config.controller, built_in):
        _tracking_only(config, "controller")


def check_estimator(config: Any, built_in: tuple[str, ...]) -> None:
    """Refuse an estimator that is none of the allowed kinds, or a user's outside tracking.

    Cuff sensors (``cuff_sensors``) need the Kalman filter, which fuses them.

    A user's estimator (:mod:`exo_ctrl.estimation.plugin`) runs in the
    tracking mode without a session: the modes tune the built-in ones.
    """
    check_user_estimator(config.estimator, built_in)
    if is_plugin_estimator(config.estimator, built_in):
        _tracking_only(config, "estimator")
    mode = config.cuff_sensors.mode
    if mode != "none" and config.estimator != "kalman":
        why = "the cuff sensors' readings are fused by the Kalman filter"
        raise InvalidParameter("cuff_sensors mode", mode, "none unless estimator is kalman", why)


def _tracking_only(config: Any, kind: str) -> None:
    """Refuse a user's ``kind`` (controller or estimator) outside tracking mode or in a session."""
    if config.mode != "tracking":
        why = f"a user's {kind} runs in tracking mode"
        raise InvalidParameter("mode", config.mode, f"tracking with a user's {kind}", why)
    if config.session is not None:
        raise InvalidParameter(
            "session", "given", f"unset with a user's {kind}", "a session switches modes"
        )


def check_mode(config: Any) -> None:
    """Refuse an unknown mode, and a mode or an active patient where they do not apply."""
    v.one_of("mode", config.mode, MODES)
    if config.patient_torque == "active" and config.exercise != "gait":
        raise InvalidParameter(
            "patient_torque", "active", "none or spastic", "the active patient walks a gait"
        )
    if config.mode == "tracking":
        return
    if config.exercise != "gait":
        raise InvalidParameter("mode", config.mode, "tracking", "the calibration swing tracks")
    if config.mode in ("aan", "path") and (not config.plan_layout.period or config.synced):
        raise InvalidParameter(
            "mode",
            config.mode,
            "tracking, guidance or transparent here",
            "assist-as-needed learns per phase (and path control follows the phase) of a "
            "precomputed periodic plan: " + periodic_plan_needs(config),
        )


def periodic_plan_needs(config: Any) -> str:
    """What a precomputed periodic plan needs, with this run's figures (for messages)."""
    ramps = config.ramp_in + config.ramp_out_s
    return (
        f"a period of a whole number of ticks (here {config.gait.period / config.dt:g}), "
        f"sync off, and a run of at least the ramps and one period "
        f"({ramps + config.gait.period:g} s here; --duration {config.duration_s:g} s)"
    )


def check_estop(config: Any) -> None:
    """Refuse an e-stop time no control tick reaches (it would be ignored)."""
    v.non_negative("estop_at", config.estop_at_s, "s")
    last = (config.n_ticks - 1) * config.dt  # the time of the last tick, as the loop has it
    if config.estop_at_s <= last:
        return
    raise InvalidParameter(
        "estop_at",
        config.estop_at_s,
        f"in [0, {last:g}] s, within the run",
        f"the run lasts {config.duration_s:g} s; its last control tick is at t = {last:g} s",
    )


def check_widen(config: Any) -> None:
    """Refuse ``safety_widen`` where no supervisor reads the estimate, or with the QP."""
    if not config.safety_widen or (
        config.safety and config.safety_use_estimate and config.controller != "qp"
    ):
        return
    raise InvalidParameter(
        "safety_widen",
        True,
        "with the safety supervisor on, watching the estimated cuff forces, and a controller "
        "other than the QP (which tightens its own bound)",
    )


def check_faults(config: Any) -> None:
    """Refuse a fault no control tick reaches, or a belt stop without the belt."""
    last = (config.n_ticks - 1) * config.dt
    for fault in config.faults:
        if fault.at_s > last:
            raise InvalidParameter("fault at_s", fault.at_s, f"in [0, {last:g}] s")
        if fault.kind == "belt_stop" and not config.contact.enabled:
            raise InvalidParameter("fault kind", fault.kind, BELT_STOP_NEEDS)


def check_ramp_in(config: Any) -> None:
    """Refuse a ramp-in time that is not a number >= 0 or does not fit in the run."""
    t_in = ramp_time("ramp_in", config.ramp_in_s)
    room = config.duration_s - config.ramp_out_s
    if t_in > room:
        out = config.ramp_out_s
        raise InvalidParameter(
            "ramp_in",
            config.ramp_in_s,
            f"at most {max(room, 0.0):g} s, within the run",
            f"the run lasts {config.duration_s:g} s"
            + (f", of which the ramp-out takes the last {out:g} s" if out else ""),
        )


def check_plan_size(config: Any) -> None:
    """Refuse a plan beyond the memory cap, naming the period, a ramp or the duration.

    Then the belt's set speeds (:func:`check_belt_size`).
    """
    rows = config.plan_rows
    most = v.max_items(PLAN_ROW_BYTES)
    rate = config.control_rate_hz
    lay = config.plan_layout
    if lay.period:
        # The rows of each time the user can shorten; the default ramp-in is one period.
        parts = {
            "period": lay.period,
            "ramp_in": lay.lead,
            "ramp_out": rows - lay.lead - lay.period,
        }
        if config.ramp_in_s is None:
            parts["period"] += parts.pop("ramp_in")
        # The largest part that can make room alone, else the largest.
        fits = [r for r in parts if rows - parts[r] < most] or list(parts)
        name = max(fits, key=lambda r: parts[r])
        value = {"period": config.gait.period, "ramp_in": config.ramp_in}.get(
            name, config.ramp_out_s
        )
        share = 2 if name == "period" and config.ramp_in_s is None and lay.lead else 1
        room = max(most - (rows - parts[name]), 0) / share
        limit = f"at most {room / rate:.4g} s at {rate:g} Hz"
        note = "the plan holds one period"
        if rows > lay.period:
            ramps = "the default ramp-in of one period" if share == 2 else "the ramps"
            note = f"the plan holds one period and {ramps} ({rows - lay.period:,} ticks)"
    else:
        name, value = "duration", config.duration_s
        limit = f"at most {(most - 1) / rate:.4g} s at {rate:g} Hz"
        note = (
            "the plan holds every tick"
            if config.plan_periodic
            else (
                "the plan holds every tick, as the period "
                f"{config.gait.period:g} s is not a whole number of {1e3 * config.dt:g} ms ticks"
            )
        )
    v.allocation(name, value, rows, PLAN_ROW_BYTES, what="plan rows", limit=limit, note=note)
    check_belt_size(config)


#: Bytes a tick of the belt's planned set speed takes while it is built: the ramp's σ,
#: σ̇, σ̈, the tick times and the speeds (measured peak 88 B a tick, 96 B with a speed
#: profile; sim/setup.py) [bytes].
BELT_ROW_BYTES = 128


def check_belt_size(config: Any) -> None:
    """With the belt on, its set speed is planned for every tick: refused beyond the memory cap.

    Raises:
        InvalidParameter: duration × control rate ticks of :data:`BELT_ROW_BYTES`
            would need more than 1 GiB, naming ``duration`` and its largest value.

    """
    if not config.contact.enabled:
        return
    rate = config.control_rate_hz
    most = v.max_items(BELT_ROW_BYTES)
    v.allocation(
        "duration",
        config.duration_s,
        config.n_ticks,
        BELT_ROW_BYTES,
        what="belt speed samples",
        limit=f"at most {(most - 1) / rate:.4g} s at {rate:g} Hz with the belt on",
        note="the belt's set speed is planned for every tick",
    )


def check_pelvis(config: Any) -> None:
    """Refuse a supported pelvis without the belt to stand on, or off the gait."""
    if not isinstance(config.pelvis, PelvisParams):
        raise InvalidParameter("pelvis", config.pelvis, "a PelvisParams")
    if not config.pelvis.supported:
        if config.gait.pelvis_excursion > 0.0:
            raise InvalidParameter(
                "pelvis_excursion",
                config.gait.pelvis_excursion,
                "0 with the pelvis fixed (--pelvis supported)",
                "a fixed hip cannot rise and fall",
            )
        if config.pelvis.bws_fraction != 0.0:
            raise InvalidParameter(
                "bws", config.pelvis.bws_fraction, "0 with the pelvis fixed (--pelvis supported)"
            )
        return
    if not config.contact.enabled:
        raise InvalidParameter(
            "pelvis",
            "supported",
            "'fixed' without the belt",
            "the legs carry the weight through the belt contact: use --contact on",
        )
    if config.exercise != "gait":
        raise InvalidParameter(
            "pelvis",
            "supported",
            "'fixed' here",
            f"the {config.exercise} exercise swings the legs in the air",
        )


def check_sync(config: Any) -> None:
    """Refuse a speed profile without the belt, and sync where it does not apply."""
    profile = config.speed_profile
    if profile is not None:
        if not isinstance(profile, SpeedProfile):
            raise InvalidParameter(
                "speed_profile", profile, "a SpeedProfile, its text T1:V1,... or None"
            )
        if not config.contact.enabled:
            raise InvalidParameter(
                "speed_profile", profile.text(), "unset without the belt (contact on)"
            )
    if config.sync is not None and not isinstance(config.sync, (bool, np.bool_)):
        raise InvalidParameter("sync", config.sync, "True, False or None")
    if not config.synced:
        return
    why = None
    if not config.contact.enabled:
        why = "the belt's speed is measured with contact on only"
    elif config.exercise != "gait":
        why = f"the {config.exercise} exercise has no gait"
    elif config.ramp_out_s > 0.0:
        why = "a ramp-out with the synchronised plan is not supported"
    if why is not None:
        raise InvalidParameter("sync", "on", "off here", why)


def check_parts(config: Any) -> None:
    """Refuse a part of the run that is not of its declared parameter class.

    (A float given as ``gait`` would otherwise fail later with an AttributeError.)
    """
    for name, allowed, optional in _part_classes(type(config)):
        value = getattr(config, name)
        if not (isinstance(value, allowed) or (optional and value is None)):
            names = " or ".join(t.__name__ for t in allowed) + (" or None" if optional else "")
            raise InvalidParameter(name, value, f"a {names}")


@functools.cache
def _part_classes(cls: type) -> tuple[tuple[str, tuple[type, ...], bool], ...]:
    """The fields of ``cls`` (SimConfig) typed by parameter classes: (name, classes, None allowed).

    Read from the annotations once (evaluating them took 0.4 ms, two thirds
    of a SimConfig's construction).  ``speed_profile`` is left out: it also
    takes its text, which ``check_sync`` checks; containers check their items.
    """
    hints = typing.get_type_hints(cls)
    parts = []
    for f in fields(cls):
        hint = hints[f.name]
        union = typing.get_origin(hint) in (typing.Union, types.UnionType)
        if f.name == "speed_profile" or (typing.get_origin(hint) is not None and not union):
            continue
        members = typing.get_args(hint) if union else (hint,)
        allowed = tuple(t for t in members if is_dataclass(t))
        if allowed:
            parts.append((f.name, allowed, type(None) in members))
    return tuple(parts)
