"""The simulated device: exoskeleton and patient rigid bodies, drives and cuffs.

State: joint angles and speeds of both bodies stacked as
``q_all = [q_exo (4), q_patient (4)]`` (JOINT_NAMES order) and the drive
currents.  Inputs per step: drive voltages [V] and patient joint torques
[N·m].  Forces on the bodies:

- exoskeleton: drive torque (DC motors, :mod:`exo_ctrl.plant.motor`), cuff forces,
  viscous damping and smoothed dry friction from the URDF ``<dynamics>``;
  the gearbox reflects the rotor inertia i_G² J_rotor onto each joint;
- patient: patient joint torques (an input), cuff forces, URDF damping and
  friction.

Integration, step h (default 1 ms): drift–kick–drift leapfrog,
q½ = q + (h/2) v,  a = ABA(q½, v½),  v⁺ = v + h a,  q⁺ = q½ + (h/2) v⁺,
with v½ = v + (h/2) a⁻ extrapolated from the previous step's acceleration, so
the velocity-dependent forces (Coriolis, cuff damping) are also taken at
mid-step: second order with one ABA call per step.  Symplectic Euler, also
one call, drifted 3 % in energy over 10 s at 1 ms on the passive system; this
scheme stays within 0.1 % (tests/test_plant.py).
The two bodies are one Pinocchio model for that call: the patient's model
appended to the exoskeleton's at the world frame (``pin.appendModel``; two
independent fixed-base trees, so the dynamics are those of the two models
apart, and the coordinates are q_all's, exo first).  Both source models must
have the same gravity.
The stiff viscous terms are taken implicitly: the drive's back-EMF damping
D_m = -∂τ/∂ω (about 330 N·m·s/rad at the default gear ratio; its time
constant with the shank's inertia is well under 1 ms, so an explicit step
would be unstable) and the joint damping b.  Linearising the torque at the
present speed, (M + h D) a = τ(v) - b(q, v) - ..., and M + h D is M with h D
added to its diagonal, which is exactly what Pinocchio's ``armature`` does: the
ABA call runs with armature = [i_G² J_rotor + h b + h D_m (exo), h b (patient)].
The drive current itself is integrated exactly over the step
(:class:`~exo_ctrl.plant.motor.MotorBank`).

Outputs of a step: ``drive_torque`` is the torque the drive applied at the
joint, τ_m(v) - h D_m a (the mean-current torque with its implicit back-EMF
correction); ``sensor_torque`` is what a joint torque sensor between the
gearbox and the link reads, drive_torque - i_G² J_rotor a (the rotor's
inertia is on the motor side of the sensor).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .. import _validate as _v
from .._jit import kernel
from ..exceptions import InvalidModel, SimulationDiverged
from ..model.body import FRICTION_SMOOTHING_RAD_S, JOINT_NAMES, BodyModel, combined_model
from .cuffs import CuffParams, CuffSet, cuff_forces
from .motor import MotorBank, MotorParams, motor_step

__all__ = ["Plant"]

#: A joint speed above this is taken as divergence [rad/s].
MAX_JOINT_SPEED_RAD_S = 100.0


class Plant:
    """Exoskeleton + patient + drives + cuffs, stepped at a fixed step.

    Both bodies are stepped by one ABA call on a combined Pinocchio model
    (see the module docstring).

    Args:
        exo: the exoskeleton body.
        patient: the patient body (same gravity as the exoskeleton's model).
        dt: integration step h [s].
        motors: drive parameters; None disconnects the drives (no torque, no
            rotor inertia, no back-EMF) — for passive tests.
        cuffs: cuff parameters.
        joint_losses: apply the URDF's joint damping and friction.

    Raises:
        InvalidModel: a body without exactly the four joints in JOINT_NAMES
            order, or the two models' gravities differ.
        InvalidParameter: a step that is not a positive number.

    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel,
        dt: float = 1e-3,
        motors: MotorParams | None = None,
        cuffs: CuffParams | None = None,
        joint_losses: bool = True,
    ) -> None:
        for body in (exo, patient):
            if not np.array_equal(body.q_index, np.arange(4)) or body.model.nq != 4:
                raise InvalidModel(
                    body.source,
                    "",
                    f"the plant needs exactly the joints {JOINT_NAMES} in that order",
                )
        if not (math.isfinite(dt) and dt > 0):
            from ..exceptions import InvalidParameter

            raise InvalidParameter("dt", dt, "> 0 s")
        self.exo = exo
        self.patient = patient
        self.dt = float(dt)
        # Both bodies in one model: one ABA call per step.
        self._model = combined_model(exo, patient)
        self._data = self._model.createData()
        self.motor_params = motors
        self.motors = MotorBank(4, motors) if motors is not None else None
        rotor = motors.reflected_inertia_kgm2 if motors is not None else 0.0
        losses = 1.0 if joint_losses else 0.0
        self._b = losses * np.concatenate((exo.damping, patient.damping))
        self._fr = losses * np.concatenate((exo.friction, patient.friction))
        self._has_friction = bool(np.any(self._fr > 0))
        hip_e = exo.legs["left"].hip_xz
        hip_p = patient.legs["left"].hip_xz
        self.patient_offset_xz = (hip_e[0] - hip_p[0], hip_e[1] - hip_p[1])
        self.cuff_params = cuffs or CuffParams()
        self.cuffs = CuffSet(exo, patient, self.cuff_params, self.patient_offset_xz)
        # State and work arrays (allocated once), as rows of two buffers the
        # step kernels fill in place.
        self._s8 = np.zeros((7, 8))
        self.q, self.v, self._acc, self._q_mid, self._v_mid, self._tau, self._arm = self._s8
        self._s4 = np.zeros((6, 4))
        (
            self.drive_torque,
            #: Joint torque sensor reading at each drive output (gearbox to link) [N·m].
            self.sensor_torque,
            self.patient_torque,
            self._damping_m,  # h D_m of the drives [kg·m²]
            self._arm_base,
            self._arm_const,
        ) = self._s4
        self._arm_base[:] = rotor
        #: q and v stacked, (16,) view of the state [rad, rad/s].
        self.state = self._s8[:2].reshape(16)
        #: The last step's applied drive voltage [V], mean drive current [A],
        #: drive torque and patient torque [N·m] (4 each) and cuff forces on
        #: the exoskeleton (fx of the 4 cuffs, fz of the 4 cuffs) [N]: (24,).
        self.outputs = np.zeros(24)
        # The combined model's armature: exo = rotor inertia + h b (implicit
        # joint damping, constant) + h D_m (implicit back-EMF damping, per
        # step); patient = h b.
        self._arm_const[:] = self._arm_base + self.dt * self._b[:4]
        self._arm[:4] = self._arm_const
        self._arm[4:] = self.dt * self._b[4:]
        self._model.armature = self._arm
        self._losses = np.stack((self._b, self._fr))
        self._flags = np.array([self._has_friction, self.motors is not None, False], dtype=np.bool_)
        self.t = 0.0
        # The arguments of every step's calls, gathered once (views stay valid:
        # the buffers are never reallocated).
        if self.motors is not None:
            self.motors.set_step(self.dt)
            motor_args = (self.motors.kernel_params, self.motors.kernel_state)
        else:
            motor_args = (np.zeros(8), np.zeros((6, 4)))
        c = self.cuffs
        self._pre_args = (self.dt, self._s8, self._s4, self._losses, self._flags)
        self._pre_more = (c.kernel_matrices, c.kernel_params, c.kernel_out, *motor_args)
        self._post_more = (motor_args[1], c.kernel_out, self.outputs)
        self._aba = (self._model, self._data, self._q_mid, self._v_mid, self._tau)

    # ------------------------------------------------------------------ state

    def reset(
        self,
        q_exo: np.ndarray,
        v_exo: np.ndarray,
        q_patient: np.ndarray | None = None,
        v_patient: np.ndarray | None = None,
        current_A: np.ndarray | float = 0.0,
        fit_cuffs: bool = True,
    ) -> None:
        """Set the state; the patient defaults to the exoskeleton's joint state.

        Args:
            q_exo: exoskeleton joint angles [rad].
            v_exo: exoskeleton joint speeds [rad/s].
            q_patient: patient joint angles [rad] (default: the exo's).
            v_patient: patient joint speeds [rad/s] (default: the exo's).
            current_A: drive currents [A].
            fit_cuffs: make the present cuff offsets the slack ones (the
                straps are fitted in this posture).

        """
        self.q[:4] = q_exo
        self.v[:4] = v_exo
        self.q[4:] = q_exo if q_patient is None else q_patient
        self.v[4:] = v_exo if v_patient is None else v_patient
        self.t = 0.0
        self._acc[:] = 0.0
        if self.motors is not None:
            self.motors.reset(current_A)
        if fit_cuffs:
            self.cuffs.fit(self.q)
        self.cuffs.compute(self.q, self.v)
        self.drive_torque[:] = self.motors.torque_Nm if self.motors is not None else 0.0
        self.sensor_torque[:] = self.drive_torque

    @property
    def cuff_force(self) -> np.ndarray:
        """Cuff forces on the exoskeleton over the last step (mid-step), (4, 2) [N]."""
        return self.cuffs.force

    # ------------------------------------------------------------------ stepping

    def step(self, voltage_V: np.ndarray, patient_torque_Nm: np.ndarray | None = None) -> None:
        """Advance by one step h with the drive voltages and patient torques held.

        Args:
            voltage_V: commanded drive voltages, (4,) [V].
            patient_torque_Nm: patient joint torques, (4,) [N·m] (None: zero).

        Raises:
            SimulationDiverged: a joint speed became non-finite or exceeded
                :data:`MAX_JOINT_SPEED_RAD_S`.
            InvalidParameter: an input that is not 4 numbers (or one).

        """
        flags = self._flags
        if patient_torque_Nm is None:
            flags[2] = False
            patient_torque_Nm = self.patient_torque
        else:
            flags[2] = True
        if not (type(voltage_V) is type(patient_torque_Nm) is np.ndarray):
            voltage_V, patient_torque_Nm = _v.arrays(
                (4,), voltage_V=voltage_V, patient_torque_Nm=patient_torque_Nm
            )
        changed = _drift_and_forces(*self._pre_args, voltage_V, patient_torque_Nm, *self._pre_more)
        if changed < 0:
            _v.refuse_shapes((4,), voltage_V=voltage_V, patient_torque_Nm=patient_torque_Nm)
        if changed:
            self._model.armature = self._arm
        # Kick: accelerations of both bodies at mid-step, damping implicit
        # through the armature.
        acc = pin.aba(*self._aba)
        self.t += self.dt
        speed2 = _kick_and_drift(self.dt, self._s8, self._s4, acc, flags, *self._post_more)
        if not speed2 < MAX_JOINT_SPEED_RAD_S**2:
            self._diverged()

    @property
    def acceleration(self) -> np.ndarray:
        """Joint accelerations [exo, patient] over the last step [rad/s²], (8,)."""
        return self._acc

    def _diverged(self) -> None:
        names = [f"exoskeleton {j} speed" for j in JOINT_NAMES] + [
            f"patient {j} speed" for j in JOINT_NAMES
        ]
        bad = np.where(np.isfinite(self.v), np.abs(self.v), np.inf)
        i = int(np.argmax(bad))
        raise SimulationDiverged(
            self.t, names[i] + " [rad/s]", float(self.v[i]), MAX_JOINT_SPEED_RAD_S
        )

    # ------------------------------------------------------------------ diagnostics

    def mechanical_energy(self) -> float:
        """Kinetic + gravitational + cuff-spring energy of both bodies [J].

        Kinetic energy includes the reflected rotor inertia of the drives.
        Gravity potential is m g z of every body (world z up).
        """
        energy = 0.0
        for model, q, v, arm in (
            (self.exo.model, self.q[:4], self.v[:4], self._arm_base),
            (self.patient.model, self.q[4:], self.v[4:], np.zeros(4)),
        ):
            data = model.createData()
            mass = pin.crba(model, data, q)
            mass = np.triu(mass) + np.triu(mass, 1).T
            energy += 0.5 * float(v @ (mass + np.diag(arm)) @ v)
            energy += float(pin.computePotentialEnergy(model, data, q))
        stretch = self.cuffs.stretch(self.q)
        energy += 0.5 * self.cuff_params.stiffness_N_per_m * float(stretch @ stretch)
        return energy


