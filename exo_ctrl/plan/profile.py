"""A session's belt-speed profile: the set speed a therapist schedules over time.

``"T1:V1,T2:V2,..."`` (s and m/s) is a piecewise-linear speed v(t) through
the points (T_i, V_i): times strictly increasing and ≥ 0, speeds ≥
:data:`MIN_SPEED_MPS`.
Before T1 the profile holds V1, after the last point the last speed:

    v(t) = V_1                                             t ≤ T_1
    v(t) = V_i + (V_{i+1} - V_i) (t - T_i) / (T_{i+1} - T_i)   T_i ≤ t < T_{i+1}
    v(t) = V_n                                             t ≥ T_n

and its rate v̇(t) is the slope of the piece (0 outside the points; at a
point, the slope of the piece that starts there).  The belt's drive follows
σ(t) v(t) during the ramp-in from standing (:mod:`exo_ctrl.plan.ramp`).
The gait's adaptation to the speed is :mod:`exo_ctrl.plan.adapt`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._jit import kernel
from ..exceptions import InvalidParameter

__all__ = ["MIN_SPEED_MPS", "PROFILE_FORMAT", "SpeedProfile", "profile_at"]

#: The slowest belt a profile sets [m/s]: the adapted gait's period grows as
#: 1/√v (:mod:`exo_ctrl.plan.adapt`), to about 9 s at 0.01 m/s for the default
#: gait, and without bound below.
MIN_SPEED_MPS = 0.01

#: What a profile's text must look like (the messages quote it).
PROFILE_FORMAT = 'points T:V separated by commas, T in s and V in m/s (e.g. "0:0.4,3:0.7")'


@dataclass(frozen=True)
class SpeedProfile:
    """A piecewise-linear belt set speed (module docstring).

    Attributes:
        times: T_i [s], strictly increasing, ≥ 0.
        speeds: V_i [m/s], ≥ :data:`MIN_SPEED_MPS`, one per time.

    Raises:
        InvalidParameter: ``speed_profile`` with no point, times and speeds
            of different lengths, a value that is not a finite number, a
            negative time, times out of order or a speed below
            :data:`MIN_SPEED_MPS` (the point named).

    """

    times: tuple[float, ...]
    speeds: tuple[float, ...]

    def __post_init__(self) -> None:
        text = self.text()
        try:
            times = tuple(float(t) for t in self.times)
            speeds = tuple(float(s) for s in self.speeds)
        except (TypeError, ValueError):
            raise InvalidParameter("speed_profile", text, PROFILE_FORMAT) from None
        if not times or len(times) != len(speeds):
            raise InvalidParameter("speed_profile", text, PROFILE_FORMAT)
        for i, (t, s) in enumerate(zip(times, speeds, strict=True)):
            where = f"point {i + 1}, {t:g}:{s:g}"
            if not (math.isfinite(t) and math.isfinite(s)):
                raise InvalidParameter("speed_profile", text, "finite times and speeds", where)
            if t < 0.0:
                raise InvalidParameter("speed_profile", text, "times >= 0 s", where)
            if s < MIN_SPEED_MPS:
                raise InvalidParameter(
                    "speed_profile", text, f"speeds >= {MIN_SPEED_MPS:g} m/s", where
                )
            if i and t <= times[i - 1]:
                raise InvalidParameter(
                    "speed_profile",
                    text,
                    "times in increasing order",
                    f"{where} is not after {times[i - 1]:g} s",
                )
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "speeds", speeds)

    @classmethod
    def parse(cls, text: str) -> SpeedProfile:
        """The profile of ``"T1:V1,T2:V2,..."``.

        Raises:
            InvalidParameter: malformed text (:data:`PROFILE_FORMAT`), or a
                profile :class:`SpeedProfile` refuses.

        """
        if not isinstance(text, str):
            raise InvalidParameter("speed_profile", text, PROFILE_FORMAT)
        times, speeds = [], []
        for item in text.split(","):
            parts = item.split(":")
            try:
                if len(parts) != 2:
                    raise ValueError(item)
                times.append(float(parts[0]))
                speeds.append(float(parts[1]))
            except ValueError:
                raise InvalidParameter(
                    "speed_profile", text, PROFILE_FORMAT, f"{item.strip()!r} is not T:V"
                ) from None
        return cls(tuple(times), tuple(speeds))

    @classmethod
    def constant(cls, speed_mps: float) -> SpeedProfile:
        """A profile that holds one speed [m/s]."""
        return cls((0.0,), (speed_mps,))

    def text(self) -> str:
        """The ``"T1:V1,..."`` form."""
        try:
            return ",".join(f"{t:g}:{s:g}" for t, s in zip(self.times, self.speeds, strict=True))
        except (TypeError, ValueError):
            return repr((self.times, self.speeds))

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(T_i [s], V_i [m/s]) as contiguous float arrays (for :func:`profile_at`)."""
        return np.array(self.times, dtype=float), np.array(self.speeds, dtype=float)

    def at(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """v(t) [m/s] and v̇(t) [m/s²] at times ``t`` [s] (module docstring)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        times, speeds = self.arrays()
        v = np.interp(t, times, speeds)
        rate = np.zeros_like(t)
        if times.size > 1:
            slope = np.diff(speeds) / np.diff(times)
            piece = np.searchsorted(times, t, side="right") - 1
            inside = (piece >= 0) & (piece < times.size - 1)
            rate[inside] = slope[piece[inside]]
        return v, rate

    @property
    def speed_range(self) -> tuple[float, float]:
        """(slowest, fastest) speed of the profile [m/s]: at its points."""
        return min(self.speeds), max(self.speeds)


@kernel
def profile_at(times: np.ndarray, speeds: np.ndarray, t: float) -> tuple[float, float]:
    """v(t) [m/s] and v̇(t) [m/s²] of the points (``times``, ``speeds``): :meth:`SpeedProfile.at`."""
    n = times.shape[0]
    if t < times[0]:
        return speeds[0], 0.0
    for i in range(n - 1):
        if t < times[i + 1]:
            slope = (speeds[i + 1] - speeds[i]) / (times[i + 1] - times[i])
            return speeds[i] + slope * (t - times[i]), slope
    return speeds[n - 1], 0.0
