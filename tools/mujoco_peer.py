"""The peer a user would pick instead: the same bodies and cuffs in MuJoCo, a plain Python PD loop.

    .venv/bin/python tools/mujoco_peer.py [--seconds S] [--repeat N]

Needs MuJoCo (``.venv/bin/pip install -e ".[bench]"``; a benchmark-only dependency).
:func:`peer_model` writes an MJCF model of a run's exoskeleton and patient
legs from the same Pinocchio models the run uses (each joint's placement,
axis and limits; each body's mass, centre of mass and inertia; the joints'
viscous damping; the drives' rotor inertia reflected through the gearbox
as the exoskeleton joints' armature), with the pelvis fixed and the feet in
free air, as the run's ``paper-free-air`` scenario.  Each cuff is two
spatial tendons between the exoskeleton's cuff point and the patient's,
one across the exoskeleton link and one along it, each a linear spring and
damper of the cuff's normal (k_n, C_n) or shear (k_u, C_u) stiffness and
damping (:class:`~exo_ctrl.plant.cuffs.CuffParams`; the published split
cuffs by default).  A tendon runs from a site ``LEVER_M`` off the cuff
point on the exoskeleton link to the patient's cuff point, its rest length
``LEVER_M``: for the millimetres a cuff stretches, its force is the split
spring's (the part across the tendon is T/L of it, 10⁻³ relative at 1 mm).

:func:`run_peer` then steps it with what a user writes first: a loop in
Python that reads the joint angles and speeds, computes a joint PD torque
τ = K_p (q* − q) + K_d (q̇* − q̇) on the run's plan, clipped at the URDF's
effort, and calls ``mj_step`` once per control period (MuJoCo's timestep
the run's Δt, its ``implicitfast`` integrator).  K_p and K_d are the run's
PD gains in volts turned into joint torque through the drive
(i_G k_t / R), with the back-EMF's damping i_G² k_t / (k_ω R) added to
K_d.  No motors' electrics, sensors, estimator, supervisor or logging: the
floor of what a user's own loop costs.

Prints the real-time factor (simulated time over wall time, best of
``--repeat`` runs) and, as a check that the bodies are the same, the RMS
tracking error beside the run's own PD on the same plan.  :func:`mass_matrix_pair` gives
both simulators' joint-space mass matrices at one posture
(``tests/test_mujoco_peer.py`` holds them equal).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

try:
    import mujoco
except ImportError:  # reported by main(); the module stays importable for its docstring
    mujoco = None

from exo_ctrl.model import CUFF_NAMES, BodyModel
from exo_ctrl.plant.cuffs import CuffSet
from exo_ctrl.sim import Setup, SimConfig, build, simulate, start_on_plan

#: Distance from a cuff point to the site its two tendons start from [m].
LEVER_M = 1.0


def _axis(joint: pin.JointModel) -> np.ndarray:
    """A revolute joint's axis in its own frame."""
    name = joint.shortname()
    if name == "JointModelRevoluteUnaligned":
        return np.asarray(joint.extract().axis, dtype=float)
    letter = name[-1]
    return np.eye(3)["XYZ".index(letter)]


def _vec(x: np.ndarray) -> str:
    return " ".join(f"{float(v):.12g}" for v in x)


def _bodies(body: BodyModel, prefix: str, root_xyz: np.ndarray, armature: np.ndarray) -> str:
    """MJCF bodies of one model's tree, its root joints placed at ``root_xyz`` in the world."""
    m = body.model
    data = m.createData()
    pin.framesForwardKinematics(m, data, pin.neutral(m))
    driven = set(body.joint_ids)
    children: dict[int, list[int]] = {}
    for j in range(1, m.njoints):
        children.setdefault(m.parents[j], []).append(j)
    sites: dict[int, list[str]] = {}
    for c, fid in enumerate(body.cuff_frame_ids):
        frame = m.frames[fid]
        joint = frame.parentJoint
        point = frame.placement.translation
        rows = [f'<site name="{prefix}{CUFF_NAMES[c]}" pos="{_vec(point)}"/>']
        if prefix == "exo_":  # the tendons' start: across and along the link
            along = data.oMf[fid].translation - data.oMi[joint].translation
            along[1] = 0.0
            along /= max(float(np.linalg.norm(along)), 1e-12)
            normal = np.array([along[2], 0.0, -along[0]])  # u turned by +90° about y
            rot = data.oMi[joint].rotation.T
            for tag, direction in (("n", normal), ("u", along)):
                off = point + LEVER_M * (rot @ direction)
                rows.append(f'<site name="{prefix}{CUFF_NAMES[c]}_{tag}" pos="{_vec(off)}"/>')
        sites.setdefault(joint, []).extend(rows)

    def emit(j: int) -> str:
        place = m.jointPlacements[j]
        pos = place.translation + (root_xyz if m.parents[j] == 0 else 0.0)
        quat = pin.Quaternion(place.rotation)
        inertia = m.inertias[j]
        i3 = inertia.inertia
        full = [i3[0, 0], i3[1, 1], i3[2, 2], i3[0, 1], i3[0, 2], i3[1, 2]]
        lo, hi = m.lowerPositionLimit[m.idx_qs[j]], m.upperPositionLimit[m.idx_qs[j]]
        slot = list(body.joint_ids).index(j) if j in driven else None
        arm = armature[slot] if slot is not None else 0.0
        damping = body.damping[slot] if slot is not None else 0.0
        inner = "".join(emit(k) for k in children.get(j, []))
        return (
            f'<body name="{prefix}{m.names[j]}" pos="{_vec(pos)}" '
            f'quat="{quat.w:.15g} {quat.x:.15g} {quat.y:.15g} {quat.z:.15g}">'
            f'<joint name="{prefix}{m.names[j]}" type="hinge" axis="{_vec(_axis(m.joints[j]))}" '
            f'range="{lo:.12g} {hi:.12g}" limited="false" damping="{damping:.12g}" '
            f'armature="{arm:.12g}"/>'
            f'<inertial pos="{_vec(inertia.lever)}" mass="{inertia.mass:.12g}" '
            f'fullinertia="{_vec(full)}"/>' + "".join(sites.get(j, [])) + inner + "</body>"
        )

    return "".join(emit(j) for j in children.get(0, []))


