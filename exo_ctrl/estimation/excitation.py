r"""What a calibration run cannot tell: the parameters its motion does not excite.

:mod:`~exo_ctrl.estimation.identification` finds the base parameters
β = T π of the symmetric patient's 21 standard parameters π.  Three kinds
of parameter are then *not excited*, whatever the noise or the fit:

- **no column**: standard parameters that never enter the hip and knee
  torques of a sagittal motion with the hips fixed (T's column is zero):
  the thigh's mass (a link on a fixed joint shows only its first moment
  and its moment about the joint), and of both segments the COM's lateral
  component m c_y and the inertia about axes other than the joint's
  (I_xx, I_xy, I_xz, I_yz, I_zz);
- **folded**: standard parameters whose column is a combination of others
  (T's column is not a unit vector): only the sums are identified.  With
  the hips fixed this is the shank's mass, which enters only with the
  thigh's first moment and inertia (m_s L_t in thigh.mcz, m_s L_t² in
  thigh.Iyy);
- **physical directions**: the URDF's parameters θ (per segment a mass m,
  a COM ratio c and a gyration ratio ρ, and the damping and off-axis COMs)
  map to β through β(θ) = T π(θ), 9 parameters onto 7.  Along the null
  space of ∂β/∂θ the joint torques do not change (to first order) for
  *any* motion of a fixed-hip leg: per segment only the first moment
  m c L and the moment about the joint m L² (ρ² + c²) are seen, so the
  mass and the two ratios are not separately identifiable.  Along those
  directions the identified patient is the prior's
  (:class:`~exo_ctrl.estimation.segment_fit.PriorSpread`).  No motion with
  the pelvis fixed and no joint-side sensor (encoder, joint torque sensor,
  motor current) can excite them: a patient moved along them produces the
  same readings.

:func:`excitation_report` computes all three at the identified θ̂ and
expresses each physical direction as the change of the other parameters
that goes with a +10 % change of one segment's mass.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .segment_fit import SEGMENTS, jacobian

__all__ = ["MASS_STEP_REL", "ExcitationReport", "excitation_report"]

#: The segment-mass change each physical null direction is shown for [-].
MASS_STEP_REL = 0.10

#: Relative singular-value tolerance of the null space of ∂β/∂θ (scaled by the prior's σ).
NULL_TOL = 1e-6

#: Names of the URDF's parameters θ, in :mod:`~exo_ctrl.estimation.segment_fit`'s order.
THETA_NAMES = (
    "thigh mass",
    "thigh COM ratio",
    "thigh gyration ratio",
    "shank mass",
    "shank COM ratio",
    "shank gyration ratio",
    "joint damping",
    "thigh COM off axis",
    "shank COM off axis",
)


@dataclass
class ExcitationReport:
    """The parameters a calibration run does not excite (module docstring).

    Attributes:
        no_column: standard parameters absent from the joint torques.
        folded: per folded standard parameter, the base parameters it joins.
        null_directions: per segment mass stepped by :data:`MASS_STEP_REL`,
            the relative change [-] of every θ that leaves the torques unchanged
            (masses, COM and gyration ratios relative; damping [N·m·s/rad] and
            off-axis COMs [-] absolute).

    """

    no_column: list[str]
    folded: dict[str, list[str]]
    null_directions: dict[str, dict[str, float]] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """Plain-data form (JSON-able)."""
        return {
            "no_column": list(self.no_column),
            "folded": {k: list(v) for k, v in self.folded.items()},
            "null_directions": {
                k: {n: float(x) for n, x in d.items()} for k, d in self.null_directions.items()
            },
        }

    def lines(self) -> list[str]:
        """The report as text lines."""
        out = [
            "not excited by the calibration (the values written are the prior's there):",
            "  no column (absent from the hip and knee torques): "
            + (", ".join(self.no_column) or "none"),
        ]
        for name, into in self.folded.items():
            out.append(f"  folded: {name} only as part of {', '.join(into)}")
        for name, d in self.null_directions.items():
            terms = ", ".join(
                f"{n} {100.0 * x:+.1f} %"
                for n, x in d.items()
                if n != name and "ratio" in n and abs(x) >= 5e-4
            )
            out.append(
                f"  same torques for any motion: {name} {100.0 * MASS_STEP_REL:+.0f} % with {terms}"
            )
        return out


def _column_names(column_name: Callable[[int], str], cols: np.ndarray) -> list[str]:
    return [column_name(int(k)) for k in cols]


def excitation_report(
    t_map: np.ndarray,
    base_names: list[str],
    column_name: Callable[[int], str],
    beta_of: Callable[[np.ndarray], np.ndarray],
    theta: np.ndarray,
    sig_theta: np.ndarray,
) -> ExcitationReport:
    """The not-excited parameters of an identification (module docstring).

    Args:
        t_map: T (r, 21), β = T π.
        base_names: the base parameters' independent columns' names (r).
        column_name: the name of standard parameter k.
        beta_of: θ ↦ β(θ).
        theta: θ̂, where the physical directions are taken (9).
        sig_theta: the prior's σ of θ (9), to scale the null space.

    """
    norms = np.abs(t_map).max(axis=0)
    no_column = _column_names(column_name, np.flatnonzero(norms == 0.0))
    folded: dict[str, list[str]] = {}
    for k in np.flatnonzero(norms > 0.0):
        col = t_map[:, k]
        if np.count_nonzero(col) == 1 and np.isclose(col[np.flatnonzero(col)[0]], 1.0):
            continue
        folded[column_name(int(k))] = [base_names[i].split(" ")[0] for i in np.flatnonzero(col)]
    jac = jacobian(beta_of, theta) * sig_theta
    _, sv, vt = np.linalg.svd(jac)
    rank = int(np.sum(sv > NULL_TOL * sv.max()))
    null = (vt[rank:].T * sig_theta[:, None]) if rank < theta.size else np.zeros((theta.size, 0))
    directions: dict[str, dict[str, float]] = {}
    masses = [3 * s for s in range(len(SEGMENTS))]
    if null.shape[1] >= len(masses) and abs(np.linalg.det(null[masses, :2])) > 1e-12:
        for s, seg in enumerate(SEGMENTS):
            target = np.zeros(len(masses))
            target[s] = np.log1p(MASS_STEP_REL)  # θ holds log(m / m0)
            step = null[:, :2] @ np.linalg.solve(null[masses, :2], target)
            rel = {}
            for i, name in enumerate(THETA_NAMES):
                if i in masses:
                    rel[name] = float(np.expm1(step[i]))
                elif "ratio" in name:
                    rel[name] = float(step[i] / theta[i])
                else:
                    rel[name] = float(step[i])
            directions[f"{seg} mass"] = rel
    return ExcitationReport(no_column, folded, directions)
