r"""The start at rest: the patient settled into the cuffs, the drives holding the exoskeleton.

A session starts with the device standing still.  The straps are closed while
the patient stands aligned with the exoskeleton (the cuffs fitted slack in
the exoskeleton's posture q₀, :meth:`~exo_ctrl.plant.cuffs.CuffSet.fit`), and
the patient then settles into them.  With everything at rest the patient's
joint angles q_p solve the static balance

.. math::

    F(q_p) = g_p(q_p) - τ_{c,p}(q_0, q_p) - τ_h(q_p) = 0,

g_p the patient's gravity torque (Pinocchio's RNEA at v = a = 0), τ_{c,p} =
-J_pᵀ f the cuffs' generalised force on the patient (f = -K (Δp - r₀), no
damping at rest), τ_h the patient's own joint torque at rest
(:mod:`exo_ctrl.plant.patient`; zero for the paper's passive patient) and,
with the patient's feet on the belt (:mod:`exo_ctrl.plant.patient_feet`),
less the belt's normal force at rest J_zᵀ k δⁿ (``ground``).
:func:`settle_patient` solves it by Newton's method on the four angles from
q_p = q₀, with a central finite-difference Jacobian (step
:data:`FD_STEP_RAD`), to :data:`TOLERANCE_NM`.

The exoskeleton is held still at q₀ by its drives: τ_drive = g_e(q₀) -
τ_{c,e}(q₀, q_p), its gravity torque less the cuffs' reaction J_eᵀ f
(:func:`holding_torque`), so that at t = 0 no body accelerates.  Joint
friction and damping are zero at rest; an end stop acts only beyond the
URDF limits, which a plan does not reach.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from ..exceptions import InvalidParameter
from .cuffs import CuffSet
from .patient import PatientTorque

__all__ = ["FD_STEP_RAD", "MAX_ITERATIONS", "TOLERANCE_NM", "holding_torque", "settle_patient"]

#: Newton stops when every joint's residual |F| is below this [N·m].
TOLERANCE_NM = 1e-9
#: Newton steps before giving up.
MAX_ITERATIONS = 50
#: Step of the central differences of the Jacobian ∂F/∂q_p [rad].
FD_STEP_RAD = 1e-6


class _Balance:
    """F(q_p) of the module docstring for a fixed exoskeleton posture q₀."""

    def __init__(
        self,
        cuffs: CuffSet,
        patient_model: pin.Model,
        q_exo: np.ndarray,
        patient_torque: PatientTorque | None,
        ground: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self._cuffs = cuffs
        self._ground = ground
        self._model = patient_model
        self._data = patient_model.createData()
        self._q = np.concatenate((np.asarray(q_exo, dtype=float), q_exo))
        self._v = np.zeros(8)
        self._zero = np.zeros(4)
        self._own = patient_torque
        self._tau_h = np.zeros(4)

    def __call__(self, q_p: np.ndarray) -> np.ndarray:
        self._q[4:] = q_p
        self._cuffs.compute(self._q, self._v)
        out = pin.rnea(self._model, self._data, q_p, self._zero, self._zero).copy()
        out -= self._cuffs.joint_torque[4:]
        if self._own is not None:
            out -= self._own(0.0, q_p, self._zero, self._tau_h)
        if self._ground is not None:
            out -= self._ground(q_p)
        return out


def settle_patient(
    cuffs: CuffSet,
    patient_model: pin.Model,
    q_exo: np.ndarray,
    patient_torque: PatientTorque | None = None,
    ground: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Fit the cuffs slack at the aligned posture q₀, then solve F(q_p) = 0 for the patient.

    Args:
        cuffs: the plant's cuffs (refitted here: slack with the patient at q₀).
        patient_model: the patient's Pinocchio model.
        q_exo: the exoskeleton's posture q₀ [rad], (4,).
        patient_torque: the patient's own joint torque model (None: none).
        ground: the belt's generalised force on the patient's joints at rest
            at angles q_p [N·m], (4,) (None: the feet free; with the patient's
            feet on the belt, :meth:`~exo_ctrl.plant.patient_feet.PatientFeet.rest_torque`).

    Returns:
        q_p [rad], (4,): the patient's joint angles at static equilibrium.

    Raises:
        InvalidParameter: named ``cuff_fit``, when Newton's method does not
            bring the residual below :data:`TOLERANCE_NM` within
            :data:`MAX_ITERATIONS` steps (cuffs too soft to hold the patient,
            say); the message gives the residual and the posture reached.

    """
    q0 = np.asarray(q_exo, dtype=float)
    cuffs.fit(np.concatenate((q0, q0)))
    balance = _Balance(cuffs, patient_model, q0, patient_torque, ground)
    q = q0.copy()
    f = balance(q)
    jac = np.empty((4, 4))
    for _ in range(MAX_ITERATIONS):
        if np.all(np.abs(f) < TOLERANCE_NM):
            return q
        for j in range(4):
            dq = np.zeros(4)
            dq[j] = FD_STEP_RAD
            jac[:, j] = (balance(q + dq) - balance(q - dq)) / (2.0 * FD_STEP_RAD)
        try:
            step = np.linalg.solve(jac, -f)
        except np.linalg.LinAlgError:
            break
        # Damped: halve the step until the residual falls (at most 20 halvings).
        norm = float(np.max(np.abs(f)))
        for _ in range(20):
            trial = balance(q + step)
            if np.all(np.isfinite(trial)) and float(np.max(np.abs(trial))) < norm:
                break
            step *= 0.5
        q = q + step
        f = trial
    if np.all(np.abs(f) < TOLERANCE_NM):
        return q
    raise InvalidParameter(
        "cuff_fit",
        "equilibrium",
        "'slack' for cuffs that cannot hold this patient at rest",
        f"no static equilibrium of the patient in the cuffs: Newton's method left a joint "
        f"torque residual of {float(np.max(np.abs(f))):.3g} N·m (tolerance {TOLERANCE_NM:g}) "
        f"after {MAX_ITERATIONS} steps, at patient angles {np.round(q, 4).tolist()} rad "
        f"against the exoskeleton's {np.round(q0, 4).tolist()} rad; stiffer cuffs hold it",
    )


def holding_torque(
    cuffs: CuffSet, exo_model: pin.Model, q_exo: np.ndarray, q_patient: np.ndarray
) -> np.ndarray:
    """τ_drive = g_e(q₀) - J_eᵀ f: the drive torques holding the exoskeleton still [N·m], (4,).

    Args:
        cuffs: the plant's cuffs, fitted.
        exo_model: the exoskeleton's Pinocchio model.
        q_exo: the exoskeleton's posture q₀ [rad].
        q_patient: the patient's posture [rad].

    """
    q_exo = np.asarray(q_exo, dtype=float)
    cuffs.compute(np.concatenate((q_exo, q_patient)), np.zeros(8))
    zero = np.zeros(4)
    gravity = pin.rnea(exo_model, exo_model.createData(), q_exo, zero, zero)
    return gravity - cuffs.joint_torque[:4]
