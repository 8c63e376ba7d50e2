"""The plant: Pinocchio's dynamics against a hand-derived Lagrangian, energy, drives.

The 2-link Lagrangian (one leg, hip fixed to the world, sagittal plane):
θ1 and θ2 are the absolute angles of the thigh and the shank from the
downward vertical, forward positive.  A rotation by q about the joint axis
(0, a_y, 0) turns a link pointing down, (x, z) = (0, -1), to (-a_y sin q, -cos q),
so θ = -a_y q: with the generated URDF's axes (hip -y, knee +y)
θ1 = q_hip and θ2 = q_hip - q_knee.  With link COM distances c1, c2 from the
joints, masses m1, m2, transverse inertias about the COM I1, I2 and the
thigh length l1,

    p1 = c1 (sin θ1, -cos θ1),  p2 = l1 (sin θ1, -cos θ1) + c2 (sin θ2, -cos θ2),
    T  = ½ (m1 c1² + I1 + m2 l1²) θ̇1² + m2 l1 c2 cos(θ1-θ2) θ̇1 θ̇2 + ½ (m2 c2² + I2) θ̇2²,
    V  = -(m1 c1 + m2 l1) g cos θ1 - m2 c2 g cos θ2,

and Lagrange's equations give the generalised forces on (θ1, θ2)

    Q1 = M11 θ̈1 + M12 θ̈2 + m2 l1 c2 sin(θ1-θ2) θ̇2² + (m1 c1 + m2 l1) g sin θ1,
    Q2 = M12 θ̈1 + M22 θ̈2 - m2 l1 c2 sin(θ1-θ2) θ̇1² + m2 c2 g sin θ2,

mapped to the joints by the Jacobian A = ∂θ/∂q: τ = Aᵀ Q.  The paper's §V
equations are the special case I = 0, c = l (point masses at the link ends).
"""

from __future__ import annotations

import dataclasses
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidModel, InvalidParameter, SimulationDiverged
from exo_ctrl.model import BodyModel, default_urdf_path, load_body
from exo_ctrl.plant.cuffs import CuffParams
from exo_ctrl.plant.drive import MotorParams
from exo_ctrl.plant.end_stops import EndStopParams
from exo_ctrl.plant.plant import Plant

G = 9.81


@dataclass(frozen=True)
class Leg:
    """One leg's parameters as read from the URDF XML."""

    l1: float
    c1: float
    c2: float
    m1: float
    m2: float
    i1: float
    i2: float
    s_hip: float  # θ1 = s_hip q_hip
    s_knee: float  # θ2 = θ1 + s_knee q_knee


def _xyz(el: ET.Element | None) -> np.ndarray:
    if el is None:
        return np.zeros(3)
    return np.array([float(x) for x in el.get("xyz", "0 0 0").split()])


def _rpy(el: ET.Element | None) -> np.ndarray:
    if el is None:
        return np.zeros(3)
    return np.array([float(x) for x in el.get("rpy", "0 0 0").split()])


def joints_of(path: Path) -> dict[str, ET.Element]:
    return {j.get("name"): j for j in ET.parse(path).getroot().findall("joint")}


def read_leg(root: ET.Element, side: str) -> Leg:
    """The leg's masses, COM distances, iyy and axis signs, from the XML alone."""
    joints = {j.get("name"): j for j in root.findall("joint")}
    links = {lk.get("name"): lk for lk in root.findall("link")}
    hip, knee = joints[f"{side}_hip"], joints[f"{side}_knee"]
    thigh, shank = hip.find("child").get("link"), knee.find("child").get("link")
    assert knee.find("parent").get("link") == thigh
    # The derivation assumes a planar chain: the knee straight below the hip
    # along the thigh's z axis, no joint rotations, lateral axes.
    knee_xyz = _xyz(knee.find("origin"))
    assert knee_xyz[0] == 0.0 and knee_xyz[1] == 0.0 and knee_xyz[2] < 0.0
    signs = []
    for j in (hip, knee):
        assert np.all(_rpy(j.find("origin")) == 0.0)
        axis = _xyz(j.find("axis"))
        assert axis[0] == 0.0 and axis[2] == 0.0 and abs(axis[1]) == 1.0
        signs.append(-axis[1])
    # Links fixed to the thigh or shank (cuffs, foot) must be massless.
    for j in joints.values():
        if j.get("type") == "fixed" and j.find("parent").get("link") in (thigh, shank):
            assert links[j.find("child").get("link")].find("inertial") is None
    params = []
    for name in (thigh, shank):
        inertial = links[name].find("inertial")
        com = _xyz(inertial.find("origin"))
        assert com[0] == 0.0 and com[1] == 0.0 and com[2] < 0.0
        assert np.all(_rpy(inertial.find("origin")) == 0.0)
        mass = float(inertial.find("mass").get("value"))
        iyy = float(inertial.find("inertia").get("iyy"))
        params.append((-com[2], mass, iyy))
    (c1, m1, i1), (c2, m2, i2) = params
    return Leg(-knee_xyz[2], c1, c2, m1, m2, i1, i2, signs[0], signs[1])


