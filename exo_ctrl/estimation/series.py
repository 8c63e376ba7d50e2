r"""The live estimators run along a logged series of sensor readings.

:func:`estimate_series` steps the same
:class:`~exo_ctrl.estimation.observer.CuffForceEstimator` as the live loop
along rows (t_k, q_k, q̇_k, τ_k): row 0 starts the observer, row k > 0
advances it by h_k = t_k − t_{k-1} (or a fixed control period), so the
sensor readings logged every tick reproduce the live estimate exactly.
:func:`kalman_series` does the same with a
:class:`~exo_ctrl.estimation.kalman.CuffForceKalman` built on the device's
models (its step is the filter's fixed control period).

:func:`first_order_filter` is the observer's own filter,
y_k = y_{k-1} + (1 − e^{−K_O h}) (x_k − y_{k-1}), for the exact observer's
answer to a known truth.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidLog, InvalidParameter
from ..model import BodyModel
from .kalman import CuffForceKalman
from .observer import DEFAULT_GAIN_PER_S, CuffForceEstimator

__all__ = ["EstimateSeries", "estimate_series", "first_order_filter", "kalman_series"]


@dataclass
class EstimateSeries:
    """An estimator's output along a logged series.

    Attributes:
        t: times [s], (N,).
        normal: estimated normal components f⊥ [N], (N, 4), CUFF_NAMES order.
        force: estimated cuff forces on the exoskeleton [N], (N, 4, 2): f⊥ n
            from the momentum observer, every component from the Kalman filter.
        tau_ext: external joint torques r [N·m], (N, 4), JOINT_NAMES order.
        gain_per_s: the momentum observer's gain used [1/s] (None: the
            Kalman filter, which has none).
        estimator: ``"momentum"`` or ``"kalman"``
            (:data:`~exo_ctrl.estimation.kalman.ESTIMATORS`).

    """

    t: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    tau_ext: np.ndarray
    gain_per_s: float | None
    estimator: str = "momentum"


def _check_series(
    t: np.ndarray, q: np.ndarray, dq: np.ndarray | None, tau: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """(t, q, dq, tau) as float arrays of shapes (N,), (N, 4) each (dq may be None).

    Raises:
        InvalidLog: a shape differs, a value is not finite, N < 2, or t is
            not strictly increasing.

    """
    t = np.asarray(t, dtype=float)
    arrays = {"q": q, "tau": tau} if dq is None else {"q": q, "dq": dq, "tau": tau}
    if t.ndim != 1 or t.shape[0] < 2:
        raise InvalidLog("arrays", f"t must have shape (N,) with N >= 2; got {t.shape}")
    out = {}
    for name, arr in arrays.items():
        a = np.asarray(arr, dtype=float)
        if a.shape != (t.shape[0], 4):
            raise InvalidLog(
                "arrays", f"{name} must have shape ({t.shape[0]}, 4) like t; got {a.shape}"
            )
        out[name] = a
    for name, a in {"t": t, **out}.items():
        bad = np.flatnonzero(~np.all(np.isfinite(a.reshape(a.shape[0], -1)), axis=1))
        if bad.size:
            raise InvalidLog("arrays", f"{name} has a non-finite value in row {bad[0]}")
    steps = np.diff(t)
    if not np.all(steps > 0):
        i = int(np.flatnonzero(~(steps > 0))[0])
        raise InvalidLog(
            "arrays",
            f"t must be strictly increasing; t[{i + 1}] = {float(t[i + 1])!r} <= t[{i}]",
        )
    return t, out["q"], out.get("dq"), out["tau"]


def estimate_series(
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray | None,
    tau_sensor: np.ndarray,
    exo: BodyModel,
    gain_per_s: float = DEFAULT_GAIN_PER_S,
    dt: float | None = None,
    torque_bias_Nm: np.ndarray | float = 0.0,
    stiffness_ratio: float = 1.0,
) -> EstimateSeries:
    """Run the momentum observer along a logged series of sensor readings.

    Row 0 starts the observer (estimate zero); row k > 0 advances it by
    h_k = t_k − t_{k-1} (or ``dt``), exactly as
    :meth:`~exo_ctrl.estimation.observer.CuffForceEstimator.update` does
    live, so the logged readings of a run reproduce its live estimate.

    Args:
        t: times [s], (N,), strictly increasing.
        q: encoder joint angles [rad], (N, 4), JOINT_NAMES order.
        dq: joint speeds [rad/s], (N, 4); None: central differences of q
            (``numpy.gradient``; then the result differs from a live estimate
            that used the sensors' own speed).
        tau_sensor: joint torque sensor readings [N·m], (N, 4).
        exo: the exoskeleton model.
        gain_per_s: observer gain K_O [1/s].
        dt: a fixed step [s] to use for every row (the control period of a
            recorded run, so that the estimate matches the live one to
            rounding); None: the differences of t.
        torque_bias_Nm: a known torque-sensor bias to subtract [N·m].
        stiffness_ratio: κ of the assumption (see
            :class:`~exo_ctrl.estimation.observer.CuffForceEstimator`).

    Returns:
        The estimate at every row.

    Raises:
        InvalidLog: shapes differ, a value is not finite, t does not increase,
            or the estimate is not finite (readings too large for the model).

    """
    t, q, dq, tau = _check_series(t, q, dq, tau_sensor)
    if dq is None:
        dq = np.gradient(q, t, axis=0)
    if dt is not None:
        v.positive("dt", dt, "s")
        steps = np.diff(t)
        if np.max(np.abs(steps - dt)) > 1e-6 * dt + 1e-12:
            raise InvalidLog("arrays", f"t is not sampled every dt = {dt!r} s")
    est = CuffForceEstimator(
        exo,
        dt if dt is not None else float(t[1] - t[0]),
        gain_per_s,
        torque_bias_Nm,
        stiffness_ratio,
    )
    n = t.shape[0]
    normal = np.zeros((n, 4))
    force = np.zeros((n, 4, 2))
    tau_ext = np.zeros((n, 4))
    for k in range(n):
        h = dt if dt is not None else (t[k] - t[k - 1] if k else 1.0)
        est.step(q[k], dq[k], tau[k], h)
        normal[k] = est.normal
        force[k] = est.force
        tau_ext[k] = est.tau_ext
    _require_finite(t, normal)
    return EstimateSeries(t=t, normal=normal, force=force, tau_ext=tau_ext, gain_per_s=gain_per_s)


def _require_finite(t: np.ndarray, normal: np.ndarray) -> None:
    """Refuse an estimate that is not finite: finite readings too large for the model.

    Raises:
        InvalidLog: naming the first sample whose estimate is not finite.

    """
    bad = ~np.all(np.isfinite(normal), axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidLog(
            "arrays",
            f"the estimate is not finite from sample {k} (t = {float(t[k])!r} s) on: "
            "the readings there are finite but beyond what the model can take "
            "(the dynamics overflow)",
        )


def kalman_series(
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray | None,
    tau_sensor: np.ndarray,
    kalman: CuffForceKalman,
    torque_rates: Sequence[tuple[int, float | None]] = (),
    cuff_readings: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> EstimateSeries:
    """Run a fresh Kalman filter along a logged series of sensor readings.

    Row 0 starts the filter at its readings (the nominal patient settled in
    the cuffs, :meth:`~exo_ctrl.estimation.kalman.CuffForceKalman.step`);
    row k > 0 advances it by its control period h, exactly as the live loop
    does, so the readings a run logged reproduce its live estimate when the
    filter is built on the run's device models.  The rows must be sampled
    every h: the filter's process noise and transition are made for h.

    Args:
        t: times [s], (N,), strictly increasing, t_k − t_{k-1} = h.
        q: encoder joint angles [rad], (N, 4), JOINT_NAMES order.
        dq: joint speeds [rad/s], (N, 4) (used only to start); None: central
            differences of q.
        tau_sensor: joint torque sensor readings [N·m], (N, 4).
        kalman: the filter, on the device's exoskeleton, patient, cuff and
            sensor models; it is restarted (:meth:`~CuffForceKalman.reset`).
        torque_rates: (row, σ_d) pairs: before stepping that row the filter's
            σ_d is set (:meth:`~CuffForceKalman.set_torque_rate`; None: its
            own), as the live run's modes set it.
        cuff_readings: the cuff sensors' logged readings, (normal [N] (N, 4),
            along [N] (N, 4), fresh (N,): nonzero on a new sample), put into
            the filter's readings record (:attr:`~CuffForceKalman.cuff_meas`)
            before each row's step, as the live sensors' read does; None: no
            cuff sensors.  Needs a filter built with cuff sensors.

    Raises:
        InvalidLog: shapes differ, a value is not finite, t does not
            increase, t is not sampled every h, or the estimate is not finite.
        InvalidParameter: cuff readings for a filter without cuff sensors.

    """
    t, q, dq, tau = _check_series(t, q, dq, tau_sensor)
    if dq is None:
        dq = np.gradient(q, t, axis=0)
    h = kalman.dt
    if np.max(np.abs(np.diff(t) - h)) > 1e-6 * h + 1e-12:
        raise InvalidLog("arrays", f"t is not sampled every dt = {h!r} s (the filter's period)")
    kalman.reset()
    n = t.shape[0]
    normal = np.zeros((n, 4))
    force = np.zeros((n, 4, 2))
    tau_ext = np.zeros((n, 4))
    rates = dict(torque_rates)
    meas = kalman.cuff_meas
    if cuff_readings is not None and meas is None:
        raise InvalidParameter("cuff_readings", "given", "None for a filter without cuff sensors")
    for k in range(n):
        if k in rates:
            kalman.set_torque_rate(rates[k])
        if cuff_readings is not None:
            meas["reading"][0, :, 0] = cuff_readings[0][k]
            meas["reading"][0, :, 1] = cuff_readings[1][k]
            meas["fresh"] = cuff_readings[2][k] != 0.0
        kalman.step(q[k], dq[k], tau[k])
        normal[k] = kalman.normal
        force[k] = kalman.force
        tau_ext[k] = kalman.tau_ext
    _require_finite(t, normal)
    return EstimateSeries(t, normal, force, tau_ext, gain_per_s=None, estimator="kalman")


def first_order_filter(x: np.ndarray, dt: float, gain_per_s: float) -> np.ndarray:
    """The observer's own filter applied to a series: y_k = y_{k-1} + α (x_k − y_{k-1}).

    α = 1 − e^{−K_O dt}, y_0 = 0 (as the observer starts at zero).  Applied to
    the true external torques (or cuff forces) aligned with the readings, it
    gives what an exact observer would output, separating the observer's lag
    from its errors.

    Args:
        x: series, (N, …).
        dt: sampling period [s].
        gain_per_s: K_O [1/s].

    """
    x = np.asarray(x, dtype=float)
    alpha = -math.expm1(-v.positive("gain", gain_per_s, "1/s") * v.positive("dt", dt, "s"))
    y = np.zeros_like(x)
    for k in range(1, x.shape[0]):
        y[k] = y[k - 1] + alpha * (x[k] - y[k - 1])
    return y