@kernel
def _drift_and_forces(
    h: float,
    s8: np.ndarray,
    s4: np.ndarray,
    losses: np.ndarray,
    flags: np.ndarray,
    voltage_V: np.ndarray,
    patient_torque_Nm: np.ndarray,
    cuff_matrices: np.ndarray,
    cuff_params: np.ndarray,
    cuff_out: np.ndarray,
    motor_params: np.ndarray,
    motor_state: np.ndarray,
) -> int:
    """First half of :meth:`Plant.step`: drift to mid-step and every force there.

    q½ = q + (h/2) v, v½ = v + (h/2) a⁻; τ = cuffs(q½, v½) - b v - f_c tanh(v/ε)
    (+ patient torque) (+ drive torque of the exact motor step); the exo
    armature i_G² J_rotor + h b + h D_m.  Rows of ``s8``: q, v, a, q½, v½, τ,
    armature (exo, patient); of ``s4``: drive torque, sensor torque, patient
    torque, h D_m, i_G² J_rotor, i_G² J_rotor + h b.  ``flags``: friction,
    motors, patient torque given.  Returns 1 if the exo armature changed (D_m
    changes only when a drive's current enters or leaves its limit), else 0;
    -1 (and nothing done) when the voltages or patient torques are not 4.
    """
    if voltage_V.shape[0] != 4 or patient_torque_Nm.shape[0] != 4:
        return -1
    q, v, acc, qm, vm, tau = s8[0], s8[1], s8[2], s8[3], s8[4], s8[5]
    half = 0.5 * h
    for i in range(8):
        qm[i] = q[i] + v[i] * half
        vm[i] = v[i] + acc[i] * half
    cuff_forces(cuff_matrices, cuff_params, qm, vm, cuff_out)
    for i in range(8):
        t = cuff_out[1, i] - losses[0, i] * v[i]
        if flags[0]:
            t -= np.tanh(v[i] / FRICTION_SMOOTHING_RAD_S) * losses[1, i]
        tau[i] = t
    if flags[2]:
        for j in range(4):
            s4[2, j] = patient_torque_Nm[j]
            tau[4 + j] += s4[2, j]
    changed = False
    if flags[1]:
        motor_step(motor_params, motor_state, voltage_V, v[:4])
        for j in range(4):
            torque = motor_state[3, j]
            s4[0, j] = torque
            tau[j] += torque
            s4[3, j] = motor_state[5, j] * h
            arm = s4[3, j] + s4[5, j]
            changed = changed or arm != s8[6, j]
            s8[6, j] = arm
    return 1 if changed else 0