def lagrangian_torque(leg: Leg, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    """Joint torques (hip, knee) of the module docstring's Lagrangian [N·m]."""
    a = np.array([[leg.s_hip, 0.0], [leg.s_hip, leg.s_knee]])  # θ = A q
    th, dth, ddth = a @ q, a @ dq, a @ ddq
    m11 = leg.m1 * leg.c1**2 + leg.i1 + leg.m2 * leg.l1**2
    m12 = leg.m2 * leg.l1 * leg.c2 * math.cos(th[0] - th[1])
    m22 = leg.m2 * leg.c2**2 + leg.i2
    h = leg.m2 * leg.l1 * leg.c2 * math.sin(th[0] - th[1])
    q1 = (
        m11 * ddth[0]
        + m12 * ddth[1]
        + h * dth[1] ** 2
        + (leg.m1 * leg.c1 + leg.m2 * leg.l1) * G * math.sin(th[0])
    )
    q2 = m12 * ddth[0] + m22 * ddth[1] - h * dth[0] ** 2 + leg.m2 * leg.c2 * G * math.sin(th[1])
    return a.T @ np.array([q1, q2])


def paper_torque(
    m1: float, m2: float, l1: float, l2: float, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray
) -> np.ndarray:
    """The paper's §V point-mass leg (no cuffs) solved for M1, M2, mapped to (q_hip, q_knee)."""
    a = np.array([[1.0, 0.0], [1.0, -1.0]])  # φ1 = q_hip, φ2 = q_hip - q_knee
    (p1, p2), (dp1, dp2), (ddp1, ddp2) = a @ q, a @ dq, a @ ddq
    big_m1 = (
        ddp1 * l1**2 * (m1 + m2)
        + ddp2 * m2 * l1 * l2 * math.cos(p1 - p2)
        + dp2**2 * m2 * l1 * l2 * math.sin(p1 - p2)
        + (m1 + m2) * G * l1 * math.sin(p1)
    )
    big_m2 = (
        ddp2 * l2**2 * m2
        + ddp1 * m2 * l1 * l2 * math.cos(p1 - p2)
        - dp1**2 * m2 * l1 * l2 * math.sin(p1 - p2)
        + m2 * G * l2 * math.sin(p2)
    )
    return a.T @ np.array([big_m1, big_m2])


def random_states(seed: int, n: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    return [
        (rng.uniform(-2.0, 2.0, 4), rng.uniform(-6.0, 6.0, 4), rng.uniform(-40.0, 40.0, 4))
        for _ in range(n)
    ]


@pytest.fixture(params=["exo", "patient", "short_exo"])
def urdf_path(request, short_exo_path: Path) -> Path:
    """The exoskeleton, the patient and an exoskeleton with 0.45 m / 0.40 m links."""
    if request.param == "short_exo":
        return short_exo_path
    return default_urdf_path(request.param)


def test_rnea_equals_the_two_link_lagrangian(urdf_path: Path) -> None:
    root = ET.parse(urdf_path).getroot()
    legs = [read_leg(root, side) for side in ("left", "right")]
    # The generated URDFs: flexion positive on both joints.
    assert all(leg.s_hip == 1.0 and leg.s_knee == -1.0 for leg in legs)
    body = load_body(urdf_path)
    model, data = body.model, body.model.createData()
    np.testing.assert_array_equal(model.gravity.linear, [0.0, 0.0, -G])
    for q, dq, ddq in random_states(11, 20):
        tau = pin.rnea(model, data, body.to_model_q(q), body.to_model_q(dq), body.to_model_q(ddq))
        tau = tau[body.q_index]
        for s, leg in enumerate(legs):
            j = slice(2 * s, 2 * s + 2)
            expected = lagrangian_torque(leg, q[j], dq[j], ddq[j])
            np.testing.assert_allclose(tau[j], expected, rtol=0.0, atol=1e-9)


def test_other_lengths_really_change_the_dynamics(exo_path: Path, short_exo_path: Path) -> None:
    long_leg = read_leg(ET.parse(exo_path).getroot(), "left")
    short_leg = read_leg(ET.parse(short_exo_path).getroot(), "left")
    assert long_leg.l1 == pytest.approx(0.52) and short_leg.l1 == pytest.approx(0.45)
    q, dq, ddq = np.array([0.5, 1.0]), np.array([1.0, -2.0]), np.array([3.0, 4.0])
    diff = lagrangian_torque(long_leg, q, dq, ddq) - lagrangian_torque(short_leg, q, dq, ddq)
    assert np.min(np.abs(diff)) > 0.5


def test_lagrangian_matches_the_papers_point_mass_equations() -> None:
    # The derivation above with I = 0 and c = l is the paper's §V leg.
    leg = Leg(0.52, 0.52, 0.48, 3.5, 4.5, 0.0, 0.0, 1.0, -1.0)
    for q, dq, ddq in random_states(12, 10):
        expected = paper_torque(3.5, 4.5, 0.52, 0.48, q[:2], dq[:2], ddq[:2])
        np.testing.assert_allclose(
            lagrangian_torque(leg, q[:2], dq[:2], ddq[:2]), expected, atol=1e-9
        )


def test_rnea_with_point_masses_is_the_papers_leg(exo_path: Path) -> None:
    """Pinocchio on the exoskeleton URDF edited to point masses at the link ends."""
    root = ET.parse(exo_path).getroot()
    lengths = {}
    for side in ("left", "right"):
        leg = read_leg(root, side)
        lengths[f"{side}_thigh"] = leg.l1
    joints = {j.get("name"): j for j in root.findall("joint")}
    for side in ("left", "right"):
        foot = _xyz(joints[f"{side}_foot_joint"].find("origin"))
        lengths[f"{side}_shank"] = -foot[2]
    for link in root.findall("link"):
        if link.get("name") in lengths:
            inertial = link.find("inertial")
            inertial.find("origin").set("xyz", f"0 0 {-float(lengths[link.get('name')])!r}")
            for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                inertial.find("inertia").set(k, "0")
    model = pin.buildModelFromXML(ET.tostring(root, encoding="unicode"))
    model.gravity.linear = np.array([0.0, 0.0, -G])
    data = model.createData()
    # (Pinocchio's parser reports a bad <inertial> on stderr and goes on massless.)
    masses = [model.inertias[model.getJointId(n)].mass for n in ("left_hip", "left_knee")]
    assert masses == [3.5, 4.5]
    ids = [model.joints[model.getJointId(n)].idx_q for n in ("left_hip", "left_knee")]
    for q, dq, ddq in random_states(13, 10):
        full = [np.zeros(model.nq) for _ in range(3)]
        for arr, src in zip(full, (q, dq, ddq), strict=True):
            arr[ids] = src[:2]
        tau = pin.rnea(model, data, *full)[ids]
        expected = paper_torque(
            3.5, 4.5, lengths["left_thigh"], lengths["left_shank"], q[:2], dq[:2], ddq[:2]
        )
        np.testing.assert_allclose(tau, expected, rtol=0.0, atol=1e-9)


# --------------------------------------------------------------------------- energy


@pytest.fixture(scope="module")
def patient() -> BodyModel:
    return load_body(default_urdf_path("patient"), name="patient")


def passive_plant(exo: BodyModel, patient: BodyModel, dt: float = 1e-3) -> Plant:
    return Plant(
        exo,
        patient,
        dt=dt,
        motors=None,
        cuffs=CuffParams.isotropic(damping_N_s_per_m=0.0),
        joint_losses=False,
        # The hard stops are a non-smooth contact (test_end_stops.py): off here.
        end_stops=EndStopParams(enabled=False),
    )


def rest_energy(plant: Plant) -> float:
    """Energy of the hanging rest posture (q = 0, at rest, straps fitted at q = 0) [J].

    The default bodies' cuff frames coincide at equal joint angles, so fitting
    at any equal posture gives slack straps at q = 0 too.
    """
    plant.reset(np.zeros(4), np.zeros(4))
    return plant.mechanical_energy()


def test_mechanical_energy_is_kinetic_plus_potential_plus_spring(exo, patient) -> None:
    plant = passive_plant(exo, patient)
    e_rest = rest_energy(plant)
    # Hanging straight down at rest: the potential energy of the COMs below the hips.
    pot = 0.0
    for path in (default_urdf_path("exo"), default_urdf_path("patient")):
        root = ET.parse(path).getroot()
        for side in ("left", "right"):
            leg = read_leg(root, side)
            pot -= G * (leg.m1 * leg.c1 + leg.m2 * (leg.l1 + leg.c2))
    # Pinocchio also counts the fixed pelvis (at hip height, z = 0 here) — zero.
    assert e_rest == pytest.approx(pot, rel=1e-12)
    # Moving and stretched: ½ q̇ᵀ M q̇ + V + ½ K |Δp|² by hand for one joint.
    # Straight legs swinging about the hip (exo and patient alike): the
    # kinetic energy ½ I_hip w² of each, I_hip by the parallel-axis theorem.
    w = 1.3
    plant.reset(np.zeros(4), np.array([w, 0.0, 0.0, 0.0]))
    kinetic = 0.0
    for path in (default_urdf_path("exo"), default_urdf_path("patient")):
        leg = read_leg(ET.parse(path).getroot(), "left")
        i_hip = leg.m1 * leg.c1**2 + leg.i1 + leg.m2 * (leg.l1 + leg.c2) ** 2 + leg.i2
        kinetic += 0.5 * i_hip * w**2
    assert plant.mechanical_energy() - e_rest == pytest.approx(kinetic, rel=1e-12)
    # A stretched strap: the patient's right knee bent alone adds ½ K |Δp|² of
    # the right shank cuff, Δp from the chord of the bend.
    bend = 0.2
    plant.reset(
        np.zeros(4), np.zeros(4), q_patient=np.array([0.0, 0.0, 0.0, bend]), fit_cuffs=False
    )
    leg = read_leg(ET.parse(default_urdf_path("patient")).getroot(), "right")
    cuff = float(
        _xyz(joints_of(default_urdf_path("patient"))["right_shank_cuff_joint"].find("origin"))[2]
    )
    chord = 2.0 * abs(cuff) * math.sin(bend / 2.0)
    knee_rise = leg.m2 * G * leg.c2 * (1.0 - math.cos(bend))
    spring = 0.5 * CuffParams().stiffness_N_per_m * chord**2
    assert plant.mechanical_energy() - e_rest == pytest.approx(knee_rise + spring, rel=1e-12)


def test_passive_energy_is_conserved(exo, patient) -> None:
    """Undamped, passive, frictionless: energy drift < 0.1 % over 10 s at 1 ms.

    The drift is relative to the energy above the hanging rest posture,
    E0 − E_rest (the absolute energy has an arbitrary zero).
    """
    plant = passive_plant(exo, patient, dt=1e-3)
    e_rest = rest_energy(plant)
    q_bent = np.array([0.8, 1.2, -0.3, 0.6])
    plant.reset(q_bent, np.zeros(4))  # patient in the same posture, straps fitted
    e0 = plant.mechanical_energy()
    assert e0 - e_rest > 20.0
    steps = round(10.0 / plant.dt)
    energies = np.empty(steps // 10)
    stretch = 0.0
    zero = np.zeros(4)
    for k in range(steps):
        plant.step(zero)
        if k % 10 == 9:
            energies[k // 10] = plant.mechanical_energy()
            stretch = max(stretch, float(np.max(np.abs(plant.q[:4] - plant.q[4:]))))
    drift = float(np.max(np.abs(energies - e0)) / (e0 - e_rest))
    print(f"\npassive energy drift over 10 s at 1 ms: {100 * drift:.4f} % of E0 - E_rest")
    assert plant.t == pytest.approx(10.0)
    # The bodies really swung and the straps really worked.
    assert stretch > 1e-3
    assert drift < 1e-3


def test_damping_and_joint_losses_dissipate(exo, patient) -> None:
    plant = Plant(exo, patient, dt=1e-3, motors=None, cuffs=CuffParams(), joint_losses=True)
    e_rest = rest_energy(plant)
    plant.reset(np.array([0.8, 1.2, -0.3, 0.6]), np.zeros(4))
    e0 = plant.mechanical_energy()
    for _ in range(3000):
        plant.step(np.zeros(4))
    assert plant.mechanical_energy() - e_rest < 0.5 * (e0 - e_rest)


# --------------------------------------------------------------------------- drives


def clamped_run(plant: Plant, voltage: np.ndarray, q0: np.ndarray, w: np.ndarray, n: int):
    """Step with the exoskeleton's joints clamped to q0 + w t (state reset every step)."""
    plant.reset(q0, w, current_A=0.0)
    for k in range(1, n + 1):
        plant.step(voltage)
        plant.q[:4] = q0 + w * k * plant.dt
        plant.v[:4] = w
        plant.q[4:] = plant.q[:4]
        plant.v[4:] = plant.v[:4]


def test_drive_in_the_plant_settles_to_the_stall_current(exo, patient) -> None:
    params = MotorParams()
    plant = Plant(exo, patient, dt=1e-3, motors=params)
    voltage = np.array([0.5, -0.3, 0.2, 0.8])
    clamped_run(plant, voltage, np.array([0.3, 0.5, -0.1, 0.2]), np.zeros(4), 50)
    # Joint fixed: L dI/dt + R I = U, so I → U / R (50 ms ≫ L/R ≈ 0.7 ms).
    current = voltage / params.resistance_ohm
    assert np.all(np.abs(current) < params.current_limit_A)
    np.testing.assert_allclose(plant.motors.current_A, current, rtol=1e-9)
    # The drive's torque at the joint is i_G k_m I.  (The plant's drive_torque
    # also carries the implicit back-EMF correction of the step's computed
    # acceleration, which the clamp here does not make zero.)
    torque = params.gear_ratio * params.torque_constant_Nm_per_A * current
    np.testing.assert_allclose(plant.motors.torque_Nm, torque, rtol=1e-9)


def test_drive_in_the_plant_sees_the_exoskeleton_joint_speed(exo, patient) -> None:
    params = MotorParams()
    plant = Plant(exo, patient, dt=1e-3, motors=params)
    voltage = np.array([1.5, -2.2, 5.7, 0.2])  # currents -8, 24, -12, 2 A: within every limit
    w = np.array([0.5, -1.0, 1.5, 0.0])
    clamped_run(plant, voltage, np.array([0.3, 0.5, -0.1, 0.2]), w, 50)
    # At a held speed the back-EMF i_G ω / k_E opposes the voltage.
    back_emf = params.gear_ratio * w / params.speed_constant_rad_per_Vs
    current = (voltage - back_emf) / params.resistance_ohm
    assert np.all(np.abs(current) < params.current_limit_A)
    assert np.all(np.abs(current - voltage / params.resistance_ohm)[:3] > 1.0)
    np.testing.assert_allclose(plant.motors.current_A, current, rtol=1e-9)


def test_drive_torque_moves_the_legs(exo, patient) -> None:
    """Equal and opposite voltages: the legs accelerate in opposite directions."""
    plant = Plant(exo, patient, dt=1e-3, motors=MotorParams())
    plant.reset(np.zeros(4), np.zeros(4))
    voltage = np.array([1.0, 0.0, -1.0, 0.0])
    for _ in range(20):
        plant.step(voltage)
    assert plant.q[0] > 1e-3 and plant.q[2] < -1e-3
    assert plant.q[0] == pytest.approx(-plant.q[2], rel=1e-9)
    # The patient's thigh is carried along by the cuffs.
    assert plant.q[4] > 0.1 * plant.q[0]


# --------------------------------------------------------------------------- one ABA call


@pytest.mark.parametrize("which", ["patient", "human"])
def test_combined_aba_is_the_two_bodies_apart(request, exo, patient, which) -> None:
    """The plant's one ABA call on both bodies = one call per body's own model.

    Separate models built from ``exo.model`` and ``patient.model`` with the
    same armatures: the plant's own (exo i_G² J_rotor + h b (+ h D_m), patient
    h b), then random ones, on random states and torques; and the
    accelerations of a real step from its mid-step rows.
    """
    body = patient if which == "patient" else request.getfixturevalue("human")
    params = MotorParams()
    plant = Plant(exo, body, dt=1e-3, motors=params)
    h = plant.dt
    expected_arm = np.concatenate(
        (params.reflected_inertia_kgm2 + h * exo.damping, h * body.damping)
    )
    np.testing.assert_allclose(plant.model.armature, expected_arm, rtol=1e-15)
    model = pin.Model(plant.model)
    data = model.createData()
    me, mp = pin.Model(exo.model), pin.Model(body.model)
    de, dp = me.createData(), mp.createData()

    def apart(arm, q, v, tau):
        me.armature, mp.armature = arm[:4], arm[4:]
        return np.concatenate(
            (pin.aba(me, de, q[:4], v[:4], tau[:4]), pin.aba(mp, dp, q[4:], v[4:], tau[4:]))
        )

    rng = np.random.default_rng(21)
    for k in range(20):
        arm = expected_arm if k < 5 else rng.uniform(0.0, 0.5, 8)
        model.armature = arm
        q, v, tau = rng.uniform(-2, 2, 8), rng.uniform(-6, 6, 8), rng.uniform(-40, 40, 8)
        both = pin.aba(model, data, q, v, tau)
        assert np.max(np.abs(both)) > 1.0
        np.testing.assert_allclose(both, apart(arm, q, v, tau), rtol=0.0, atol=1e-12)
    # In the plant's step: its accelerations are those of its mid-step state
    # and armature, h D_m included (zero while a drive's current is at its
    # limit: the large voltages).
    plant.reset(np.array([0.3, 0.5, -0.1, 0.2]), np.array([1.0, -2.0, 0.5, 0.0]))
    plant.q[4:] += 0.05  # stretch the straps
    saturated = 0
    for k in range(6):
        voltage = np.array([3.0, -2.0, 1.0, 4.0]) * (10.0 if k % 3 == 2 else 1.0)
        plant.step(voltage, np.array([1.0, 2.0, -3.0, 0.5]))
        saturated += int(np.any(plant.motors.saturated))
        arm = expected_arm.copy()
        arm[:4] += h * plant.motors.damping_Nm_s_per_rad
        expected = apart(arm, plant._q_mid, plant._v_mid, plant._tau)
        np.testing.assert_allclose(plant.acceleration, expected, rtol=0.0, atol=1e-12)
    assert 0 < saturated < 6


def test_bodies_under_different_gravity_are_refused(exo, patient) -> None:
    model = pin.Model(patient.model)
    model.gravity = pin.Motion(np.array([0.0, 0.0, -1.62, 0.0, 0.0, 0.0]))
    on_the_moon = dataclasses.replace(patient, model=model)
    with pytest.raises(InvalidModel, match=r"gravity .* differs from the exoskeleton's"):
        Plant(exo, on_the_moon)


# --------------------------------------------------------------------------- errors


def test_bad_step_is_refused(exo, patient) -> None:
    for dt in (0.0, -1e-3, float("nan")):
        with pytest.raises(InvalidParameter) as info:
            Plant(exo, patient, dt=dt)
        assert str(info.value) == f"dt must be > 0 s; got {dt!r}"


QUANTITY = r"(exoskeleton|patient) (left|right)_(hip|knee) speed \[rad/s\]"


@pytest.mark.parametrize(
    ("index", "value", "name"),
    [
        (0, 150.0, "exoskeleton left_hip speed [rad/s]"),
        (7, -101.0, "patient right_knee speed [rad/s]"),
        (5, float("nan"), None),  # NaN spreads through the leg and the cuffs
    ],
)
def test_runaway_speed_raises_simulation_diverged(exo, patient, index, value, name) -> None:
    plant = passive_plant(exo, patient)
    plant.reset(np.zeros(4), np.zeros(4))
    plant.v[index] = value
    with pytest.raises(SimulationDiverged) as info:
        plant.step(np.zeros(4))
    err = info.value
    match = re.fullmatch(
        rf"simulation diverged at t = 0\.0010 s: ({QUANTITY}) = (\S+) \(allowed magnitude 100\)",
        str(err),
    )
    assert match, str(err)
    assert err.time == pytest.approx(1e-3) and err.limit == 100.0
    assert match.group(1) == err.quantity
    if name is None:
        assert match.group(5) == "nan" and math.isnan(err.value)
    else:
        assert err.quantity == name
        assert abs(err.value) > 100.0 and np.sign(err.value) == np.sign(value)
        assert float(match.group(5)) == pytest.approx(err.value, rel=1e-3)


def test_inputs_of_the_wrong_length_are_refused_by_name(exo, patient) -> None:
    # The step runs in a compiled kernel: a short array must not be read past its end.
    plant = Plant(exo, patient, dt=1e-3, motors=MotorParams())
    plant.reset(np.zeros(4), np.zeros(4))
    with pytest.raises(
        InvalidParameter,
        match=re.escape("voltage_V must be an array of shape (4,); got array("),
    ):
        plant.step(np.zeros(3))
    with pytest.raises(
        InvalidParameter, match=re.escape("patient_torque_Nm must be an array of shape (4,)")
    ):
        plant.step(np.zeros(4), np.zeros(5))
    q_before = plant.q.copy()
    plant.step(1.0, [0.0, 0.0, 0.0, 0.0])  # a scalar and a list broadcast as numpy would
    assert not np.array_equal(plant.q, q_before)