def peer_model(setup: Setup) -> str:
    """The MJCF text of ``setup``'s bodies and cuffs (module docstring)."""
    plant = setup.plant
    offset = np.array([plant.patient_offset_xz[0], 0.0, plant.patient_offset_xz[1]])
    armature = np.asarray(plant.model.armature)  # the rotors' and the plant's own, per joint
    cuffs = plant.cuff_params
    tendons = []
    for name in CUFF_NAMES:
        for tag, k, c in (
            ("n", cuffs.stiffness_N_per_m, cuffs.damping_N_s_per_m),
            ("u", cuffs.shear_stiffness_N_per_m, cuffs.shear_damping_N_s_per_m),
        ):
            tendons.append(
                f'<spatial name="{name}_{tag}" stiffness="{k:.12g}" damping="{c:.12g}" '
                f'springlength="{LEVER_M:.12g}"><site site="exo_{name}_{tag}"/>'
                f'<site site="patient_{name}"/></spatial>'
            )
    gravity = setup.exo.model.gravity.linear
    actuators = "".join(
        f'<motor name="{setup.exo.model.names[j]}" joint="exo_{setup.exo.model.names[j]}"/>'
        for j in setup.exo.joint_ids
    )
    return (
        '<mujoco model="exo_ctrl_peer"><compiler angle="radian"/>'
        f'<option timestep="{setup.config.dt:.12g}" integrator="implicitfast" '
        f'gravity="{_vec(gravity)}"/>'
        "<worldbody>"
        + _bodies(setup.exo, "exo_", np.zeros(3), armature[:4])
        + _bodies(setup.patient, "patient_", offset, armature[4:])
        + "</worldbody><tendon>"
        + "".join(tendons)
        + f"</tendon><actuator>{actuators}</actuator></mujoco>"
    )


def pd_gains(setup: Setup) -> tuple[np.ndarray, np.ndarray]:
    """The run's PD gains as joint torque gains: K_p [N·m/rad], K_d [N·m·s/rad]."""
    motor, gains = setup.device_motor, setup.config.gains
    per_volt = motor.gear_ratio * motor.torque_constant_Nm_per_A / motor.resistance_ohm
    emf = motor.gear_ratio / motor.speed_constant_rad_per_Vs
    kp, kd = np.broadcast_to(gains.kp, 4), np.broadcast_to(gains.kd, 4)
    return kp * per_volt, kd * per_volt + emf * per_volt


class Peer:
    """The MuJoCo model and data of a run's bodies, at the run's start."""

    def __init__(self, setup: Setup) -> None:
        start_on_plan(setup)
        self.setup = setup
        self.model = mujoco.MjModel.from_xml_string(peer_model(setup))
        self.data = mujoco.MjData(self.model)
        names = [setup.exo.model.names[j] for j in setup.exo.joint_ids]
        pat = [setup.patient.model.names[j] for j in setup.patient.joint_ids]
        jnt = mujoco.mjtObj.mjOBJ_JOINT
        self.exo_q = [
            self.model.jnt_qposadr[mujoco.mj_name2id(self.model, jnt, f"exo_{n}")] for n in names
        ]
        self.patient_q = [
            self.model.jnt_qposadr[mujoco.mj_name2id(self.model, jnt, f"patient_{n}")] for n in pat
        ]
        self.reset()

    def reset(self) -> None:
        """Both bodies at the plant's start (the plan's first row, the patient settled)."""
        mujoco.mj_resetData(self.model, self.data)
        q = self.setup.plant.q
        self.data.qpos[self.exo_q] = q[:4]
        self.data.qpos[self.patient_q] = q[4:8]
        mujoco.mj_forward(self.model, self.data)

    def at(self, q_all: np.ndarray, v_all: np.ndarray | None = None) -> np.ndarray:
        """Both bodies at ``q_all`` (``v_all``) = [exo, patient]; their qpos indices (8,)."""
        order = np.asarray(self.exo_q + self.patient_q)
        self.data.qpos[order] = q_all
        if v_all is not None:
            self.data.qvel[order] = v_all
        mujoco.mj_forward(self.model, self.data)
        return order


