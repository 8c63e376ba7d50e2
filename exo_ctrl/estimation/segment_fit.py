r"""A physically consistent patient from its base parameters: the segments of a BodyParams.

:mod:`exo_ctrl.estimation.identification` estimates the base parameters β
of the patient; the URDF written is a :class:`~exo_ctrl.model.BodyParams`
(per segment a mass m, a centre of mass c L on the link's axis and a
transverse radius of gyration ρ L; both legs alike).  Its parameters

    θ = (μ_t, c_t, ρ_t, μ_s, c_s, ρ_s, b_p, x_t, x_s),   m = m₀ e^μ,

(t thigh, s shank, x a COM off the link's axis over its length, b_p the
joint damping) map to the standard parameters π(θ) and so to β(θ) = T π(θ).
:func:`physical_fit` takes the θ closest to β̂, weighted by its covariance,
with the prior on θ (:class:`PriorSpread`), within bounds: m > 0 by
construction, ρ above r / (2 L) (the triangle inequality of the principal
moments with the axial moment m r² / 2), c in :data:`COM_BOUNDS`, b_p ≥ 0.
Every answer is a positive mass with a positive-definite inertia (and
pseudo-inertia).  x is fitted (it takes up a sag of the patient in the
straps, which looks like a COM off the axis) but a BodyParams has no such
field: the URDF puts the COM on the axis.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .. import _validate as v
from ..model import BodyParams, CohortSpread

__all__ = [
    "COM_BOUNDS",
    "SEGMENTS",
    "PriorSpread",
    "body_params_of",
    "jacobian",
    "physical_fit",
    "segment_parameters",
    "standard_of",
    "theta_prior",
    "theta_sigma",
]

#: Segments of the symmetric patient, in the order of θ and π.
SEGMENTS = ("thigh", "shank")

#: Bounds of the fitted COM ratio c.
COM_BOUNDS = (0.05, 0.95)


@dataclass(frozen=True)
class PriorSpread:
    """How far the patient may be from the nominal model (1 σ), the prior of the fit.

    The defaults are the virtual cohort's coefficients of variation
    (:class:`~exo_ctrl.model.CohortSpread`, whose sources its module cites:
    segment mass 10 %, centre-of-mass ratio 4 %, gyration ratio 5 %), so
    that the prior says what the project's population model says about a
    patient of a stature, mass and sex; the segment lengths are measured (the
    exoskeleton is fitted to them) and carry no spread.  The patient's joint
    damping is given its own size (100 %, chosen) and a COM off the link's
    axis 2 % of its length (chosen).  The calibration cannot separate a
    segment's mass from its ratios (:mod:`~exo_ctrl.estimation.identification`,
    "Not excited"): along those directions the answer is this prior's.

    Attributes:
        mass_rel: segment mass, relative [-].
        com_rel: centre-of-mass ratio, relative [-].
        gyration_rel: transverse gyration ratio, relative [-].
        damping_rel: the patient's joint damping, relative [-].
        com_x_ratio: the COM off the link's axis, over the link length [-].

    """

    mass_rel: float = CohortSpread.mass
    com_rel: float = CohortSpread.com_ratio
    gyration_rel: float = CohortSpread.gyration_ratio
    damping_rel: float = 1.0
    com_x_ratio: float = 0.02

    def __post_init__(self) -> None:
        for name in ("mass_rel", "com_rel", "gyration_rel", "damping_rel", "com_x_ratio"):
            v.positive(name, getattr(self, name))

    @classmethod
    def from_cohort(cls, spread: CohortSpread, **overrides: float) -> PriorSpread:
        """The prior of a cohort's spreads (mass, COM and gyration ratios); keywords override."""
        values = {
            "mass_rel": spread.mass,
            "com_rel": spread.com_ratio,
            "gyration_rel": spread.gyration_ratio,
        }
        return cls(**{**values, **overrides})


def segment_parameters(
    m: float, c: float, rho: float, cx: float, length: float, radius: float
) -> np.ndarray:
    """Pinocchio's standard parameters (10) of a BodyParams segment, the COM ``cx`` L off axis.

    Args:
        m: mass [kg].
        c: COM along the link over its length L [-].
        rho: transverse radius of gyration about the COM over L [-].
        cx: COM off the axis (along x) over L [-].
        length: L [m].
        radius: r, for the axial moment m r² / 2 [m].

    """
    inertia = pin.Inertia(
        m,
        np.array([cx * length, 0.0, -c * length]),
        np.diag([m * (rho * length) ** 2, m * (rho * length) ** 2, m * radius**2 / 2.0]),
    )
    return inertia.toDynamicParameters()