@kernel
def _kick_and_drift(
    h: float,
    s8: np.ndarray,
    s4: np.ndarray,
    acc_all: np.ndarray,
    flags: np.ndarray,
    motor_state: np.ndarray,
    cuff_out: np.ndarray,
    outputs: np.ndarray,
) -> float:
    """Second half of :meth:`Plant.step`: v⁺ = v + h a, q⁺ = q½ + (h/2) v⁺; returns |v⁺|².

    ``acc_all``: the ABA accelerations of both bodies, (8,) in q_all order.
    With drives, the applied torque τ_m - h D_m a and the sensor torque
    τ_m - h D_m a - i_G² J_rotor a (rows of ``s4`` as in :func:`_drift_and_forces`).
    Fills :attr:`Plant.outputs`.
    """
    q, v, acc, qm = s8[0], s8[1], s8[2], s8[3]
    for i in range(8):
        acc[i] = acc_all[i]
    if flags[1]:
        for j in range(4):
            s4[0, j] = s4[0, j] - s4[3, j] * acc[j]
            s4[1, j] = s4[0, j] - s4[4, j] * acc[j]
    for j in range(4):
        outputs[j] = motor_state[2, j]
        outputs[4 + j] = motor_state[1, j]
        outputs[8 + j] = s4[0, j]
        outputs[12 + j] = s4[2, j]
    for i in range(8):
        outputs[16 + i] = cuff_out[0, i]
    half = 0.5 * h
    speed2 = 0.0
    for i in range(8):
        v[i] = v[i] + acc[i] * h
        q[i] = qm[i] + v[i] * half
        speed2 += v[i] * v[i]
    return speed2
