"""Tests of exo_ctrl.model.urdfgen: generated URDFs checked through Pinocchio against hand maths."""

from __future__ import annotations

import io
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy

from exo_ctrl.model import (
    DEFAULT_URDF_NAMES,
    BodyParams,
    build_urdf,
    draw_cohort,
    fitted_exo,
    nominal_patient,
    segment_inertia,
    urdf_xml,
    write_urdf,
)

REPO = Path(__file__).resolve().parents[2]
G = 9.81
JOINTS = ["left_hip", "left_knee", "right_hip", "right_knee"]

EXO = BodyParams.exo_default()
PATIENT = BodyParams.patient_default()
SHORT = BodyParams.exo_default(
    thigh_length=0.45, shank_length=0.40, thigh_cuff=0.3, shank_cuff=0.35
)
SHORT_PATIENT = BodyParams.patient_default(thigh_length=0.45, shank_length=0.40, shank_cuff=0.35)
ALL = [EXO, PATIENT, SHORT, SHORT_PATIENT]


def expected_segment(params: BodyParams, seg: str) -> tuple[float, float, float]:
    """(COM distance, transverse moment about the COM, axial moment), written out by hand."""
    m = getattr(params, f"{seg}_mass")
    length = getattr(params, f"{seg}_length")
    if params.kind == "exo":  # uniform solid cylinder, r = 0.03 m
        r = 0.03
        return 0.5 * length, m * (3 * r**2 + length**2) / 12, m * r**2 / 2
    # Winter (2009) Table 4.1; axial radius 0.06 m thigh, 0.04 m shank
    com, rho, r = {"thigh": (0.433, 0.323, 0.06), "shank": (0.606, 0.416, 0.04)}[seg]
    return com * length, m * (rho * length) ** 2, m * r**2 / 2


def model_of(params: BodyParams) -> pin.Model:
    return pin.buildModelFromXML(urdf_xml(params))


def frame_pos(model: pin.Model, q: np.ndarray, frame: str) -> np.ndarray:
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId(frame)].translation.copy()


def q_of(model: pin.Model, **angles: float) -> np.ndarray:
    q = pin.neutral(model)
    for name, value in angles.items():
        q[model.joints[model.getJointId(name)].idx_q] = value
    return q


# --- committed files and determinism ------------------------------------------------------


@pytest.mark.parametrize("params", [EXO, PATIENT], ids=["exo", "patient"])
def test_committed_urdf_matches_generator(params: BodyParams) -> None:
    committed = (REPO / "urdf" / DEFAULT_URDF_NAMES[params.kind]).read_bytes()
    assert committed == urdf_xml(params).encode("utf-8")


def test_xml_is_deterministic_and_parameter_dependent() -> None:
    assert urdf_xml(EXO) == urdf_xml(BodyParams.exo_default())
    assert urdf_xml(EXO) != urdf_xml(BodyParams.exo_default(joint_damping=0.6))
    assert urdf_xml(EXO) != urdf_xml(PATIENT)


def _yourdfpy_text(params: BodyParams) -> str:
    """yourdfpy's own serialisation of :func:`build_urdf`'s model (lxml, pretty-printed)."""
    buffer = io.BytesIO()
    build_urdf(params, scene=False).write_xml().write(
        buffer, xml_declaration=True, pretty_print=True, encoding="UTF-8"
    )
    return buffer.getvalue().decode("utf-8")


# the defaults, a short pair, a drawn cohort (random lengths, masses, cuffs) and their
# fitted exoskeletons, and a nominal patient with an odd stature and mass
COHORT = draw_cohort(6, seed=3, height_m=1.62, mass_kg=57.3, sex="female")
ODD = nominal_patient(0.431, 0.397, 1.58, 61.7)
VARIED = [*ALL, *COHORT, *(fitted_exo(p) for p in COHORT), ODD]


@pytest.mark.parametrize("params", VARIED)
def test_text_is_yourdfpys_serialisation_of_the_built_model(params: BodyParams) -> None:
    # urdf_xml writes the description with the standard library; build_urdf makes
    # yourdfpy's objects of it, which lxml writes: the two texts are one, byte for byte
    assert urdf_xml(params) == _yourdfpy_text(params)


