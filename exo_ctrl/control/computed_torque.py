"""Computed-torque feedforward on top of the paper's PD.

The drive torque the planned motion needs is computed from the models:

    τ_ff = RNEA_exo(q*, q̇*, q̈*) + i_G² J_rotor q̈* + b_exo q̇* + f_exo tanh(q̇*/ε)
         + RNEA_patient(q*, q̇*, q̈*) + b_patient q̇* + f_patient tanh(q̇*/ε),

the second line being the patient's load carried through the cuffs: with the
cuffs fitted so that the patient's hip and knee axes coincide with the
exoskeleton's (how the device is adjusted to a patient), a rigid cuff makes
the patient follow the same joint angles, and by virtual work the torque
that moves the patient is the patient's own inverse dynamics.  Patient joint
torques are unknown to the controller and taken as zero.  τ_ff becomes a
voltage through the steady-state motor model, U_ff = R τ_ff / (i_G k_m) +
i_G q̇* / k_E (the back-EMF at the planned speed is the larger part), and is
added to the PD voltage.  As U_ff depends on the plan only, it is tabulated
for every plan row (the ramps' rows and one gait period for a periodic plan) when the controller
is built; a tick looks its row up, in the PD's kernel
(:func:`~exo_ctrl.control.pd.pd_law`): one compiled call per tick.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .._jit import kernel
from ..model import FRICTION_SMOOTHING_RAD_S, BodyModel
from ..plan.kinematics import JointTrajectory
from ..plant.drive import EFFICIENCY_SMOOTHING_RAD_S, MotorParams
from ..plant.motor import MotorBank
from .base import PDGains
from .pd import PDController

__all__ = ["ComputedTorqueController", "feedforward_torque"]


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

    """

    name = "ct"

    def __init__(
        self,
        plan: JointTrajectory,
        exo: BodyModel,
        patient: BodyModel | None,
        motor: MotorParams,
        gains: PDGains | None = None,
    ) -> None:
        super().__init__(plan, gains)
        # The feedforward depends on the plan only: tabulated once per plan row
        # (the ramps and one gait period for a periodic plan), looked up per tick.
        self._motor = MotorBank(4, motor)
        self._torque_ff = feedforward_torque(plan, exo, patient, motor)
        self._u_ff = np.ascontiguousarray(self._motor.voltage_for(self._torque_ff, plan.dq))
        self._ff: _Feedforward | None = None
        self._models = (exo, patient, motor)

    def refresh_row(self, row: int = 0) -> None:
        """Recompute plan row ``row``'s feedforward after the plan's row changed in place.

        For a plan generated each tick (:mod:`exo_ctrl.plan.online`): two
        RNEA calls on the controller's own models and the drive model's
        voltage, as the table was made.
        """
        ff = self._ff
        if ff is None:
            ff = self._ff = _Feedforward(*self._models)
            m = self._models[2]
            self._drive = np.array(
                [
                    m.resistance_ohm / m.torque_per_amp_Nm_per_A,
                    m.back_emf_V_per_rad_s,
                    math.log(m.gear_efficiency),
                    EFFICIENCY_SMOOTHING_RAD_S,
                    FRICTION_SMOOTHING_RAD_S,
                ]
            )
            self._zero = np.zeros(4)
        q, dq, ddq = self.plan.q[row], self.plan.dq[row], self.plan.ddq[row]
        tau_e = pin.rnea(ff._me, ff._de, q, dq, ddq)
        tau_p = pin.rnea(ff._mp, ff._dp, q, dq, ddq) if ff._mp is not None else self._zero
        feedforward_row(
            tau_e, tau_p, dq, ff._b, ff._fr, self._drive, self._torque_ff[row], self._u_ff[row]
        )

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


class _Feedforward:
    """τ_ff of the module docstring, allocated once."""

    def __init__(self, exo: BodyModel, patient: BodyModel | None, motor: MotorParams) -> None:
        self._me = pin.Model(exo.model)
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
        self._tmp = np.zeros(4)

    def torque(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, out: np.ndarray) -> np.ndarray:
        out[:] = pin.rnea(self._me, self._de, q, dq, ddq)
        if self._mp is not None:
            np.add(out, pin.rnea(self._mp, self._dp, q, dq, ddq), out=out)
        np.multiply(self._b, dq, out=self._tmp)
        np.add(out, self._tmp, out=out)
        np.divide(dq, FRICTION_SMOOTHING_RAD_S, out=self._tmp)
        np.tanh(self._tmp, out=self._tmp)
        np.multiply(self._tmp, self._fr, out=self._tmp)
        np.add(out, self._tmp, out=out)
        return out


def feedforward_torque(
    plan: JointTrajectory,
    exo: BodyModel,
    patient: BodyModel | None,
    motor: MotorParams,
    rows: int | None = None,
) -> np.ndarray:
    """τ_ff along a plan, (N, 4) [N·m]: every row, or the first ``rows``."""
    ff = _Feedforward(exo, patient, motor)
    n = plan.q.shape[0] if rows is None else min(rows, plan.q.shape[0])
    out = np.zeros((n, 4))
    for k in range(n):
        ff.torque(plan.q[k], plan.dq[k], plan.ddq[k], out=out[k])
    return out


@kernel
def feedforward_row(tau_exo, tau_patient, dq, damping, friction, drive, tau_out, u_out):
    """τ_ff (module docstring) from the two RNEA torques and U_ff through the drive model.

    ``drive``: (R / k_t [Ω·A/(N·m)], i_G / k_E [V·s/rad], ln η, ω_η [rad/s],
    ε [rad/s]); U = R τ / (k_t η^s) + (i_G / k_E) q̇*, s = sign(τ) tanh(q̇*/ω_η)
    (:meth:`~exo_ctrl.plant.motor.MotorBank.voltage_for`).
    """
    for j in range(4):
        v = dq[j]
        tau = tau_exo[j] + tau_patient[j] + damping[j] * v + friction[j] * np.tanh(v / drive[4])
        tau_out[j] = tau
        s = np.sign(tau) * np.tanh(v / drive[3])
        u_out[j] = drive[0] * tau / np.exp(s * drive[2]) + drive[1] * v
