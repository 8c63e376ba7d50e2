"""Computed-torque feedforward on top of the paper's PD.

The drive torque the planned motion needs is computed from the models:

    τ_ff = RNEA_exo(q*, q̇*, q̈*) + i_G² J_rotor q̈* + b_exo q̇* + f_exo tanh(q̇*/ε)
         + RNEA_patient(q*, q̇*, q̈*) + b_patient q̇* + f_patient tanh(q̇*/ε),

the second line being the patient's load carried through the cuffs (and,
with the pelvis on its guide, the stance legs' share of the weight the
support leaves, :mod:`exo_ctrl.control.stance_load`): with the
cuffs fitted so that the patient's hip and knee axes coincide with the
exoskeleton's (how the device is adjusted to a patient), a rigid cuff makes
the patient follow the same joint angles, and by virtual work the torque
that moves the patient is the patient's own inverse dynamics.  Patient joint
torques are unknown to the controller and taken as zero.  τ_ff becomes a
voltage through the steady-state motor model, U_ff = R τ_ff / (i_G k_m) +
i_G q̇* / k_E (the back-EMF at the planned speed is the larger part), and is
added to the PD voltage.  The swing leg's planned acceleration is blended in
over its first T_b = 10 ms after lift-off (q̈* → q̈_b,
:mod:`exo_ctrl.control.lift_off`): the paper's C¹ swing path would otherwise
step the feedforward while the foot is still on the belt, and throw it into
a slide.  As U_ff depends on the plan only, it is tabulated
for every plan row (the ramps' rows and one gait period for a periodic plan) when the controller
is built; a tick looks its row up, in the PD's kernel
(:func:`~exo_ctrl.control.pd.pd_law`): one compiled call per tick.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel
from ..model import FRICTION_SMOOTHING_RAD_S, BodyModel
from ..model.leg_kernels import legs_record
from ..plan.kinematics import JointTrajectory
from ..plant.drive import MotorParams
from ..plant.motor import drive_model, steady_voltage
from .base import PDGains
from .lift_off import LIFT_OFF_BLEND_S, blend_lift_off
from .pd import PDController
from .stance_load import StanceLoad, stance_load_record, stance_load_torque

__all__ = ["ComputedTorqueController", "Feedforward", "feedforward_torque"]


class ComputedTorqueController(PDController):
    """PD plus model-based feedforward voltage.

    :meth:`command` is the PD's, with the feedforward voltage of the plan
    row added (the same kernel, given the table of U_ff per plan row).

    Args:
        plan: joint targets at the control ticks.
        exo: the exoskeleton model the controller believes in.
        patient: the patient model (None: the exoskeleton alone).
        motor: the drive model.
        gains: the PD gains (the same as the plain PD for a fair comparison).
        stance_load: what the device knows of the weight its stance legs carry
            (with the pelvis on its guide; None: the pelvis fixed, no load).
        lift_off_blend_s: T_b, the swing leg's acceleration feedforward
            blended in over this time after lift-off [s]
            (:mod:`exo_ctrl.control.lift_off`; 0: the plan's q̈* throughout).

    Raises:
        InvalidParameter: a negative or non-finite ``lift_off_blend_s``.

    """

    name = "ct"

    def __init__(
        self,
        plan: JointTrajectory,
        exo: BodyModel,
        patient: BodyModel | None,
        motor: MotorParams,
        gains: PDGains | None = None,
        stance_load: StanceLoad | None = None,
        lift_off_blend_s: float = LIFT_OFF_BLEND_S,
    ) -> None:
        super().__init__(plan, gains)
        # The feedforward depends on the plan only: tabulated once per plan row
        # (the ramps and one gait period for a periodic plan), looked up per tick.
        self._ff = Feedforward(exo, patient, motor, stance_load, lift_off_blend_s)
        self._torque_ff, self._u_ff = self._ff.tables(plan)

    def refresh_row(self, row: int = 0) -> None:
        """Recompute plan row ``row``'s feedforward after the plan's row changed in place.

        For a plan generated each tick (:mod:`exo_ctrl.plan.online`): the
        same row computation the table was made with (two RNEA calls on the
        controller's own models, one kernel).
        """
        plan = self.plan
        lift = None if plan.lift_off_s is None else plan.lift_off_s[row]
        self._ff.row(
            plan.q[row], plan.dq[row], plan.ddq[row], self._torque_ff[row], self._u_ff[row], lift
        )

    def feedforward_along(self, plan: JointTrajectory) -> np.ndarray:
        """τ_ff along another plan on this controller's models, (N, 4) [N·m].

        For a plan generated each tick, whose own table holds one row: the
        same gait precomputed (:mod:`exo_ctrl.control.drive_reach`).
        """
        return self._ff.tables(plan)[0]

    @property
    def torque_ff(self) -> np.ndarray:
        """Feedforward torque of the last tick [N·m], (4,)."""
        return self._torque_ff[self.last_row]

    @property
    def torque_ff_table(self) -> np.ndarray:
        """Feedforward torque of every plan row [N·m], (rows, 4): a read-only view."""
        view = self._torque_ff.view()
        view.flags.writeable = False
        return view

    @property
    def voltage_ff_table(self) -> np.ndarray:
        """Feedforward voltage of every plan row [V], (rows, 4): a read-only view.

        Made through the controller's drive model
        (:meth:`~exo_ctrl.plant.motor.MotorBank.voltage_for`).
        """
        view = self._u_ff.view()
        view.flags.writeable = False
        return view


class Feedforward:
    """τ_ff [N·m] and U_ff [V] of the module docstring, row by row, allocated once.

    Args:
        exo: the exoskeleton model the controller believes in.
        patient: the patient model (None: the exoskeleton alone).
        motor: the drive model (its reflected rotor inertia and the voltage law).
        stance_load: the stance legs' load (None: the pelvis fixed, no load).
        lift_off_blend_s: T_b of :mod:`exo_ctrl.control.lift_off` [s] (0: none).

    Raises:
        InvalidParameter: a negative or non-finite ``lift_off_blend_s``.

    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel | None,
        motor: MotorParams,
        stance_load: StanceLoad | None = None,
        lift_off_blend_s: float = LIFT_OFF_BLEND_S,
    ) -> None:
        self._blend_s = v.non_negative("lift_off_blend", lift_off_blend_s, "s")
        self._legs = legs_record(exo)
        self._ddq = np.zeros(4)
        self._me = pin.Model(exo.model)
        self._load = None if stance_load is None else stance_load_record(stance_load, exo)
        self._tau_e = np.zeros(4)
        self._me.armature = np.full(exo.model.nv, motor.reflected_inertia_kgm2)
        self._de = self._me.createData()
        self._b = exo.damping.copy()
        self._fr = exo.friction.copy()
        self._mp = None
        if patient is not None:
            self._mp = pin.Model(patient.model)
            self._dp = self._mp.createData()
            self._b += patient.damping
            self._fr += patient.friction
        self._zero = np.zeros(4)
        self._u = np.zeros(4)
        #: The drive model for :func:`feedforward_row` (:func:`drive_model`).
        self._drive = drive_model(motor)

    def row(
        self,
        q: np.ndarray,
        dq: np.ndarray,
        ddq: np.ndarray,
        tau_out: np.ndarray,
        u_out: np.ndarray | None = None,
        lift: np.ndarray | None = None,
    ) -> None:
        """τ_ff [N·m] into ``tau_out`` and U_ff [V] into ``u_out`` for one plan row.

        ``lift``: the row's time since each leg's lift-off [s], (2,)
        (:mod:`exo_ctrl.control.lift_off`; None: q̈* as planned).
        """
        if lift is not None and self._blend_s > 0.0:
            blend_lift_off(self._legs, q, dq, ddq, lift, self._blend_s, self._ddq)
            ddq = self._ddq
        tau_e = pin.rnea(self._me, self._de, q, dq, ddq)
        if self._load is not None:  # the stance legs' load (control/stance_load.py)
            tau_e = np.copyto(self._tau_e, tau_e) or self._tau_e
            stance_load_torque(self._load, q, dq, ddq, tau_e)
        tau_p = self._zero if self._mp is None else pin.rnea(self._mp, self._dp, q, dq, ddq)
        u = self._u if u_out is None else u_out
        feedforward_row(tau_e, tau_p, dq, self._b, self._fr, self._drive, tau_out, u)

    def tables(self, plan: JointTrajectory, rows: int | None = None) -> tuple[np.ndarray, ...]:
        """τ_ff and U_ff along a plan, (N, 4) each: every row, or the first ``rows``."""
        n = plan.q.shape[0] if rows is None else min(rows, plan.q.shape[0])
        tau, u = np.zeros((n, 4)), np.zeros((n, 4))
        lift = plan.lift_off_s
        for k in range(n):
            row_lift = None if lift is None else lift[k]
            self.row(plan.q[k], plan.dq[k], plan.ddq[k], tau[k], u[k], row_lift)
        return tau, u


def feedforward_torque(
    plan: JointTrajectory,
    exo: BodyModel,
    patient: BodyModel | None,
    motor: MotorParams,
    rows: int | None = None,
    lift_off_blend_s: float = LIFT_OFF_BLEND_S,
) -> np.ndarray:
    """τ_ff along a plan, (N, 4) [N·m]: every row, or the first ``rows``.

    ``lift_off_blend_s``: T_b of :mod:`exo_ctrl.control.lift_off` [s] (0: none).
    """
    return Feedforward(exo, patient, motor, None, lift_off_blend_s).tables(plan, rows)[0]


@kernel
def feedforward_row(tau_exo, tau_patient, dq, damping, friction, drive, tau_out, u_out):
    """τ_ff (module docstring) from the two RNEA torques, and U_ff through the drive model.

    ``drive``: :func:`~exo_ctrl.plant.motor.drive_model`; the voltage is
    :func:`~exo_ctrl.plant.motor.steady_voltage`.
    """
    for j in range(4):
        v = dq[j]
        tau = tau_exo[j] + tau_patient[j] + damping[j] * v
        tau += friction[j] * np.tanh(v / FRICTION_SMOOTHING_RAD_S)
        tau_out[j] = tau
        u_out[j] = steady_voltage(tau, v, drive)
