"""The log rows of a control tick: what it measured, and what it applied, by signal name.

Two compiled calls per tick (:mod:`exo_ctrl.sim.tick`): :func:`write_measured`
(the state at t_k and what the device measured and estimated) before the
command, and :func:`write_applied` (the command, what acted over
[t_k, t_k+1), the belt, the feet and the pelvis) after the plant step; the
fields are the declared signals (:mod:`exo_ctrl.sim.schema`).
"""

from __future__ import annotations

from .._jit import kernel

__all__ = ["write_applied", "write_measured"]


@kernel
def write_measured(log, row, plant, readings, estimate, cuffs):
    """The state at t_k and what the device measured and estimated, into log row ``row``.

    ``plant``, ``readings``, ``estimate``: the records of the plant, the
    sensors and the estimator (fields ``q``, ``v`` (8: exo, patient);
    ``q``, ``dq``, ``tau``; ``tau_ext``, ``cuff_normal``, ``cuff_force``);
    ``cuffs``: the cuff sensors' readings record (an axis not read: 0).
    """
    r = log[row]
    p = plant[0]
    s = readings[0]
    e = estimate[0]
    c = cuffs[0]
    r.cuff_sensor_fresh = c.fresh
    for j in range(4):
        r.cuff_sensor_normal[j] = c.reading[j, 0] if c.axes > 0 else 0.0
        r.cuff_sensor_along[j] = c.reading[j, 1] if c.axes > 1 else 0.0
    for j in range(4):
        r.q[j] = p.q[j]
        r.q_patient[j] = p.q[4 + j]
        r.dq[j] = p.v[j]
        r.dq_patient[j] = p.v[4 + j]
        r.q_meas[j] = s.q[j]
        r.dq_meas[j] = s.dq[j]
        r.tau_sensor[j] = s.tau[j]
        r.tau_ext_est[j] = e.tau_ext[j]
        r.cuff_normal_est[j] = e.cuff_normal[j]
        r.cuff_force_est[j, 0] = e.cuff_force[j, 0]
        r.cuff_force_est[j, 1] = e.cuff_force[j, 1]


@kernel
def write_applied(log, row, controller, supervisor, plant, encoder, phase, foot):
    """The command and what acted over [t_k, t_k+1), into log row ``row``.

    ``controller``: its record (``u_cmd``, ``active_constraints``,
    ``failures``, ``margin``); ``supervisor``: its record (``state``); ``plant``: its
    record (``voltage``, ``current``, ``drive_torque``, ``patient_torque``,
    ``stop_torque``, ``deflection``, ``cuff_force``; ``contact``,
    :mod:`exo_ctrl.plant.contact`, all zero with contact off; ``patient_feet``,
    :mod:`exo_ctrl.plant.patient_feet`, zero with them off; ``pelvis``,
    height and speed zero when fixed); ``encoder``: the belt encoder's
    record (``speed``); ``phase``: the path mode's record, whose ``row`` is
    the plan row of the device's phase (-1 in other modes); ``foot``: the
    foot plates' load cells' record.
    """
    r = log[row]
    c = controller[0]
    p = plant[0]
    r.safety_state = supervisor[0].state
    r.qp_active = c.active_constraints
    r.qp_failures = c.failures
    for j in range(4):
        r.voltage_cmd[j] = c.u_cmd[j]
        r.cuff_bound_margin[j] = c.margin[j]
        r.voltage[j] = p.voltage[j]
        r.current[j] = p.current[j]
        r.drive_torque[j] = p.drive_torque[j]
        r.patient_torque[j] = p.patient_torque[j]
        r.end_stop_torque[j] = p.stop_torque[j]
        r.joint_deflection[j] = p.deflection[j]
        r.cuff_force[j, 0] = p.cuff_force[j, 0]
        r.cuff_force[j, 1] = p.cuff_force[j, 1]
    ct = p.contact
    b = ct.belt
    for f in range(2):
        r.ground_force[f, 0] = ct.ft[f]
        r.ground_force[f, 1] = ct.fn[f]
        r.foot_slip[f] = ct.slip[f]
        r.foot_penetration[f] = ct.pen[f]
        r.contact_state[f] = ct.state[f]
        r.normal_force_rate[f] = ct.fn_rate[f]
        r.touchdown_velocity[f, 0] = ct.td_vx[f]
        r.touchdown_velocity[f, 1] = ct.td_vz[f]
    pf = p.patient_feet  # zero unless the patient's feet meet the belt
    for f in range(2):
        r.patient_ground_force[f, 0] = pf.ft[f]
        r.patient_ground_force[f, 1] = pf.fn[f]
        r.patient_foot_slip[f] = pf.slip[f]
        r.patient_foot_penetration[f] = pf.pen[f]
        r.patient_contact_state[f] = pf.state[f]
    r.belt_speed = b.v
    r.belt_speed_set = b.v_set
    r.belt_speed_meas = encoder[0].speed
    r.belt_drive_force = b.f_drive
    r.path_phase = phase[0].row
    fl = foot[0]
    for j in range(2):
        r.foot_force_meas[j, 0] = fl.force[j, 0]
        r.foot_force_meas[j, 1] = fl.force[j, 1]
    for j in range(4):
        r.tau_ground_meas[j] = fl.tau[j]
    r.pelvis_z = p.pelvis.z
    r.pelvis_vz = p.pelvis.vz
    r.pelvis_stop_force = p.pelvis.stop_force
