"""A therapy session: segments of modes and belt speeds, switched bumplessly (``--session``).

A session file is a JSON list of segments, run one after another::

    [
      {"duration": 3.6, "mode": "tracking"},
      {"duration": 4.8, "mode": "aan", "aan_gain": 60},
      {"duration": 3.6, "mode": "transparent", "belt_speed": 0.5}
    ]

Each segment has ``duration`` [s] (in (0, 10⁷]), ``mode`` (one of
:data:`~exo_ctrl.control.modes.MODES`), optionally ``belt_speed`` [m/s]
(≥ 0.01, :data:`~exo_ctrl.plan.profile.MIN_SPEED_MPS`; with the belt:
contact on) and its mode's parameters, overriding the run's: ``guidance``,
``force_gain``, ``aan_forgetting``, ``aan_gain``
(:class:`~exo_ctrl.control.modes.ModeParams`), ``tunnel_width`` [m],
``path_support`` [N] (:class:`~exo_ctrl.control.modes.PathParams`).  The
durations sum to the run's.  The controllers switch bumplessly
(:mod:`exo_ctrl.control.modes.switch`: blended over ``blend_s``) and each
switch is an event of the run (and so of its recording).  A segment's belt
speed is reached over the first ``belt_ramp_s`` of the segment, linearly
(the run's speed profile); a segment without one keeps the gait's belt
speed v_f.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass
from typing import Any

from .. import _validate as v
from ..control.modes import MODES, InteractionController, ModeParams, PathController, PathParams
from ..control.modes.switch import SwitchedController
from ..exceptions import InvalidParameter
from ..plan import SpeedProfile
from ..plan.profile import MIN_SPEED_MPS
from .config_checks import MAX_DURATION_S, periodic_plan_needs

__all__ = [
    "SEGMENT_KEYS",
    "Segment",
    "SessionParams",
    "check_session",
    "load_session",
    "session_controller",
]

#: A segment's mode parameters: JSON key → (parameter set, field).
_PARAM_KEYS = {
    "guidance": ("modes", "guidance"),
    "force_gain": ("modes", "force_gain"),
    "aan_forgetting": ("modes", "aan_forgetting"),
    "aan_gain": ("modes", "aan_gain"),
    "tunnel_width": ("path", "tunnel_width_m"),
    "path_support": ("path", "support_N"),
}

#: The keys a segment may have.
SEGMENT_KEYS = ("duration", "mode", "belt_speed", *_PARAM_KEYS)


def _check_ranges(name: str, duration: float, mode: str, speed: float | None) -> None:
    """Refuse a segment's duration outside (0, 10⁷] s, an unknown mode, a belt under 0.01 m/s.

    ``name``: how the messages call the segment; the values are numbers
    already checked finite (shown as given).
    """
    if not 0.0 < float(duration) <= MAX_DURATION_S:
        raise InvalidParameter(f"{name} duration", duration, f"in (0, {MAX_DURATION_S:g}] s")
    v.one_of(f"{name} mode", mode, MODES)
    if speed is not None and not float(speed) >= MIN_SPEED_MPS:
        raise InvalidParameter(f"{name} belt_speed", speed, f">= {MIN_SPEED_MPS:g} m/s")


@dataclass(frozen=True)
class Segment:
    """One segment of a session.

    Raises:
        InvalidParameter: a duration not in (0, 10⁷] s or a belt speed below
            0.01 m/s, an unknown mode or parameter.

    Attributes:
        duration_s: its duration [s], > 0.
        mode: its mode, one of :data:`~exo_ctrl.control.modes.MODES`.
        belt_speed_mps: its belt speed [m/s] (None: the gait's v_f).
        params: its mode parameters, (JSON key, value) pairs over the run's.

    """

    duration_s: float
    mode: str
    belt_speed_mps: float | None = None
    params: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        v.finite("session segment duration", self.duration_s, "s")
        if self.belt_speed_mps is not None:
            v.finite("session segment belt_speed", self.belt_speed_mps, "m/s")
        _check_ranges("session segment", self.duration_s, self.mode, self.belt_speed_mps)
        for key, _ in self.params:
            if key not in _PARAM_KEYS:
                raise InvalidParameter(
                    "session segment parameter", key, f"one of {', '.join(_PARAM_KEYS)}"
                )

    @classmethod
    def from_dict(cls, index: int, data: object) -> Segment:
        """Segment ``index`` (from 1) of a file from its JSON object.

        Raises:
            InvalidParameter: not an object, a missing or unknown key, a
                duration not > 0, an unknown mode, a belt speed not > 0, a
                parameter outside its range.

        """
        name = f"session segment {index}"
        if not isinstance(data, dict):
            raise InvalidParameter(name, data, "a JSON object with duration and mode")
        for key in data:
            if key not in SEGMENT_KEYS:
                raise InvalidParameter(f"{name} key", key, f"one of {', '.join(SEGMENT_KEYS)}")
        for key in ("duration", "mode"):
            if key not in data:
                raise InvalidParameter(f"{name} {key}", None, "given", "each segment has one")
        duration = _number(f"{name} duration", data["duration"])
        mode = data["mode"]
        speed = data.get("belt_speed")
        if speed is not None:
            speed = _number(f"{name} belt_speed", speed)
        # the file's own values in the messages (-2, not -2.0)
        _check_ranges(name, data["duration"], mode, data.get("belt_speed"))
        params = tuple((k, _number(f"{name} {k}", data[k])) for k in _PARAM_KEYS if k in data)
        seg = cls(duration, mode, speed, params)
        try:  # each parameter checked by its own dataclass
            seg.mode_params(ModeParams()), seg.path_params(PathParams())
        except InvalidParameter as exc:
            raise InvalidParameter(f"{name} {exc.name}", exc.value, exc.allowed) from None
        return seg

    def mode_params(self, base: ModeParams) -> ModeParams:
        """The run's mode parameters with this segment's over them."""
        return dataclasses.replace(base, **self._fields("modes"))

    def path_params(self, base: PathParams) -> PathParams:
        """The run's path parameters with this segment's over them."""
        return dataclasses.replace(base, **self._fields("path"))

    def _fields(self, group: str) -> dict[str, float]:
        return {_PARAM_KEYS[k][1]: value for k, value in self.params if _PARAM_KEYS[k][0] == group}


@dataclass(frozen=True)
class SessionParams:
    """A session: its segments and how they switch.

    Attributes:
        segments: the segments, in order (at least one).
        blend_s: T_b ≥ 0, the window over which the command is blended from
            one segment's controller to the next [s] (default 0.1: 0.475 V per
            tick at most from the switch with the default 24 V supply at
            1 kHz, :mod:`exo_ctrl.control.modes.switch`; choice); shorter
            than every segment after the first.
        belt_ramp_s: the time a segment takes to reach its belt speed [s]
            (default 1.0, choice: 0.5 m/s in 1 s is 0.5 m/s², a gentle
            treadmill acceleration); shorter than every segment that sets one.
        source: the file it came from ("" if built in code).

    Raises:
        InvalidParameter: no segment, a window not >= 0 or too long.

    """

    segments: tuple[Segment, ...]
    blend_s: float = 0.1
    belt_ramp_s: float = 1.0
    source: str = ""

    def __post_init__(self) -> None:
        segs = tuple(self.segments)
        if not segs or not all(isinstance(s, Segment) for s in segs):
            raise InvalidParameter("session", self.source or segs, "at least one segment")
        object.__setattr__(self, "segments", segs)
        blend = v.non_negative("session blend", self.blend_s, "s")
        ramp = v.non_negative("session belt_ramp", self.belt_ramp_s, "s")
        for i, seg in enumerate(segs[1:], start=2):
            if seg.duration_s <= blend:
                raise InvalidParameter(
                    f"session segment {i} duration", seg.duration_s, f"> the {blend:g} s blend"
                )
            if seg.belt_speed_mps is not None and seg.duration_s <= ramp:
                raise InvalidParameter(
                    f"session segment {i} duration",
                    seg.duration_s,
                    f"> the belt's {ramp:g} s ramp to its belt_speed",
                )

    @classmethod
    def coerce(cls, value: object) -> SessionParams:
        """A SessionParams from itself or its plain-data form (``dataclasses.asdict``'s).

        Raises:
            InvalidParameter: anything else.

        """
        if isinstance(value, SessionParams):
            return value
        if isinstance(value, dict) and isinstance(value.get("segments"), list | tuple):
            try:
                segments = tuple(
                    Segment(
                        s["duration_s"],
                        s["mode"],
                        s.get("belt_speed_mps"),
                        tuple((str(k), float(x)) for k, x in s.get("params", ())),
                    )
                    for s in value["segments"]
                )
                rest = {k: value[k] for k in ("blend_s", "belt_ramp_s", "source") if k in value}
                return cls(segments, **rest)
            except (KeyError, TypeError, ValueError):
                pass
        raise InvalidParameter("session", value, "a SessionParams or None")

    @property
    def total_s(self) -> float:
        """The segments' durations summed [s]."""
        return math.fsum(s.duration_s for s in self.segments)

    @property
    def starts_s(self) -> list[float]:
        """Each segment's start time [s]."""
        out, t = [], 0.0
        for seg in self.segments:
            out.append(t)
            t += seg.duration_s
        return out

    def speed_profile(self, belt_speed_mps: float) -> SpeedProfile | None:
        """The belt's speed profile (None: no segment sets a belt speed).

        Args:
            belt_speed_mps: the gait's belt speed v_f [m/s], for the segments
                that set none.

        """
        if all(s.belt_speed_mps is None for s in self.segments):
            return None
        times: list[float] = []
        speeds: list[float] = []
        for i, (start, seg) in enumerate(zip(self.starts_s, self.segments, strict=True)):
            speed = belt_speed_mps if seg.belt_speed_mps is None else seg.belt_speed_mps
            first = start + (self.belt_ramp_s if i and speed != speeds[-1] else 0.0)
            if times and first <= times[-1]:
                times.pop(), speeds.pop()
            times += [first, start + seg.duration_s]
            speeds += [speed, speed]
        return SpeedProfile(tuple(times), tuple(speeds))


def _number(name: str, value: object) -> float:
    """A finite JSON number (not a boolean)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidParameter(name, value, "a number")
    return v.finite(name, value)


#: The longest session file read [characters] (a segment takes about 60).
MAX_SESSION_BYTES = 1 << 20


def load_session(path: str, blend_s: float = 0.1) -> SessionParams:
    """Read a session file (module docstring).

    Raises:
        InvalidParameter: the file does not exist or cannot be read, is not
            valid JSON (its line and column), is not a list of segments, or
            a segment is refused (:meth:`Segment.from_dict`).

    """
    if not os.path.isfile(path):
        why = "no such file"
        if os.path.isdir(path):
            why = "a directory"
        elif os.path.exists(path):
            why = "not a regular file"
        raise InvalidParameter("session", path, "an existing JSON file", why)
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read(MAX_SESSION_BYTES + 1)
        if len(text) > MAX_SESSION_BYTES:
            raise InvalidParameter(
                "session", path, "a JSON list of segments", f"over {MAX_SESSION_BYTES:,} characters"
            )
        deep = v.json_depth_problem(text)
        if deep:
            raise InvalidParameter("session", path, "a JSON list of segments", deep)
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidParameter(
            "session", path, "a JSON list of segments", f"line {exc.lineno}: {exc.msg}"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
        raise InvalidParameter("session", path, "a readable JSON file", str(reason)) from None
    if not isinstance(data, list) or not data:
        raise InvalidParameter("session", path, "a JSON list of segments", "a non-empty list")
    segments = tuple(Segment.from_dict(i, d) for i, d in enumerate(data, start=1))
    return SessionParams(segments, blend_s=blend_s, source=path)


def check_session(config: Any) -> None:
    """Refuse a session that does not fit its run (a :class:`SimConfig` being made).

    Raises:
        InvalidParameter: durations not summing to the run's, ``mode`` set
            beside it, a segment's mode that does not apply, belt speeds
            without the belt or beside a speed profile.

    """
    session: SessionParams = config.session
    total = session.total_s
    if abs(total - config.duration_s) > 1e-9 * max(total, 1.0):
        raise InvalidParameter(
            "session total duration",
            round(total, 9),
            f"equal to the run's duration, {config.duration_s:g} s",
            f"the sum of its {len(session.segments)} segments' durations [s]",
        )
    if config.mode != "tracking":
        raise InvalidParameter("mode", config.mode, "tracking (unset) with a session")
    if config.exercise != "gait":
        raise InvalidParameter("session", session.source, "unset", "the calibration swing tracks")
    for i, seg in enumerate(session.segments, start=1):
        if seg.mode in ("aan", "path") and (not config.plan_layout.period or config.synced):
            raise InvalidParameter(
                f"session segment {i} mode",
                seg.mode,
                "tracking, guidance or transparent here",
                "it follows the phase of a precomputed periodic plan: "
                + periodic_plan_needs(config),
            )
        if seg.belt_speed_mps is not None and not config.contact.enabled:
            raise InvalidParameter(
                f"session segment {i} belt_speed",
                seg.belt_speed_mps,
                "unset without the belt (contact on)",
            )


def session_controller(
    config: Any, plan: Any, exo: Any, motor: Any, tracking: Any, patient: Any = None
) -> SwitchedController:
    """The session's controllers, one per segment, behind a bumpless switch.

    Args:
        config: the run (its ``session``, ``modes``, ``path``, gains, Δt).
        plan: the joint plan.
        exo: the exoskeleton model the DEVICE holds.
        motor: the drive the device believes in.
        tracking: a function returning a new tracking controller (the run's
            PD, CT or QP), one per segment that tracks or guides.
        patient: the patient model the DEVICE holds (path's wall damping).

    """
    session: SessionParams = config.session
    controllers, names = [], []
    for seg in session.segments:
        modes = seg.mode_params(config.modes)
        if seg.mode == "tracking":
            ctrl = tracking()
        elif seg.mode == "path":
            ctrl = PathController(
                seg.path_params(config.path),
                modes,
                plan,
                exo,
                motor,
                config.dt,
                config.estimator,
                patient=patient,
            )
        else:
            inner = tracking() if seg.mode == "guidance" else None
            ctrl = InteractionController(
                seg.mode, modes, plan, exo, motor, inner, config.dt, config.estimator
            )
        controllers.append(ctrl)
        names.append(seg.mode)
    starts = [round(t / config.dt) for t in session.starts_s]
    blend = round(session.blend_s / config.dt)
    return SwitchedController(controllers, names, starts, blend, config.dt)
