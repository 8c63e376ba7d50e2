"""The plant's step kernels: drift to mid-step with every force, then kick and drift.

The two halves of :meth:`Plant.step <exo_ctrl.plant.plant.Plant.step>`
around the ABA call (the scheme, its implicit damping and the current
limit: :mod:`exo_ctrl.plant.plant`).  They read and write the plant's record
(:func:`~exo_ctrl.plant.plant_record.plant_fields`).

Both take the compile-time switches of the features a run may leave off
(:func:`plant_switches`, :func:`~exo_ctrl._jit.switch`): the pelvis guide,
the belt contact, compliant drives, the patient's feet on the belt and, for
the first, split cuffs.  A run without them compiles none of their kernels.
"""

from __future__ import annotations

import numpy as np

from .._jit import Status, kernel, switch
from ..model import FRICTION_SMOOTHING_RAD_S
from .compliance import rotor_forces, rotor_kick
from .contact import contact_commit, contact_forces
from .cuffs import forces_of, isotropic_forces
from .end_stops import end_stop_torques
from .energy import book_drives
from .motor import drive_cap, hold_drive, step_drives
from .patient_feet import feet_commit, patient_forces
from .pelvis import pelvis_drift, pelvis_kick

__all__ = ["MAX_JOINT_SPEED_RAD_S", "drift_and_forces", "kick_and_drift", "plant_switches"]

#: A joint speed above this is taken as divergence [rad/s].
MAX_JOINT_SPEED_RAD_S = 100.0


def plant_switches(plant: np.ndarray) -> tuple[bool | None, ...]:
    """The switches (pelvis, contact, compliant, split, feet) of the plant's record ``plant``.

    From the record's own flags, set when the plant is built: the pelvis on
    its guide, the belt contact on, compliant drives, split cuffs, the
    patient's feet on the belt.  Pass all five to :func:`drift_and_forces`,
    all but ``split`` to :func:`kick_and_drift`.
    """
    p = plant[0]
    flags = (
        p["pelvis"]["on"],
        p["contact"]["on"],
        p["compliant"],
        p["cuffs"]["split"],
        p["patient_feet"]["on"],
    )
    return tuple(switch(bool(flag)) for flag in flags)


@kernel
def drift_and_forces(
    plant: np.ndarray,
    voltage_V: np.ndarray,
    patient_torque_Nm: np.ndarray,
    given: bool,
    pelvis: bool | None,
    contact: bool | None,
    compliant: bool | None,
    split: bool | None,
    feet: bool | None,
) -> int:
    """First half of :meth:`Plant.step`: drift to mid-step and every force there.

    q½ = q + (h/2) v, v½ = v + (h/2) a⁻; τ = cuffs(q½, v½) - b v - f_c tanh(v/ε)
    + end stops(q½, v½) (+ patient torque, if ``given``) (+ drive torque of the exact motor
    step); the exo armature i_G² J_rotor + h b + h D_m (fields: PLANT_FIELDS).
    ``pelvis``, ``contact``, ``compliant``, ``split``, ``feet``: :func:`plant_switches`.
    Returns ``Status.WRONG_LENGTH`` (nothing done) when the voltages or
    patient torques are not 4, else ``Status.OK``.
    """
    if voltage_V.shape[0] != 4 or patient_torque_Nm.shape[0] != 4:
        return Status.WRONG_LENGTH.value
    p = plant[0]
    q, v, acc, qm, vm, tau = p.q, p.v, p.acc, p.q_mid, p.v_mid, p.tau
    h = p.h
    half = 0.5 * h
    for i in range(8):
        qm[i] = q[i] + v[i] * half
        vm[i] = v[i] + acc[i] * half
    if pelvis is not None and p.pelvis.on:  # the pelvis to mid-step; the feet ride on it
        pelvis_drift(p.pelvis, h)
        p.contact.z_pelvis = p.pelvis.z_mid
        p.contact.vz_pelvis = p.pelvis.vz_mid
    c = p.cuffs
    if split is None:  # isotropic cuffs: the split cuffs' code not compiled in
        isotropic_forces(c, qm[:], vm[:])
    else:
        forces_of(c, qm[:], vm[:])
    for i in range(8):
        t = c.tau[i] - p.b[i] * v[i]
        if p.has_friction:
            t -= np.tanh(v[i] / FRICTION_SMOOTHING_RAD_S) * p.friction[i]
        tau[i] = t
    end_stop_torques(p, qm, vm, tau)
    if contact is not None and p.contact.on:
        contact_forces(p.contact, qm, vm, tau, h)
        if feet is not None and p.patient_feet.on:  # after the exo's feet: c.any, c.fz
            patient_forces(p.contact, p.patient_feet, qm, vm, tau, h)
    if given:
        for j in range(4):
            p.patient_torque[j] = patient_torque_Nm[j]
            tau[4 + j] += p.patient_torque[j]
    changed = False
    if compliant is not None and p.compliant:
        rotor_forces(p, voltage_V, qm, vm, tau)
    elif p.has_motors:
        m = p.motors
        step_drives(m, voltage_V, v[:4])
        for j in range(4):
            torque = m.torque[j]
            p.drive_torque[j] = torque
            tau[j] += torque
            p.damping_m[j] = m.damping[j] * h
            arm = p.damping_m[j] + p.arm_const[j]
            changed = changed or arm != p.armature[j]
            p.armature[j] = arm
    p.armature_changed = changed
    return Status.OK.value