def theta_prior(prior: BodyParams) -> np.ndarray:
    """θ₀ of the prior (module docstring): μ = 0, its ratios and damping, x = 0."""
    th = []
    for seg in SEGMENTS:
        rho = getattr(prior, f"{seg}_gyration_ratio")
        if rho is None:  # uniform cylinder: the ratio that gives the same I_t
            length, r = getattr(prior, f"{seg}_length"), getattr(prior, f"{seg}_radius")
            rho = math.sqrt((3.0 * r**2 + length**2) / 12.0) / length
        th += [0.0, getattr(prior, f"{seg}_com_ratio"), rho]
    return np.array([*th, prior.joint_damping, 0.0, 0.0])


def theta_sigma(theta0: np.ndarray, spread: PriorSpread) -> np.ndarray:
    """The prior's standard deviation of each component of θ."""
    sig = np.empty(9)
    for s in range(2):
        sig[3 * s] = spread.mass_rel
        sig[3 * s + 1] = spread.com_rel * theta0[3 * s + 1]
        sig[3 * s + 2] = spread.gyration_rel * theta0[3 * s + 2]
    sig[6] = spread.damping_rel * max(theta0[6], 0.05)
    sig[7:] = spread.com_x_ratio
    return sig


def standard_of(theta: np.ndarray, prior: BodyParams) -> np.ndarray:
    """π(θ) (21): thigh π, shank π (Pinocchio's order), b_p; lengths and radii the prior's."""
    out = np.empty(21)
    for s, seg in enumerate(SEGMENTS):
        m = getattr(prior, f"{seg}_mass") * math.exp(theta[3 * s])
        out[10 * s : 10 * s + 10] = segment_parameters(
            m,
            theta[3 * s + 1],
            theta[3 * s + 2],
            theta[7 + s],
            getattr(prior, f"{seg}_length"),
            getattr(prior, f"{seg}_radius"),
        )
    out[20] = theta[6]
    return out


def jacobian(
    fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, rel: float = 1e-6
) -> np.ndarray:
    """∂fun/∂x by central differences, steps ``rel`` max(|x_i|, 0.01)."""
    f0 = fun(x)
    jac = np.empty((f0.size, x.size))
    for i in range(x.size):
        step = rel * max(abs(x[i]), 1e-2)
        xp, xm = x.copy(), x.copy()
        xp[i] += step
        xm[i] -= step
        jac[:, i] = (fun(xp) - fun(xm)) / (2.0 * step)
    return jac


def physical_fit(
    beta: np.ndarray,
    cov: np.ndarray,
    theta0: np.ndarray,
    sig_theta: np.ndarray,
    t_map: np.ndarray,
    prior: BodyParams,
) -> tuple[np.ndarray, np.ndarray]:
    """The consistent θ closest to β̂ (weighted by its covariance) and the prior."""
    chol = np.linalg.cholesky(np.linalg.inv(cov + np.diag(1e-12 * (1.0 + np.abs(beta)) ** 2)))

    def residual(th: np.ndarray) -> np.ndarray:
        misfit = chol.T @ (t_map @ standard_of(th, prior) - beta)
        return np.concatenate((misfit, (th - theta0) / sig_theta))

    lower = np.full(9, -np.inf)
    upper = np.full(9, np.inf)
    for s, seg in enumerate(SEGMENTS):
        lower[3 * s + 1], upper[3 * s + 1] = COM_BOUNDS
        r, length = getattr(prior, f"{seg}_radius"), getattr(prior, f"{seg}_length")
        lower[3 * s + 2] = 1.001 * r / (2.0 * length)
    lower[6] = 0.0
    start = np.clip(theta0, lower + 1e-9, upper - 1e-9)
    # scipy (installed with proxsuite) on use only: importing scipy.optimize
    # takes about 0.3 s, which every other exo-ctrl command would pay.
    from scipy import optimize

    fit = optimize.least_squares(residual, start, bounds=(lower, upper), x_scale=sig_theta)
    jac = fit.jac
    cov_theta = np.linalg.pinv(jac.T @ jac)
    return fit.x, np.sqrt(np.maximum(np.diag(cov_theta), 0.0))


def body_params_of(theta: np.ndarray, prior: BodyParams) -> BodyParams:
    """The prior's BodyParams with θ's masses, ratios and damping (x is not written)."""
    values = {}
    for s, seg in enumerate(SEGMENTS):
        values[f"{seg}_mass"] = getattr(prior, f"{seg}_mass") * math.exp(theta[3 * s])
        values[f"{seg}_com_ratio"] = float(theta[3 * s + 1])
        values[f"{seg}_gyration_ratio"] = float(theta[3 * s + 2])
    values["joint_damping"] = float(theta[6])
    return prior.replace(**values)
