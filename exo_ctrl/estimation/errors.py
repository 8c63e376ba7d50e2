r"""Errors of estimated cuff forces against the simulated truth.

**The headline: the whole force.**  Per cuff (CUFF_NAMES order) the estimated
2-D force f̂ (every component the estimator gives, the ones it assumes
included) is compared with the true force f on the exoskeleton:

    RMS = √(mean |f̂ − f|²),   relative = RMS / √(mean |f|²)

(``cuff_force_estimate_rms_error_N`` and ``cuff_force_estimate_rms_error_rel``
in the summaries).  It counts the along-link components, which the joint
torques cannot see (:mod:`.cuff_geometry`) and which are the largest on the
shank: an estimator that is blind to them shows it here.

**The normal component alone** (the figure before, kept under its precise
names ``cuff_force_estimate_normal_rms_error_N`` and
``cuff_force_estimate_normal_rms_over_peak``): the estimate f̂⊥ against
n(q) · f (n of :mod:`exo_ctrl.estimation.cuff_geometry`),

    e = f̂⊥ − n(q) · f,   RMS = √(mean e²),   relative = RMS / max |n(q) · f|.

A relative figure is given only where its denominator means something: a
cuff whose RMS true force (whole figure) or peak true normal force (normal
figure) is below :data:`REL_FLOOR_N` (1 N, below the torque sensors' noise
seen through the lever arms) gets NaN, written as ``null`` in JSON summaries.

**Per component, over its RMS, after the ramp-in**
(``cuff_force_estimate_normal_rms_error_over_rms``,
``cuff_force_estimate_along_rms_error_N`` and
``cuff_force_estimate_along_rms_error_over_rms``): the normal component's
RMS error over the RMS of the true normal component, and the along-link
component's, f̂∥ = u(q) · f̂ against u(q) · f (u of
:mod:`~exo_ctrl.estimation.cuff_geometry`), over the RMS true along
component,

    e⊥ = f̂⊥ − n · f,   e∥ = u · f̂ − u · f,
    relative = √(mean e²) / √(mean (n · f)²)  (and u · f for e∥),

over the rows from ``cuff_force_estimate_components_from_s`` on (a live
run: the end of the gait's ramp-in, at least the start-up; the walking at
speed, not the ramp's small forces).  These say which half of a force an estimate gets right: the
joint torques observe some components, models supply the others
(``cuff_force_estimate_components``: :data:`OBSERVER_COMPONENTS` for the
momentum observer, :func:`~exo_ctrl.estimation.kalman.kalman_components` for the
filter).

``cuff_force_estimate_unobservable`` lists, per cuff, the components the
estimator cannot observe from the joint torques (:data:`UNOBSERVABLE`).

:func:`normal_component_errors` compares whole series; :class:`EstimateErrorStats`
keeps the same sums chunk by chunk while :func:`exo_ctrl.sim.loop.simulate`
runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import kernel, preload, record
from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, BodyModel
from .cuff_geometry import GEOMETRY_FIELDS, _cuff_directions, _geometry, cuff_components
from .kalman import kalman_components

__all__ = [
    "OBSERVER_COMPONENTS",
    "REL_FLOOR_N",
    "STARTUP_S",
    "UNOBSERVABLE",
    "EstimateErrorStats",
    "EstimateErrors",
    "estimate_components",
    "normal_component_errors",
]

#: Smallest true force [N] (RMS magnitude, or peak normal component) a relative error
#: is given for (else NaN).
REL_FLOOR_N = 1.0

#: The start-up a live run's error figures leave out [s]: five time constants
#: of the default momentum observer (K_O = 100 /s), whichever estimator runs.
STARTUP_S = 0.05

#: What the joint torques cannot observe, per cuff (:mod:`.cuff_geometry`): the
#: thigh cuff's along-thigh force has no lever arm (the estimate assumes it
#: zero); the shank cuff's along-shank force is seen only in a sum with the
#: thigh's normal force (the estimate takes it from the assumption κ).
UNOBSERVABLE: dict[str, list[str]] = {
    cuff: [
        "along the thigh (no lever arm: assumed 0)"
        if cuff.endswith("thigh")
        else "along the shank (seen only with the thigh's normal force: from the assumption κ)"
    ]
    for cuff in CUFF_NAMES
}


#: Per cuff and component, where the momentum observer's estimate comes from
#: (the observer's twin of :data:`~exo_ctrl.estimation.kalman.COMPONENTS`).
OBSERVER_COMPONENTS: dict[str, dict[str, str]] = {
    cuff: (
        {
            "normal": "seen by the hip torque together with the shank's along-shank force; "
            "split between them by the assumption κ",
            "along": "assumed 0: no joint torque sees it",
        }
        if cuff.endswith("thigh")
        else {
            "normal": "observed: the knee torque",
            "along": "from the assumption κ: seen by the hip torque only together with the "
            "thigh's normal force",
        }
    )
    for cuff in CUFF_NAMES
}


def estimate_components(estimator: str, cuff_sensors: str = "none") -> dict[str, dict[str, str]]:
    """Per cuff and component, where ``estimator``'s estimate comes from (a copy).

    ``"kalman"``: :func:`~exo_ctrl.estimation.kalman.kalman_components` with
    the run's cuff sensors (``"none"``, ``"normal"``, ``"full"``); otherwise
    the momentum observer's :data:`OBSERVER_COMPONENTS` (it fuses no cuff sensor).
    """
    if estimator == "kalman":
        return kalman_components(cuff_sensors)
    return {cuff: dict(parts) for cuff, parts in OBSERVER_COMPONENTS.items()}


def _relative(rms: np.ndarray, peak: np.ndarray) -> np.ndarray:
    """The RMS over the peak per cuff, NaN where peak < :data:`REL_FLOOR_N`."""
    return np.divide(rms, peak, out=np.full(rms.shape, np.nan), where=peak >= REL_FLOOR_N)


@dataclass
class EstimateErrors:
    """Errors of an estimate against the truth, per cuff (module docstring).

    Attributes:
        rms_error_N: RMS of (estimate − true normal component) [N], (4,).
        max_error_N: largest |estimate − true| normal component [N], (4,).
        peak_true_N: peak |true normal component| [N], (4,).
        rms_error_rel: rms_error_N / peak_true_N [-], (4,); NaN where
            peak_true_N < :data:`REL_FLOOR_N` (the normal figure).
        rows: number of rows compared.
        rms_true_N: RMS of the true normal component [N], (4,), or None
            where it is not kept (:class:`EstimateErrorStats`).
        vector_rms_error_N: √(mean |f̂ − f|²) of the 2-D forces [N], (4,), or
            None without the estimated forces.
        vector_rms_true_N: √(mean |f|²) of the true forces [N], (4,), or None.
        vector_rms_error_rel: their ratio [-], (4,), NaN where
            vector_rms_true_N < :data:`REL_FLOOR_N`; or None.
        along_rms_error_N: RMS of (u · f̂ − u · f), the along-link component [N],
            (4,), or None without the estimated forces.
        along_rms_true_N: RMS of u · f [N], (4,), or None.
        normal_component_rms_error_N: RMS of the normal component's error over
            the component rows [N], (4,), or None: the same rows as
            ``rms_true_N`` and the along figures (from ``components_from_row``).
        components_from_row: the first row (of the estimate) the component
            figures cover.
        components_from_s: the same as a time [s], or None where not known
            (the summary's ``cuff_force_estimate_components_from_s``).

    """

    rms_error_N: np.ndarray
    max_error_N: np.ndarray
    peak_true_N: np.ndarray
    rms_error_rel: np.ndarray
    rows: int
    rms_true_N: np.ndarray | None = None
    vector_rms_error_N: np.ndarray | None = None
    vector_rms_true_N: np.ndarray | None = None
    vector_rms_error_rel: np.ndarray | None = None
    along_rms_error_N: np.ndarray | None = None
    along_rms_true_N: np.ndarray | None = None
    normal_component_rms_error_N: np.ndarray | None = None
    components_from_row: int = 0
    components_from_s: float | None = None

    def summary(self) -> dict[str, Any]:
        """The summary entries, keyed by cuff (NaN as None; module docstring).

        ``cuff_force_estimate_rms_error_N``, ``…_rms_error_rel`` (whole force;
        only with the estimated forces), ``…_normal_rms_error_N``,
        ``…_normal_rms_over_peak``, ``…_normal_rms_error_over_rms``,
        ``…_along_rms_error_N`` and ``…_along_rms_error_over_rms`` (with the
        estimated forces), ``…_components_from_s`` (where the component
        figures start, when known) and ``…_unobservable`` (a list: "cuff:
        component").
        """

        def keyed(x: np.ndarray) -> dict[str, float | None]:
            return {
                c: float(val) if math.isfinite(val) else None
                for c, val in zip(CUFF_NAMES, x, strict=True)
            }

        out: dict[str, Any] = {}
        if self.vector_rms_error_N is not None and self.vector_rms_error_rel is not None:
            out["cuff_force_estimate_rms_error_N"] = keyed(self.vector_rms_error_N)
            out["cuff_force_estimate_rms_error_rel"] = keyed(self.vector_rms_error_rel)
        out["cuff_force_estimate_normal_rms_error_N"] = keyed(self.rms_error_N)
        out["cuff_force_estimate_normal_rms_over_peak"] = keyed(self.rms_error_rel)
        if self.rms_true_N is not None:
            late = self.normal_component_rms_error_N
            normal_rel = _relative(self.rms_error_N if late is None else late, self.rms_true_N)
            out["cuff_force_estimate_normal_rms_error_over_rms"] = keyed(normal_rel)
        if self.along_rms_error_N is not None and self.along_rms_true_N is not None:
            out["cuff_force_estimate_along_rms_error_N"] = keyed(self.along_rms_error_N)
            along_rel = _relative(self.along_rms_error_N, self.along_rms_true_N)
            out["cuff_force_estimate_along_rms_error_over_rms"] = keyed(along_rel)
        if self.components_from_s is not None:
            out["cuff_force_estimate_components_from_s"] = self.components_from_s
        out["cuff_force_estimate_unobservable"] = [
            f"{c}: {what}" for c, x in UNOBSERVABLE.items() for what in x
        ]
        return out


def normal_component_errors(
    q_exo: np.ndarray,
    cuff_force_true: np.ndarray,
    normal_est: np.ndarray,
    exo: BodyModel | None = None,
    skip: int = 0,
    lag: int = 0,
    force_est: np.ndarray | None = None,
    components_from: int | None = None,
) -> EstimateErrors:
    """Compare estimated normal components (and forces) with the true cuff forces.

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
        force_est: estimated 2-D forces on the exoskeleton [N], (N, 4, 2), rows
            as ``normal_est``: gives the whole-force figures (module docstring).
        components_from: the first estimate row of the per-component figures
            (``rms_true_N``, ``normal_component_rms_error_N``, the along
            figures; a live run's: the end of the ramp-in); None: as the others,
            ``max(skip, lag)``.

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
    first = start if components_from is None else max(int(components_from), start)
    if n - first < 1:
        raise InvalidParameter("components_from", components_from, f"< {n} rows with these series")
    truth, along = cuff_components(q[start:n], force[start - lag : n - lag], exo)
    err = est[start:n] - truth
    rms = np.sqrt(np.mean(err**2, axis=0))
    peak = np.max(np.abs(truth), axis=0)
    late = slice(first - start, None)  # the component rows, within the compared ones
    out = EstimateErrors(
        rms_error_N=rms,
        max_error_N=np.max(np.abs(err), axis=0),
        peak_true_N=peak,
        rms_error_rel=_relative(rms, peak),
        rows=int(err.shape[0]),
        rms_true_N=np.sqrt(np.mean(truth[late] ** 2, axis=0)),
        normal_component_rms_error_N=np.sqrt(np.mean(err[late] ** 2, axis=0)),
        components_from_row=first,
    )
    if force_est is not None:
        true_f = force[start - lag : n - lag]
        diff = np.asarray(force_est, dtype=float)[start:n] - true_f
        out.vector_rms_error_N = np.sqrt(np.mean(np.sum(diff**2, axis=-1), axis=0))
        out.vector_rms_true_N = np.sqrt(np.mean(np.sum(true_f**2, axis=-1), axis=0))
        out.vector_rms_error_rel = _relative(out.vector_rms_error_N, out.vector_rms_true_N)
        _, along_est = cuff_components(q[start:n], np.asarray(force_est)[start:n], exo)
        out.along_rms_error_N = np.sqrt(np.mean((along_est - along)[late] ** 2, axis=0))
        out.along_rms_true_N = np.sqrt(np.mean(along[late] ** 2, axis=0))
    return out


#: :class:`EstimateErrorStats`' record: the cuff geometry, the last row's true
#: force (x, z) per cuff [N], and per cuff Σ e² [N²], max |e| [N], max |truth| [N].
_STATS_FIELDS = [
    *GEOMETRY_FIELDS,
    ("prev_force", np.float64, (4, 2)),
    ("sq_error_sum", np.float64, (4,)),
    ("max_error", np.float64, (4,)),
    ("peak_true", np.float64, (4,)),
    ("sq_vector_error_sum", np.float64, (4,)),
    ("sq_vector_true_sum", np.float64, (4,)),
    ("sq_true_sum", np.float64, (4,)),
    ("sq_along_error_sum", np.float64, (4,)),
    ("sq_along_true_sum", np.float64, (4,)),
    ("sq_normal_late_sum", np.float64, (4,)),
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
        components_from_s: where the per-component figures start [s] (a
            run's: the end of its ramp-in; None: ``skip_s``; never before it).

    Attributes:
        record: the geometry and the running sums, a one-element structured
            array (fields ``sq_error_sum``, ``max_error``, ``peak_true`` (4,)).
        rows: rows seen so far (compared or not).

    """

    def __init__(
        self,
        exo: BodyModel | None,
        dt: float,
        skip_s: float = STARTUP_S,
        components_from_s: float | None = None,
    ) -> None:
        self.exo = exo
        self.skip = round(v.non_negative("skip", skip_s, "s") / v.positive("dt", dt, "s"))
        late = skip_s if components_from_s is None else components_from_s
        late = v.non_negative("components_from", late, "s")
        #: The first row of the per-component figures (never before :attr:`skip`).
        self.components_from = max(round(late / dt), self.skip)
        self._dt = dt
        self._n_late = 0
        self.rows = 0
        self.record = record(_STATS_FIELDS)
        _geometry(exo).fill(self.record)
        self._prev_force = self.record["prev_force"][0]  # the last row's, once a row was seen
        self._n = 0

    def update(
        self,
        q: np.ndarray,
        cuff_force: np.ndarray,
        normal_est: np.ndarray,
        force_est: np.ndarray,
        errors: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """Add rows: q (n, 4) [rad], cuff_force and force_est (n, 4, 2), normal_est (n, 4) [N].

        ``errors``: (e⊥, e∥) arrays (n, 4) [N] to fill with each row's errors
        of the normal and along components (the log's ``cuff_normal_est_error``
        and ``cuff_along_est_error``; 0 in the first row, which has no truth).
        """
        n = np.shape(q)[0]
        if n == 0:
            return
        # Truth paired with row i: the force of row i - 1 (the previous chunk's last).
        first = 0 if self.rows else 1
        start = max(self.skip - self.rows, first)
        late = max(self.components_from - self.rows, start)
        if errors is None:
            errors = (np.zeros((n, 4)), np.zeros((n, 4)))
        else:
            errors[0][:first] = errors[1][:first] = 0.0
        rec = self.record
        _error_sums(rec, q, cuff_force, normal_est, force_est, first, start, late, *errors)
        if start < n:
            self._n += n - start
            self._n_late += max(n - late, 0)
        self._prev_force[:] = cuff_force[-1]
        self.rows += n

    def preload(
        self,
        q: np.ndarray,
        cuff_force: np.ndarray,
        normal_est: np.ndarray,
        force_est: np.ndarray,
        errors: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """Load the compiled kernel for rows of these arrays' types (before a timed run)."""
        errors = errors if errors is not None else (normal_est, normal_est)
        args = (q, cuff_force, normal_est, force_est, 0, 0, 0, *errors)
        preload(_error_sums, self.record, *args)

    def result(self) -> EstimateErrors:
        """The errors so far (zeros before any compared row, relative NaN then)."""
        sums = self.record[0]
        rows = max(self._n, 1)
        late = max(self._n_late, 1)
        rms = np.sqrt(sums["sq_error_sum"] / rows)
        peak = sums["peak_true"]
        vector = np.sqrt(sums["sq_vector_error_sum"] / rows)
        vector_true = np.sqrt(sums["sq_vector_true_sum"] / rows)
        return EstimateErrors(
            rms_error_N=rms,
            max_error_N=sums["max_error"].copy(),
            peak_true_N=peak.copy(),
            rms_error_rel=_relative(rms, peak),
            rows=self._n,
            vector_rms_error_N=vector,
            vector_rms_true_N=vector_true,
            vector_rms_error_rel=_relative(vector, vector_true),
            rms_true_N=np.sqrt(sums["sq_true_sum"] / late),
            along_rms_error_N=np.sqrt(sums["sq_along_error_sum"] / late),
            along_rms_true_N=np.sqrt(sums["sq_along_true_sum"] / late),
            normal_component_rms_error_N=np.sqrt(sums["sq_normal_late_sum"] / late),
            components_from_row=self.components_from,
            components_from_s=self.components_from * self._dt,
        )

    def summary(self) -> dict[str, Any]:
        """The summary entries of :meth:`EstimateErrors.summary`."""
        return self.result().summary()


@kernel
def _error_sums(state, q, force, normal_est, force_est, first, start, late, e_n, e_u):
    """Add rows start… to :class:`EstimateErrorStats`' sums (Σ e², max |e|, max |truth| …).

    Rows first… get their errors e⊥ = f̂⊥ − n · f in ``e_n`` and
    e∥ = u · f̂ − u · f in ``e_u`` (n, 4) [N].

    Also the whole force's Σ |f̂ − f|² and Σ |f|²; from row ``late`` on the
    normal component's Σ e⊥² and Σ (n · f)², and the along component's
    Σ (u · f̂ − u · f)² and Σ (u · f)² (u = (cos ψ, sin ψ)).

    The truth of row i is the normal component n(q_i) · f_{i-1} of the
    previous row's force (``prev_force`` of the record for row 0), per cuff
    in CUFF_NAMES order, with ψ_t = ψ_t0 + s_h q_hip and
    ψ_s = ψ_s0 + s_h q_hip + s_k q_knee (:meth:`CuffGeometry.directions`).
    """
    st = state[0]
    for r in range(first, q.shape[0]):
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
                sin, cos = math.sin(psi), math.cos(psi)
                truth = -sin * fx + cos * fz
                err = normal_est[r, c] - truth
                ex, ez = force_est[r, c, 0] - fx, force_est[r, c, 1] - fz
                along, along_err = cos * fx + sin * fz, cos * ex + sin * ez
                e_n[r, c], e_u[r, c] = err, along_err
                if r < start:
                    continue
                st.sq_error_sum[c] += err * err
                st.sq_vector_error_sum[c] += ex * ex + ez * ez
                if r >= late:
                    st.sq_true_sum[c] += truth * truth
                    st.sq_normal_late_sum[c] += err * err
                    st.sq_along_error_sum[c] += along_err * along_err
                    st.sq_along_true_sum[c] += along * along
                st.sq_vector_true_sum[c] += fx * fx + fz * fz
                st.max_error[c] = max(st.max_error[c], abs(err))
                st.peak_true[c] = max(st.peak_true[c], abs(truth))