@kernel
def kick_and_drift(
    plant: np.ndarray,
    acc_all: np.ndarray,
    pelvis: bool | None,
    contact: bool | None,
    compliant: bool | None,
    feet: bool | None,
) -> int:
    """Second half of :meth:`Plant.step`: v⁺ = v + h a, q⁺ = q½ + (h/2) v⁺.

    ``acc_all``: the ABA accelerations of both bodies, (8,) in q_all order;
    ``pelvis``, ``contact``, ``compliant``, ``feet``: :func:`plant_switches`.
    With drives, the applied torque τ_m - h D_m a and the sensor torque
    τ_m - h D_m a - i_G² J_rotor a; the step's applied voltage, mean current
    and cuff forces.

    **Current limit.**  τ_m - h D_m a is the mean torque linearised at the
    end-of-step speed, so its current (τ_m - h D_m a) / (i_G k_m) is bounded by
    I_max like any other.  h D_m is 0.15 N·m·s/rad at 1 ms but 3.0 at 10 ms:
    at 100 Hz the correction alone reached 170 N·m (241 N·m against the
    150 N·m cap).  The cap is the smaller of the drive's own, η^s i_G k_m
    I_max (η^s the gear factor, :mod:`exo_ctrl.plant.motor`), and the joint's
    rated effort (URDF ``<limit effort>``: a braking gearbox passes the motor
    torque over η, and the driver keeps the output within the rating).  A
    drive beyond the cap is held there (torque in ``tau`` at the limit, no
    damping, the current that gives it) and nothing is stepped: the caller
    solves the accelerations again.  A held drive is not held
    again: at most four re-solves; 1 kHz runs of the default scenario need none.

    Returns:
        ``Status.DIVERGED`` when a joint speed is not below
        :data:`MAX_JOINT_SPEED_RAD_S` (NaN included), else ``Status.OK``
        (with ``resolve`` set when a drive was held at its limit).

    """
    p = plant[0]
    p.resolve = False
    if p.has_motors and not p.compliant:
        m = p.motors
        held = False
        for j in range(4):
            cap, i_held = drive_cap(m, p.effort[j], j)
            linear = p.drive_torque[j] - p.damping_m[j] * acc_all[j]
            if abs(linear) > cap:
                sign = 1.0 if linear > 0.0 else -1.0
                limit = sign * cap
                p.tau[j] += limit - p.drive_torque[j]
                p.drive_torque[j] = limit
                p.damping_m[j] = 0.0
                p.armature[j] = p.arm_const[j]
                hold_drive(m, j, limit, sign * i_held)
                held = True
        if held:
            p.resolve = True
            return Status.OK.value
    q, v, acc, qm = p.q, p.v, p.acc, p.q_mid
    for i in range(8):
        acc[i] = acc_all[i]
    if compliant is not None and p.compliant:
        rotor_kick(p)
    elif p.has_motors:
        book_drives(p.motors, v[:])  # the step is final; ω held: the start of step's
        for j in range(4):
            p.drive_torque[j] = p.drive_torque[j] - p.damping_m[j] * acc[j]
            p.sensor_torque[j] = p.drive_torque[j] - p.arm_base[j] * acc[j]
    m = p.motors
    f = p.cuffs.f
    for j in range(4):
        p.voltage[j] = m.u[j]
        p.current[j] = m.mean[j]
        p.cuff_force[j, 0] = f[j]
        p.cuff_force[j, 1] = f[4 + j]
    if contact is not None and p.contact.on:
        if feet is not None and p.patient_feet.on:
            feet_commit(p.contact, p.patient_feet, p.h)
        else:
            contact_commit(p.contact, p.h)
    half = 0.5 * p.h
    speed2 = 0.0
    for i in range(8):
        v[i] = v[i] + acc[i] * p.h
        q[i] = qm[i] + v[i] * half
        speed2 += v[i] * v[i]
    if pelvis is not None and p.pelvis.on:
        speed2 += pelvis_kick(p.pelvis, p.h)
    return Status.OK.value if speed2 < MAX_JOINT_SPEED_RAD_S**2 else Status.DIVERGED.value