def test_yourdfpy_round_trip() -> None:
    urdf = yourdfpy.URDF.load(io.BytesIO(urdf_xml(PATIENT).encode()), load_meshes=False)
    assert urdf.validate()
    assert urdf.robot.name == "patient"
    assert build_urdf(EXO).robot.name == "exoskeleton"
    assert sorted(urdf.actuated_joint_names) == JOINTS
    built = build_urdf(PATIENT)
    assert urdf.robot.links == built.robot.links
    for parsed, made in zip(urdf.robot.joints, built.robot.joints, strict=True):
        assert (parsed.name, parsed.type, parsed.parent, parsed.child, parsed.limit) == (
            made.name,
            made.type,
            made.parent,
            made.child,
            made.limit,
        )
        np.testing.assert_array_equal(parsed.origin, made.origin)
        if made.type == "revolute":
            np.testing.assert_array_equal(parsed.axis, made.axis)
            # yourdfpy 0.0.60 parses <dynamics> attributes as strings, not floats
            assert float(parsed.dynamics.damping) == made.dynamics.damping
            assert float(parsed.dynamics.friction) == made.dynamics.friction


# --- structure, kinematics and limits through Pinocchio ------------------------------------


@pytest.mark.parametrize("params", ALL)
def test_pinocchio_joints_mass_and_limits(params: BodyParams) -> None:
    model = model_of(params)
    assert model.nq == model.nv == 4
    assert list(model.names)[1:] == JOINTS
    for j in range(1, model.njoints):
        assert model.joints[j].nq == model.joints[j].nv == 1
        # axis (0, -1, 0) gives RevoluteUnaligned, (0, 1, 0) gives RY
        assert model.joints[j].shortname() in {"JointModelRevoluteUnaligned", "JointModelRY"}
    legs = 2 * (params.thigh_mass + params.shank_mass)
    # the pelvis is welded to the universe: its inertia lands in inertias[0], which
    # pin.computeTotalMass leaves out
    assert sum(inertia.mass for inertia in model.inertias) == pytest.approx(
        legs + params.pelvis_mass, rel=1e-12
    )
    assert model.inertias[0].mass == pytest.approx(params.pelvis_mass, rel=1e-12)
    assert pin.computeTotalMass(model) == pytest.approx(legs, rel=1e-12)
    lower = [params.hip_range[0], params.knee_range[0]] * 2
    upper = [params.hip_range[1], params.knee_range[1]] * 2
    np.testing.assert_array_equal(model.lowerPositionLimit, lower)
    np.testing.assert_array_equal(model.upperPositionLimit, upper)
    np.testing.assert_array_equal(model.effortLimit, [params.effort_limit] * 4)
    np.testing.assert_array_equal(model.velocityLimit, [params.velocity_limit] * 4)
    np.testing.assert_array_equal(model.damping, [params.joint_damping] * 4)
    np.testing.assert_array_equal(model.friction, [params.joint_friction] * 4)


@pytest.mark.parametrize("params", ALL)
def test_geometry_at_zero(params: BodyParams) -> None:
    model = model_of(params)
    q0 = pin.neutral(model)
    lt, ls = params.thigh_length, params.shank_length
    for side, y in (("left", params.hip_width / 2), ("right", -params.hip_width / 2)):
        hip = model.jointPlacements[model.getJointId(f"{side}_hip")]
        np.testing.assert_allclose(hip.translation, [0, y, 0], atol=1e-15)
        np.testing.assert_allclose(hip.rotation, np.eye(3), atol=1e-15)
        knee = model.jointPlacements[model.getJointId(f"{side}_knee")]
        np.testing.assert_allclose(knee.translation, [0, 0, -lt], atol=1e-15)
        expected = {
            f"{side}_thigh_cuff": [0, y, -params.thigh_cuff],
            f"{side}_shank_cuff": [0, y, -lt - params.shank_cuff],
            f"{side}_foot": [0, y, -lt - ls],
        }
        for frame, pos in expected.items():
            assert model.existFrame(frame)
            np.testing.assert_allclose(frame_pos(model, q0, frame), pos, atol=1e-12)
        # the massless links hang on the joint of the segment they are fixed to
        fid = model.getFrameId(f"{side}_thigh_cuff")
        assert model.frames[fid].parentJoint == model.getJointId(f"{side}_hip")
        fid = model.getFrameId(f"{side}_foot")
        assert model.frames[fid].parentJoint == model.getJointId(f"{side}_knee")


