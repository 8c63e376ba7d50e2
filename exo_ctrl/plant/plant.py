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
correction, held within the drive's current limit: :func:`~exo_ctrl.plant.step.kick_and_drift`);
``sensor_torque`` is what a joint torque sensor between the
gearbox and the link reads, drive_torque - i_G² J_rotor a (the rotor's
inertia is on the motor side of the sensor).  With joint compliance
(:mod:`exo_ctrl.plant.compliance`, off by default) each rotor is a body of its
own behind a spring–damper and the sensor reads the spring's torque.

With the belt and foot contact (:mod:`exo_ctrl.plant.contact`, off by
default) the feet's normal forces join the mid-step forces, and on a step
with a foot in contact the friction impulses are solved after ABA (one CRBA
for the legs' mass matrices) and added to its accelerations before the kick.
Without contact the step is the same arithmetic as before, bit for bit.

With the pelvis on its vertical guide (:mod:`exo_ctrl.plant.pelvis`, off by
default) the model gains a ninth coordinate z ahead of q_all (Pinocchio's
order [z, q_exo, q_patient]), stepped by the same leapfrog; the feet's
heights and normal speeds include z and ż, their normal forces push on z,
and the friction solve takes the full 9×9 mass matrix (the legs are coupled
through the pelvis).

With the patient's feet on the belt too (``ContactParams.patient_feet``,
:mod:`exo_ctrl.plant.patient_feet`, off by default) their normal forces act
on the patient's joints and the friction solve takes all four feet.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from .. import _validate as _v
from .._jit import Status, check, record
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES, BodyModel, combined_model
from .compliance import CompliantJoint, Rotors
from .contact import (
    ContactParams,
    FootContact,
    friction_impulse,
    friction_impulse_coupled,
)
from .cuffs import CuffParams, CuffSet
from .drive import MotorParams
from .end_stops import EndStopParams
from .motor import MotorBank
from .patient_feet import PatientFeet, feet_friction, feet_friction_coupled
from .pelvis import (
    PelvisParams,
    pelvis_model,
    pelvis_pack,
    pelvis_unpack,
)
from .plant_record import plant_fields
from .step import MAX_JOINT_SPEED_RAD_S, drift_and_forces, kick_and_drift, plant_switches