def run_peer(peer: Peer) -> tuple[float, np.ndarray]:
    """The plain Python PD loop over the plan: its wall time [s] and the joint angles (n, 4)."""
    plan, d, m = peer.setup.plan, peer.data, peer.model
    kp, kd = pd_gains(peer.setup)
    effort = np.asarray(peer.setup.exo.effort_limit, dtype=float)
    qi = np.asarray(peer.exo_q)
    n = len(plan.t)
    q_log = np.empty((n, 4))
    peer.reset()
    start = time.perf_counter()
    for k in range(n):  # the loop a user writes first
        q, dq = d.qpos[qi], d.qvel[qi]
        q_log[k] = q
        tau = kp * (plan.q[k] - q) + kd * (plan.dq[k] - dq)
        d.ctrl[:] = np.clip(tau, -effort, effort)
        mujoco.mj_step(m, d)
    return time.perf_counter() - start, q_log


def mass_matrix_pair(setup: Setup, q_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joint-space mass matrices (8, 8) at ``q_all`` = [exo, patient]: Pinocchio's, MuJoCo's.

    Pinocchio's CRBA of the plant's combined model (its armature: the
    drives' rotors on the exoskeleton's joints); MuJoCo's of
    :func:`peer_model`, its rows in the same order.
    """
    peer = Peer(setup)
    order = peer.at(q_all)
    full = np.zeros((peer.model.nv, peer.model.nv))
    mujoco.mj_fullM(peer.model, peer.data, full)
    plant = setup.plant
    mass = pin.crba(plant.model, plant.model.createData(), q_all)
    return np.triu(mass) + np.triu(mass, 1).T, full[np.ix_(order, order)]


def passive_pair(
    setup: Setup, q_all: np.ndarray, v_all: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Generalised cuff and joint-damping forces (8,) at (q_all, v_all): exo_ctrl's, MuJoCo's.

    exo_ctrl's: the cuffs of the plant's parameters, fitted where the frames
    coincide (:class:`~exo_ctrl.plant.cuffs.CuffSet`), less the joints'
    viscous damping b q̇; MuJoCo's ``qfrc_passive`` of :func:`peer_model`.
    """
    peer = Peer(setup)
    order = peer.at(q_all, v_all)
    plant = setup.plant
    cuffs = CuffSet(setup.exo, setup.patient, plant.cuff_params, plant.patient_offset_xz)
    cuffs.compute(q_all, v_all)
    damping = np.concatenate((setup.exo.damping, setup.patient.damping))
    return cuffs.joint_torque - damping * v_all, peer.data.qfrc_passive[order].copy()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated time [s]")
    parser.add_argument("--repeat", type=int, default=3, help="runs; the best is printed")
    args = parser.parse_args(argv)
    if mujoco is None:
        print('mujoco_peer: needs MuJoCo: .venv/bin/pip install -e ".[bench]"', file=sys.stderr)
        return 2
    if not (0.0 < args.seconds <= 600.0) or not 1 <= args.repeat <= 100:
        print("mujoco_peer: --seconds in (0, 600], --repeat in [1, 100]", file=sys.stderr)
        return 2
    config = SimConfig(controller="pd", duration_s=args.seconds, safety=False)
    peer = Peer(build(config))
    wall, q = min((run_peer(peer) for _ in range(args.repeat)), key=lambda run: run[0])
    ours = simulate(config)
    n = min(len(q), len(ours.t))
    err_peer = math.sqrt(np.mean((q[:n] - peer.setup.plan.q[:n]) ** 2))
    err_ours = math.sqrt(np.mean((ours.signals["q"][:n] - peer.setup.plan.q[:n]) ** 2))
    print(
        f"MuJoCo {mujoco.__version__} + Python PD, {args.seconds:g} s at Δt = "
        f"{1e3 * config.dt:g} ms: real-time factor {args.seconds / wall:.1f} "
        f"({1e6 * wall / len(peer.setup.plan.t):.1f} µs a tick; best of {args.repeat})"
    )
    print(
        f"check, the same plan: RMS tracking error MuJoCo {1e3 * err_peer:.2f} mrad, "
        f"exo_ctrl's PD {1e3 * err_ours:.2f} mrad"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