def test_cuff_and_foot_frame_names_shared_by_exo_and_patient() -> None:
    def named(model: pin.Model) -> set[str]:
        return {f.name for f in model.frames if f.type == pin.FrameType.BODY}

    assert named(model_of(EXO)) == named(model_of(PATIENT))
    for side in ("left", "right"):
        for suffix in ("thigh_cuff", "shank_cuff", "foot"):
            assert f"{side}_{suffix}" in named(model_of(EXO))


@pytest.mark.parametrize("params", ALL)
def test_flexion_sign_convention(params: BodyParams) -> None:
    model = model_of(params)
    foot0 = frame_pos(model, pin.neutral(model), "left_foot")
    eps = 1e-3
    hip = frame_pos(model, q_of(model, left_hip=eps), "left_foot") - foot0
    knee = frame_pos(model, q_of(model, left_knee=eps), "left_foot") - foot0
    assert hip[0] == pytest.approx(eps * (params.thigh_length + params.shank_length), rel=1e-5)
    assert knee[0] == pytest.approx(-eps * params.shank_length, rel=1e-5)
    # the right leg is the mirror image: same x, the other leg's y
    right = frame_pos(model, q_of(model, right_hip=eps), "right_foot")
    assert right[0] == pytest.approx(hip[0] + foot0[0], rel=1e-12)


@pytest.mark.parametrize("params", ALL)
def test_forward_kinematics_closed_form(params: BodyParams) -> None:
    """Foot = hip + L1 (sin a, -cos a) + L2 (sin(a - b), -cos(a - b)) in the x-z plane."""
    model = model_of(params)
    lt, ls = params.thigh_length, params.shank_length
    for a, b in [(0.4, 0.9), (-0.3, 0.1), (1.2, 2.0)]:
        foot = frame_pos(model, q_of(model, left_hip=a, left_knee=b), "left_foot")
        x = lt * math.sin(a) + ls * math.sin(a - b)
        z = -lt * math.cos(a) - ls * math.cos(a - b)
        np.testing.assert_allclose(foot, [x, params.hip_width / 2, z], atol=1e-12)


# --- inertia -----------------------------------------------------------------------------


@pytest.mark.parametrize("params", ALL)
def test_link_inertias_match_documented_formulas(params: BodyParams) -> None:
    model = model_of(params)
    for side in ("left", "right"):
        for seg, joint in (("thigh", "hip"), ("shank", "knee")):
            inertia = model.inertias[model.getJointId(f"{side}_{joint}")]
            com, transverse, axial = expected_segment(params, seg)
            assert inertia.mass == pytest.approx(getattr(params, f"{seg}_mass"), rel=1e-12)
            np.testing.assert_allclose(inertia.lever, [0, 0, -com], atol=1e-12)
            np.testing.assert_allclose(
                inertia.inertia, np.diag([transverse, transverse, axial]), rtol=1e-12, atol=1e-15
            )
            got = segment_inertia(params, seg)
            assert (got.com, got.transverse, got.axial) == pytest.approx((com, transverse, axial))


@pytest.mark.parametrize("params", ALL)
def test_inertias_physically_valid(params: BodyParams) -> None:
    model = model_of(params)
    for inertia in model.inertias:  # includes the pelvis, merged into the universe
        assert inertia.mass > 0
        assert np.linalg.eigvalsh(inertia.toPseudoInertia().toMatrix()).min() > 0
        i1, i2, i3 = np.linalg.eigvalsh(inertia.inertia)
        assert i1 + i2 > i3 and i2 + i3 > i1 and i1 + i3 > i2


def test_patient_values_winter() -> None:
    """Spot values by hand: thigh I_t = 11.3 (0.323 · 0.52)², COM 0.433 · 0.52."""
    inertia = model_of(PATIENT).inertias[1]
    assert inertia.lever[2] == pytest.approx(-0.22516, abs=1e-12)
    assert inertia.inertia[0, 0] == pytest.approx(0.31879, rel=1e-4)
    assert inertia.inertia[2, 2] == pytest.approx(0.02034, rel=1e-12)


