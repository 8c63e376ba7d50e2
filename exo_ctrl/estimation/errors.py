r"""Errors of estimated cuff-force normal components against the simulated truth.

The estimate of a cuff's normal component f̂⊥ is compared with the normal
component n(q) · f of the true force on the exoskeleton (n of
:mod:`exo_ctrl.estimation.cuff_geometry`), per cuff in CUFF_NAMES order:

    e = f̂⊥ − n(q) · f,   RMS = √(mean e²),   relative = RMS / max |n(q) · f|.

The relative figure is given only where its denominator means something: a
cuff whose true normal force never reaches :data:`REL_FLOOR_N` (1 N, below
the torque sensors' noise seen through the lever arms) gets NaN, written as
``null`` in JSON summaries.

:func:`normal_component_errors` compares whole series; :class:`EstimateErrorStats`
keeps the same sums chunk by chunk while :func:`exo_ctrl.sim.loop.simulate`
runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from .._jit import kernel, preload, record
from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, BodyModel
from .cuff_geometry import GEOMETRY_FIELDS, _cuff_directions, _geometry, cuff_normal_components

__all__ = ["REL_FLOOR_N", "EstimateErrorStats", "EstimateErrors", "normal_component_errors"]

#: Smallest peak true normal force [N] a relative error is given for (else NaN).
REL_FLOOR_N = 1.0


def _relative(rms: np.ndarray, peak: np.ndarray) -> np.ndarray:
    """The RMS over the peak per cuff, NaN where peak < :data:`REL_FLOOR_N`."""
    return np.divide(rms, peak, out=np.full(rms.shape, np.nan), where=peak >= REL_FLOOR_N)


@dataclass
class EstimateErrors:
    """Errors of estimated normal components against the truth, per cuff.

    Attributes:
        rms_error_N: RMS of (estimate − true normal component) [N], (4,).
        max_error_N: largest |estimate − true| [N], (4,).
        peak_true_N: peak |true normal component| [N], (4,).
        rms_error_rel: rms_error_N / peak_true_N [-], (4,); NaN where
            peak_true_N < :data:`REL_FLOOR_N`.
        rows: number of rows compared.
        rms_true_N: RMS of the true normal component [N], (4,), or None
            where it is not kept (:class:`EstimateErrorStats`).

    """

    rms_error_N: np.ndarray
    max_error_N: np.ndarray
    peak_true_N: np.ndarray
    rms_error_rel: np.ndarray
    rows: int
    rms_true_N: np.ndarray | None = None

    def summary(self) -> dict[str, dict[str, float | None]]:
        """``cuff_force_estimate_rms_error_N`` and ``…_rel``, keyed by cuff (NaN as None)."""

        def keyed(x: np.ndarray) -> dict[str, float | None]:
            return {
                c: float(val) if math.isfinite(val) else None
                for c, val in zip(CUFF_NAMES, x, strict=True)
            }

        return {
            "cuff_force_estimate_rms_error_N": keyed(self.rms_error_N),
            "cuff_force_estimate_rms_error_rel": keyed(self.rms_error_rel),
        }


def normal_component_errors(
    q_exo: np.ndarray,
    cuff_force_true: np.ndarray,
    normal_est: np.ndarray,
    exo: BodyModel | None = None,
    skip: int = 0,
    lag: int = 0,
) -> EstimateErrors:
    """Compare estimated normal components with the true cuff forces.

    Row k of the estimate is compared with the normal component of row
    k − ``lag`` of the truth, taken along the normals at q_exo row k.  In
    :func:`exo_ctrl.sim.loop.simulate` row k of ``cuff_force`` is the force
    over [t_k, t_k+1), while the estimate of tick k uses the sensor torque of
    [t_{k-1}, t_k]: pass ``lag=1`` there (as :class:`EstimateErrorStats`
    does).

    Args:
        q_exo: true exoskeleton joint angles [rad], (N, 4), rows as the estimate.
        cuff_force_true: true cuff forces on the exoskeleton [N], (N, 4, 2).
        normal_est: estimated normal components [N], (N, 4).
        exo: the exoskeleton model (None: the default URDF).
        skip: estimate rows to leave out at the start (the observer's
            start-up, a few 1/K_O).
        lag: rows by which the estimate trails the truth.

    Raises:
        InvalidParameter: fewer than one row is left to compare.

    """
    q = np.asarray(q_exo, dtype=float)
    force = np.asarray(cuff_force_true, dtype=float)
    est = np.asarray(normal_est, dtype=float)
    n = est.shape[0]
    start = max(skip, lag)
    if n - start < 1 or force.shape[0] < n - lag or q.shape[0] < n:
        raise InvalidParameter("skip", skip, f"< {n - lag} rows with these series")
    truth = cuff_normal_components(q[start:n], force[start - lag : n - lag], exo)
    err = est[start:n] - truth
    rms = np.sqrt(np.mean(err**2, axis=0))
    peak = np.max(np.abs(truth), axis=0)
    return EstimateErrors(
        rms_error_N=rms,
        max_error_N=np.max(np.abs(err), axis=0),
        peak_true_N=peak,
        rms_error_rel=_relative(rms, peak),
        rows=int(err.shape[0]),
        rms_true_N=np.sqrt(np.mean(truth**2, axis=0)),
    )


#: :class:`EstimateErrorStats`' record: the cuff geometry, the last row's true
#: force (x, z) per cuff [N], and per cuff Σ e² [N²], max |e| [N], max |truth| [N].
_STATS_FIELDS = [
    *GEOMETRY_FIELDS,
    ("prev_force", np.float64, (4, 2)),
    ("sq_error_sum", np.float64, (4,)),
    ("max_error", np.float64, (4,)),
    ("peak_true", np.float64, (4,)),
]


class EstimateErrorStats:
    """Running errors of a live estimate against the simulated truth, chunk by chunk.

    Fed with the rows :func:`exo_ctrl.sim.loop.simulate` logs: ``q`` (true
    exoskeleton angles at t_k), ``cuff_force`` (true force over
    [t_k, t_k+1)) and the estimate of tick k.  The estimate of tick k uses
    the torque reading of the step just taken, so it is compared with the
    previous row's force (carried across chunks): the pairing of
    :func:`normal_component_errors` with ``lag=1``.  Rows before ``skip_s``
    (the observer's start-up) are left out.

    Args:
        exo: the exoskeleton model (None: the default URDF).
        dt: control period [s].
        skip_s: start-up left out [s] (default 50 ms, five time constants of
            the default observer).

    Attributes:
        record: the geometry and the running sums, a one-element structured
            array (fields ``sq_error_sum``, ``max_error``, ``peak_true`` (4,)).
        rows: rows seen so far (compared or not).

    """

    def __init__(self, exo: BodyModel | None, dt: float, skip_s: float = 0.05) -> None:
        self.exo = exo
        self.skip = round(v.non_negative("skip", skip_s, "s") / v.positive("dt", dt, "s"))
        self.rows = 0
        self.record = record(_STATS_FIELDS)
        _geometry(exo).fill(self.record)
        self._prev_force = self.record["prev_force"][0]  # the last row's, once a row was seen
        self._n = 0

    def update(self, q: np.ndarray, cuff_force: np.ndarray, normal_est: np.ndarray) -> None:
        """Add rows: q (n, 4) [rad], cuff_force (n, 4, 2) [N], normal_est (n, 4) [N]."""
        n = np.shape(q)[0]
        if n == 0:
            return
        # Truth paired with row i: the force of row i - 1 (the previous chunk's last).
        start = max(self.skip - self.rows, 0 if self.rows else 1)
        if start < n:
            _error_sums(self.record, q, cuff_force, normal_est, start)
            self._n += n - start
        self._prev_force[:] = cuff_force[-1]
        self.rows += n

    def preload(self, q: np.ndarray, cuff_force: np.ndarray, normal_est: np.ndarray) -> None:
        """Load the compiled kernel for rows of these arrays' types (before a timed run)."""
        preload(_error_sums, self.record, q, cuff_force, normal_est, 0)

    def result(self) -> EstimateErrors:
        """The errors so far (zeros before any compared row, relative NaN then)."""
        sums = self.record[0]
        rms = np.sqrt(sums["sq_error_sum"] / max(self._n, 1))
        peak = sums["peak_true"]
        return EstimateErrors(
            rms_error_N=rms,
            max_error_N=sums["max_error"].copy(),
            peak_true_N=peak.copy(),
            rms_error_rel=_relative(rms, peak),
            rows=self._n,
        )

    def summary(self) -> dict[str, dict[str, float | None]]:
        """``cuff_force_estimate_rms_error_N`` and ``…_rel`` keyed by cuff (NaN as None)."""
        return self.result().summary()


@kernel
def _error_sums(state, q, force, normal_est, start):
    """Add rows start… to :class:`EstimateErrorStats`' sums (Σ e², max |e|, max |truth|).

    The truth of row i is the normal component n(q_i) · f_{i-1} of the
    previous row's force (``prev_force`` of the record for row 0), per cuff
    in CUFF_NAMES order, with ψ_t = ψ_t0 + s_h q_hip and
    ψ_s = ψ_s0 + s_h q_hip + s_k q_knee (:meth:`CuffGeometry.directions`).
    """
    st = state[0]
    for r in range(start, q.shape[0]):
        for s in range(2):
            psi_t, psi_s = _cuff_directions(
                st.sign_hip[s],
                st.sign_knee[s],
                st.thigh_dir0[s],
                st.shank_dir0[s],
                q[r, 2 * s],
                q[r, 2 * s + 1],
            )
            for c in range(2 * s, 2 * s + 2):
                psi = psi_t if c == 2 * s else psi_s
                if r == 0:
                    fx, fz = st.prev_force[c, 0], st.prev_force[c, 1]
                else:
                    fx, fz = force[r - 1, c, 0], force[r - 1, c, 1]
                truth = -math.sin(psi) * fx + math.cos(psi) * fz
                err = normal_est[r, c] - truth
                st.sq_error_sum[c] += err * err
                st.max_error[c] = max(st.max_error[c], abs(err))
                st.peak_true[c] = max(st.peak_true[c], abs(truth))