__all__ = ["MAX_JOINT_SPEED_RAD_S", "Plant"]


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
        end_stops: the exoskeleton joints' hard stops at the URDF limits
            (:mod:`exo_ctrl.plant.end_stops`; default on).
        compliance: a spring–damper between each drive and its link
            (:mod:`exo_ctrl.plant.compliance`; default off: rigid).
        contact: the belt and the foot–belt contact (:mod:`exo_ctrl.plant.contact`;
            default off: the feet in free air).
        belt_height_m: the belt's top below the hip [m] (the plan's H_s),
            unless the contact's belt sets its own.
        pelvis: the pelvis on a vertical guide with body-weight support
            (:mod:`exo_ctrl.plant.pelvis`; default: fixed, as the paper).

    Raises:
        InvalidModel: a body without exactly the four joints in JOINT_NAMES
            order, or the two models' gravities differ.
        InvalidParameter: a step that is not a positive number, or
            compliance the step cannot integrate (:class:`~exo_ctrl.plant.compliance.Rotors`).

    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel,
        dt: float = 1e-3,
        motors: MotorParams | None = None,
        cuffs: CuffParams | None = None,
        joint_losses: bool = True,
        end_stops: EndStopParams | None = None,
        compliance: CompliantJoint | None = None,
        contact: ContactParams | None = None,
        belt_height_m: float = 0.9,
        pelvis: PelvisParams | None = None,
    ) -> None:
        for body in (exo, patient):
            body.require_legs_only("the plant")
        if not (math.isfinite(dt) and dt > 0):
            raise InvalidParameter("dt", dt, "> 0 s")
        self.exo = exo
        self.patient = patient
        self.dt = float(dt)
        #: Both bodies in one Pinocchio model (one ABA call per step), and its data.
        self.model = combined_model(exo, patient)
        self.data = self.model.createData()
        self.motor_params = motors
        # State, parameters and outputs in one record (plant_fields), filled in
        # place by the step kernels, the drives' and the cuffs' records among
        # its fields; the public arrays are views of it.
        self.record = record(plant_fields())
        r = self.record
        self.motors = MotorBank(4, motors, into=r["motors"]) if motors is not None else None
        self.compliance = compliance if compliance is not None else CompliantJoint()
        #: The rotors behind the springs (with compliance; a rigid drive's are the links').
        self.rotors = Rotors(r, self.compliance, motors, exo.model, self.dt)
        rotor = self.rotors.link_armature_kgm2
        losses = 1.0 if joint_losses else 0.0
        self._b = losses * np.concatenate((exo.damping, patient.damping))
        self._fr = losses * np.concatenate((exo.friction, patient.friction))
        self._has_friction = bool(np.any(self._fr > 0))
        hip_e = exo.legs["left"].hip_xz
        hip_p = patient.legs["left"].hip_xz
        self.patient_offset_xz = (hip_e[0] - hip_p[0], hip_e[1] - hip_p[1])
        self.cuff_params = cuffs or CuffParams()
        self.cuffs = CuffSet(
            exo, patient, self.cuff_params, self.patient_offset_xz, into=r["cuffs"]
        )
        self._p = r[0]
        self.q, self.v, self._acc = r["q"][0], r["v"][0], r["acc"][0]
        self._q_mid, self._v_mid, self._tau, self._arm = (
            r["q_mid"][0], r["v_mid"][0], r["tau"][0], r["armature"][0]
        )  # fmt: skip
        #: Drive torque applied at each joint over the last step [N·m].
        self.drive_torque = r["drive_torque"][0]
        #: Joint torque sensor reading at each drive output (gearbox to link) [N·m].
        self.sensor_torque = r["sensor_torque"][0]
        #: Patient joint torque over the last step [N·m].
        self.patient_torque = r["patient_torque"][0]
        self._arm_base, self._arm_const = r["arm_base"][0], r["arm_const"][0]
        self._changed = r["armature_changed"]
        self._resolve = r["resolve"]
        self._arm_base[:] = rotor
        effort = np.asarray(exo.effort_limit, dtype=float)
        r["effort"][0] = np.where(np.isfinite(effort) & (effort > 0.0), effort, np.inf)
        self.end_stops = end_stops if end_stops is not None else EndStopParams()
        lower, upper = exo.position_limits
        r["stop_lower"][0] = lower
        r["stop_upper"][0] = upper
        self._p["stop_k"] = self.end_stops.stiffness_Nm_per_rad
        self._p["stop_c"] = self.end_stops.damping_Nm_s_per_rad
        self._p["has_stops"] = self.end_stops.enabled
        #: The end stops' torque on each exoskeleton joint over the last step [N·m].
        self.end_stop_torque = r["stop_torque"][0]
        r["b"][0] = self._b
        r["friction"][0] = self._fr
        self._p["h"] = self.dt
        self._p["has_friction"] = self._has_friction
        self._p["has_motors"] = self.motors is not None
        # The combined model's armature: exo = rotor inertia + h b (implicit
        # joint damping, constant) + h D_m (implicit back-EMF damping, per
        # step); patient = h b.
        self._arm_const[:] = self._arm_base + self.dt * self._b[:4]
        self._arm[:4] = self._arm_const
        self._arm[4:] = self.dt * self._b[4:]
        self.model.armature = self._arm
        #: The belt and the feet on it (:mod:`exo_ctrl.plant.contact`).
        self.contact = FootContact(exo, contact or ContactParams(), belt_height_m, r["contact"])
        self._contact_on = self.contact.params.enabled
        self._contact_any, self._contact_acc = r["contact"]["any"], r["contact"]["acc"][0]
        #: The patient's feet on the belt (:mod:`exo_ctrl.plant.patient_feet`; off by default).
        self.patient_feet = PatientFeet(
            patient, self.contact.params, self.patient_offset_xz, self.contact.z_belt,
            r["patient_feet"],
        )  # fmt: skip
        feet = self.patient_feet.on  # the friction solve of four feet, else of the exo's two
        self._friction = feet_friction if feet else friction_impulse
        self._friction_coupled = feet_friction_coupled if feet else friction_impulse_coupled
        #: The pelvis's guide and support (:mod:`exo_ctrl.plant.pelvis`).
        self.pelvis_params = pelvis if pelvis is not None else PelvisParams()
        self._pelvis_on = self.pelvis_params.supported
        self.pelvis = r["pelvis"]
        if self._pelvis_on:
            #: Both bodies on the pelvis's z: q = [z, q_all] for ABA.
            self.model = pelvis_model(self.model, patient, self.pelvis_params)
            self.data = self.model.createData()
            pel = self.pelvis[0]
            pel["on"] = True
            pel["support"] = self.pelvis_params.support_N
            pel["mass"] = pin.computeTotalMass(self.model)
            pel["lower"], pel["upper"] = -self.pelvis_params.travel_m, self.pelvis_params.travel_m
            pel["stop_k"] = self.pelvis_params.stop_stiffness_N_per_m
            pel["stop_c"] = self.pelvis_params.stop_damping_N_s_per_m
            pel["arm9"][1:] = self._arm
            self.model.armature = pel["arm9"]
            self._q9, self._v9, self._tau9 = pel["q9"], pel["v9"], pel["tau9"]
            self._arm9, self._acc9_tail = pel["arm9"], self.pelvis["acc9"][0, 1:]
        self.t = 0.0
        if self.motors is not None:
            self.motors.set_step(self.dt)
        # The step kernels' switches: the features this plant leaves off are not compiled.
        self._switches = plant_switches(self.record)
        self._kick_switches = (*self._switches[:3], self._switches[4])

    # ------------------------------------------------------------------ state

    def reset(
        self,
        q_exo: np.ndarray,
        v_exo: np.ndarray,
        q_patient: np.ndarray | None = None,
        v_patient: np.ndarray | None = None,
        current_A: np.ndarray | float = 0.0,
        fit_cuffs: bool = True,
        pelvis_z_m: float = 0.0,
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
            pelvis_z_m: the pelvis's height above its nominal [m], at rest
                (with the pelvis on its guide).

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
        self.rotors.reset()
        self.contact.reset(self.contact.belt["v_set"][0])
        self.patient_feet.reset()
        pel = self.pelvis[0]
        z = float(pelvis_z_m) if self._pelvis_on else 0.0
        pel["z"] = pel["z_mid"] = z
        pel["vz"] = pel["vz_mid"] = pel["az"] = 0.0
        pel["locked"] = False
        self.contact.record["z_pelvis"] = z
        self.contact.record["vz_pelvis"] = 0.0

    def lock_pelvis(self) -> None:
        """Lock the harness at the pelvis's present height (a stop; module :mod:`.pelvis`)."""
        if self._pelvis_on and not self.pelvis["locked"][0]:
            self.pelvis["lock_z"][0] = self.pelvis["z"][0]
            self.pelvis["locked"][0] = True

    @property
    def pelvis_z(self) -> float:
        """The pelvis's height above its nominal [m] (0 with the pelvis fixed)."""
        return float(self.pelvis["z"][0])

    @property
    def cuff_force(self) -> np.ndarray:
        """Cuff forces on the exoskeleton over the last step (mid-step), (4, 2) [N]."""
        return self.cuffs.force

    # ------------------------------------------------------------------ stepping

    def step(self, voltage_V: np.ndarray, patient_torque_Nm: np.ndarray | None = None) -> None:
        """Advance by one step h with the drive voltages and patient torques held.

        Args:
            voltage_V: commanded drive voltages, (4,) [V] (one equal to its
                drive's ``u_ff`` selects current mode: ``motors.current_command``).
            patient_torque_Nm: patient joint torques, (4,) [N·m] (None: zero).

        Raises:
            SimulationDiverged: a joint speed became non-finite or exceeded
                :data:`MAX_JOINT_SPEED_RAD_S`.
            InvalidParameter: an input that is not 4 numbers (or one).

        """
        given = patient_torque_Nm is not None
        if not given:
            patient_torque_Nm = self.patient_torque
        if not (type(voltage_V) is type(patient_torque_Nm) is np.ndarray):
            voltage_V, patient_torque_Nm = _v.arrays(
                (4,), voltage_V=voltage_V, patient_torque_Nm=patient_torque_Nm
            )
        status = drift_and_forces(self.record, voltage_V, patient_torque_Nm, given, *self._switches)
        if status:
            check(status, "Plant.step", voltage_V=voltage_V, patient_torque_Nm=patient_torque_Nm)
        self.kicked(kick_and_drift(self.record, self.mid_step(), *self._kick_switches))

    def mid_step(self) -> np.ndarray:
        """The step after :func:`~.step.drift_and_forces`: t + h, the accelerations at mid-step.

        The kick's accelerations of both bodies (ABA), damping implicit through
        the armature, which the drift may have changed.
        """
        if self._changed[0] and not self._pelvis_on:
            self.model.armature = self._arm
        self.t += self.dt
        return self._accelerations()

    def kicked(self, status: int) -> None:
        """The step after :func:`~.step.kick_and_drift` returned ``status``.

        A drive that reached its current limit kicks again (at most 4 times);
        a divergence raises :class:`~exo_ctrl.exceptions.SimulationDiverged`.
        """
        while self._resolve[0]:
            if not self._pelvis_on:
                self.model.armature = self._arm
            status = kick_and_drift(self.record, self._accelerations(), *self._kick_switches)
        if status:
            self._diverged()

    def step_arguments(self) -> tuple[tuple, tuple]:
        """The step's kernels' arguments for a fused tick (:mod:`exo_ctrl.sim.fused`).

        :func:`~.step.drift_and_forces`'s after the record and the voltage (no
        patient torque given, the switches) and :func:`~.step.kick_and_drift`'s
        switches; the fused tick calls them around :meth:`mid_step`, then :meth:`kicked`.
        """
        return (self.patient_torque, False, *self._switches), self._kick_switches

    def _accelerations(self) -> np.ndarray:
        """ABA's accelerations at mid-step, with the feet's friction impulses if in contact."""
        if self._pelvis_on:  # [z, q_all]; the armature changes with the drives' damping
            pelvis_pack(self.record)
            self.model.armature = self._arm9
            acc = pin.aba(self.model, self.data, self._q9, self._v9, self._tau9)
            if self._contact_on and self._contact_any[0]:
                mass = pin.crba(self.model, self.data, self._q9)
                self._friction_coupled(self.record, acc, mass)
            else:
                pelvis_unpack(self.pelvis[0], acc)
            return self._acc9_tail
        acc = pin.aba(self.model, self.data, self._q_mid, self._v_mid, self._tau)
        if self._contact_on and self._contact_any[0]:
            mass = pin.crba(self.model, self.data, self._q_mid)
            self._friction(self.record, acc, mass)
            return self._contact_acc
        return acc

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
        check(
            Status.DIVERGED,
            "Plant.step",
            self.t,
            quantity=names[i] + " [rad/s]",
            value=float(self.v[i]),
            limit=MAX_JOINT_SPEED_RAD_S,
        )

    # ------------------------------------------------------------------ diagnostics

    def mechanical_energy(self) -> float:
        """Kinetic + gravitational + cuff-spring + end-stop-spring energy of both bodies [J].

        Kinetic energy includes the reflected rotor inertia of the drives.
        Gravity potential is m g z of every body (world z up).  An end stop
        stores ½ K d² at a penetration d.
        """
        energy = 0.0
        z = self.pelvis_z
        if self._pelvis_on:  # one model: the trunk's m g z, the support's potential -F_s z
            pel = self.pelvis[0]
            model = pin.Model(self.model)
            model.armature = np.zeros(9)
            bodies = [
                (
                    model,
                    np.r_[z, self.q],
                    np.r_[pel["vz"], self.v],
                    np.r_[0.0, self._arm_base, np.zeros(4)],
                )
            ]
            depth = max(z - pel["upper"], 0.0) + max(pel["lower"] - z, 0.0)
            energy += 0.5 * float(pel["stop_k"]) * depth**2 - float(pel["support"]) * z
            if pel["locked"]:
                energy += 0.5 * float(pel["stop_k"]) * (z - float(pel["lock_z"])) ** 2
        else:
            bodies = [
                (self.exo.model, self.q[:4], self.v[:4], self._arm_base),
                (self.patient.model, self.q[4:], self.v[4:], np.zeros(4)),
            ]
        for model, q, v, arm in bodies:
            data = model.createData()
            mass = pin.crba(model, data, q)
            mass = np.triu(mass) + np.triu(mass, 1).T
            energy += 0.5 * float(v @ (mass + np.diag(arm)) @ v)
            energy += float(pin.computePotentialEnergy(model, data, q))
        energy += self.cuffs.spring_energy(self.q)
        if self.end_stops.enabled:
            lower, upper = self.record["stop_lower"][0], self.record["stop_upper"][0]
            depth = np.maximum(self.q[:4] - upper, 0.0) + np.maximum(lower - self.q[:4], 0.0)
            energy += 0.5 * self.end_stops.stiffness_Nm_per_rad * float(depth @ depth)
        if self._contact_on:  # the belt's kinetic energy, the contact springs' k δⁿ⁺¹ / (n + 1)
            c = self.contact.record[0]
            energy += 0.5 * float(c["belt"]["mass"] * c["belt"]["v"] ** 2)
            depth = self.contact.penetration(self.q, z)
            if self.patient_feet.on:  # the patient's feet's springs, the same law
                depth = np.concatenate((depth, self.patient_feet.penetration(self.q, z)))
            n, depth = float(c["n"]), np.maximum(depth, 0.0)
            energy += float(c["k"]) * float(np.sum(depth ** (n + 1.0))) / (n + 1.0)
        return energy + self.rotors.energy()  # with compliance, the rotors' and springs'