@pytest.mark.parametrize("params", ALL)
def test_dynamics_match_two_link_lagrangian(params: BodyParams) -> None:
    """Gravity torque and mass matrix of one leg against a hand-derived 2-link model.

    With a = q_hip, b = q_knee, shank angle φ = a - b from the downward vertical:
    V = -g [m1 c1 cos a + m2 (L1 cos a + c2 cos φ)] and, in (a, φ),
    M = [[I1 + m1 c1² + m2 L1², m2 L1 c2 cos b], [·, I2 + m2 c2²]];
    M_q = Tᵀ M T with T = ∂(a, φ)/∂(a, b).
    """
    model = model_of(params)
    data = model.createData()
    m1, m2, l1 = params.thigh_mass, params.shank_mass, params.thigh_length
    c1, i1, _ = expected_segment(params, "thigh")
    c2, i2, _ = expected_segment(params, "shank")
    for a, b in [(0.3, 0.7), (-0.4, 0.05), (1.5, 2.0)]:
        q = q_of(model, left_hip=a, left_knee=b, right_hip=0.2, right_knee=0.1)
        phi = a - b
        tau_g = pin.computeGeneralizedGravity(model, data, q)
        expected_g = [
            G * (m1 * c1 * math.sin(a) + m2 * (l1 * math.sin(a) + c2 * math.sin(phi))),
            -G * m2 * c2 * math.sin(phi),
        ]
        np.testing.assert_allclose(tau_g[:2], expected_g, rtol=1e-9, atol=1e-12)
        mass = pin.crba(model, data, q)
        m_phi = np.array(
            [
                [i1 + m1 * c1**2 + m2 * l1**2, m2 * l1 * c2 * math.cos(b)],
                [m2 * l1 * c2 * math.cos(b), i2 + m2 * c2**2],
            ]
        )
        t = np.array([[1.0, 0.0], [1.0, -1.0]])
        np.testing.assert_allclose(mass[:2, :2], t.T @ m_phi @ t, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(mass[:2, 2:], 0.0, atol=1e-12)


def test_other_lengths_change_the_model() -> None:
    model = model_of(SHORT)
    knee = model.jointPlacements[model.getJointId("left_knee")]
    np.testing.assert_allclose(knee.translation, [0, 0, -0.45], atol=1e-15)
    np.testing.assert_allclose(
        frame_pos(model, pin.neutral(model), "left_foot"), [0, 0.1, -0.85], atol=1e-12
    )
    shank = model.inertias[model.getJointId("left_knee")]
    assert shank.lever[2] == pytest.approx(-0.20, abs=1e-12)
    assert shank.inertia[0, 0] == pytest.approx(4.5 * (3 * 0.03**2 + 0.40**2) / 12, rel=1e-12)


# --- writing ------------------------------------------------------------------------------


def test_write_urdf_atomic(tmp_path: Path) -> None:
    path = write_urdf(PATIENT, tmp_path / "p.urdf")
    assert path.read_bytes() == urdf_xml(PATIENT).encode("utf-8")
    assert write_urdf(EXO, tmp_path) == tmp_path / "exoskeleton.urdf"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exoskeleton.urdf", "p.urdf"]
    assert pin.buildModelFromUrdf(str(path)).nq == 4


def test_write_urdf_failure_keeps_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "exoskeleton.urdf"
    target.write_text("old")

    def fail(src: str, dst: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(OSError, match="disk full"):
        write_urdf(EXO, target)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["exoskeleton.urdf"]


def test_yourdfpy_is_imported_only_to_build_a_model() -> None:
    # a model's text, file and Pinocchio model (what a run needs) do without it
    code = (
        "import sys, tempfile, exo_ctrl.model as m; p = m.BodyParams.patient_default(); "
        "m.urdf_xml(p); m.load_patient(str(m.write_urdf(p, tempfile.mkdtemp()))); "
        "print('yourdfpy' in sys.modules); m.build_urdf(p); print('yourdfpy' in sys.modules)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.split() == ["False", "True"]
