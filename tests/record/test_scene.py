"""Tests of exo_ctrl.record.scene: the 3-D scene against Pinocchio, at the display rate.

3-D points are float32 in rerun, so they are compared to Pinocchio within
1e-6 m; the batched forward kinematics itself (float64) to 1e-12 m.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from rerun.chunk import RrdReader

from exo_ctrl.model import CUFF_NAMES, SIDES, load_body, load_patient
from exo_ctrl.record import FORCE_ARROW_M_PER_N, RerunRecorder
from exo_ctrl.record.format import layout
from exo_ctrl.record.omitted import left_out_signals
from exo_ctrl.record.scene import Skeleton
from exo_ctrl.sim import SimConfig, simulate


def test_3d_points_match_pinocchio(short_run, entity_columns):
    result, path = short_run
    exo = load_body(result.exo_source)
    patient = load_patient(None)
    q, qp = result.signals["q"], result.signals["q_patient"]
    hip_e, hip_p = exo.legs["left"].hip_xz, patient.legs["left"].hip_xz
    shift = np.array([hip_e[0] - hip_p[0], 0.0, hip_e[1] - hip_p[1]])
    for side in SIDES:
        ticks, joints = entity_columns(path, f"world/exo/{side}/joints", "Points3D:positions")
        assert ticks.tolist() == list(range(0, 300, 20))  # every 0.02 s
        for k, pts in zip(ticks, joints, strict=True):
            data = exo.model.createData()
            pin.framesForwardKinematics(exo.model, data, exo.to_model_q(q[k]))
            hip = data.oMi[exo.model.getJointId(f"{side}_hip")].translation
            knee = data.oMi[exo.model.getJointId(f"{side}_knee")].translation
            foot = exo.frame_position(q[k], f"{side}_foot")
            assert np.allclose(pts, [hip, knee, foot], atol=1e-6)
        _, legs = entity_columns(path, f"world/exo/{side}/leg", "LineStrips3D:strips")
        assert np.array_equal(np.asarray(legs[5][0]), np.asarray(joints[5]))
        _, cuffs = entity_columns(path, f"world/exo/{side}/cuffs", "Points3D:positions")
        k = int(ticks[7])
        thigh = exo.frame_position(q[k], f"{side}_thigh_cuff")
        shank = exo.frame_position(q[k], f"{side}_shank_cuff")
        assert np.allclose(cuffs[7], [thigh, shank], atol=1e-6)
        ticks_p, joints_p = entity_columns(
            path, f"world/patient/{side}/joints", "Points3D:positions"
        )
        assert np.array_equal(ticks_p, ticks)
        for k, pts in zip(ticks_p, joints_p, strict=True):
            foot = patient.frame_position(qp[k], f"{side}_foot") + shift
            assert np.allclose(pts[2], foot, atol=1e-6)
    # The patient's left hip sits on the exo's left hip in x and z.
    _, pe = entity_columns(path, "world/exo/left/joints", "Points3D:positions")
    _, pp = entity_columns(path, "world/patient/left/joints", "Points3D:positions")
    assert np.allclose(np.asarray(pe[0][0])[[0, 2]], np.asarray(pp[0][0])[[0, 2]], atol=1e-6)


def test_cuff_arrows_are_scaled_forces_at_the_exo_cuffs(short_run, entity_columns):
    result, path = short_run
    exo = load_body(result.exo_source)
    force, q = result.signals["cuff_force"], result.signals["q"]
    assert np.max(np.abs(force)) > 1.0  # the check below is not vacuous
    for c, cuff in enumerate(CUFF_NAMES):
        ticks, vectors = entity_columns(path, f"world/cuff_force/{cuff}", "Arrows3D:vectors")
        _, origins = entity_columns(path, f"world/cuff_force/{cuff}", "Arrows3D:origins")
        assert ticks.tolist() == list(range(0, 300, 20))
        for k, vec, org in zip(ticks, vectors, origins, strict=True):
            expected = FORCE_ARROW_M_PER_N * np.array([force[k, c, 0], 0.0, force[k, c, 1]])
            assert np.allclose(vec[0], expected, rtol=1e-6, atol=1e-7)
            assert np.allclose(org[0], exo.frame_position(q[k], f"{cuff}_cuff"), atol=1e-6)


def test_belt_and_planned_foot_paths(short_run, short_config, entity_columns):
    result, path = short_run
    gait = short_config.gait
    exo = load_body(result.exo_source)
    hip_z = exo.legs["left"].hip_xz[1]
    for side in SIDES:
        _, strips = entity_columns(path, f"world/plan/foot_path/{side}", "LineStrips3D:strips")
        pts = np.asarray(strips[-1][0])
        bottom = hip_z - gait.hip_height
        assert np.isclose(pts[:, 2].min(), bottom, atol=1e-6)
        stance = pts[np.abs(pts[:, 2] - bottom) < 1e-6]  # the foot on the belt spans s
        assert np.isclose(np.ptp(stance[:, 0]), gait.step_length, atol=1e-2)
        assert np.isclose(pts[:, 2].max(), bottom + gait.lift_height, atol=1e-6)
    _, half = entity_columns(path, "world/belt", "Boxes3D:half_sizes")
    _, centers = entity_columns(path, "world/belt", "Boxes3D:centers")
    top = centers[-1][0][2] + half[-1][0][2]
    assert np.isclose(top, hip_z - gait.hip_height, atol=1e-6)
    # Stripes move backwards at belt speed: 0.02 s moves them by v 0.02 m.
    ticks, stripes = entity_columns(path, "world/belt/stripes", "LineStrips3D:strips")
    x0 = np.array([s[0][0] for s in stripes[0]])
    x1 = np.array([s[0][0] for s in stripes[1]])
    step = result.belt_speed_mps * (ticks[1] - ticks[0]) * short_config.dt
    moved = x0 - x1
    assert np.allclose(moved[np.abs(moved) < 0.5], step, atol=1e-5)


@pytest.mark.parametrize(("rate_hz", "stride"), [(50.0, 20), (125.0, 8), (3000.0, 1)])
def test_scene_at_the_display_rate_series_at_every_tick(tmp_path, rate_hz, stride):
    """The 3-D entities every round(f_ctrl / f_scene) ticks; every time series every tick.

    The run has 300 ticks at 1 kHz in 70-tick chunks, so the scene's ticks
    cross chunk boundaries (0, 20, …, 280 at 50 Hz: 80 and 140 start no
    chunk).
    """
    path = tmp_path / "rate.rrd"
    config = SimConfig(duration_s=0.3, chunk_ticks=70)
    simulate(config, observers=[RerunRecorder(path, scene_rate_hz=rate_hz)])
    ticks: dict[str, list[int]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        if "tick" in batch.schema.names:
            ticks.setdefault(chunk.entity_path, []).extend(batch.column("tick").to_pylist())
    scene = {e: sorted(t) for e, t in ticks.items() if e.startswith("/world/")}
    series = {e: sorted(t) for e, t in ticks.items() if e.startswith("/signals/")}
    # legs, joints, cuffs; cuff arrows; stripes (no foot arrows: the contact is off)
    assert len(scene) == 2 * 2 * 3 + 4 + 1
    for entity, shown in scene.items():
        assert shown == list(range(0, 300, stride)), entity
    # every series but those of the features off in the run, each value once
    assert len(series) == len(layout().without(left_out_signals(config)).series) >= 30
    for entity, logged in series.items():
        assert logged == list(range(300)), entity


@pytest.mark.parametrize("body", ["exo", "patient", "human"])
def test_batched_kinematics_equals_pinocchio(body, exo, patient, human):
    """The many-poses forward kinematics against Pinocchio's, pose by pose."""
    model = {"exo": exo, "patient": patient, "human": human}[body]
    skeleton = Skeleton(model, offset_xz=(0.1, -0.2))
    assert skeleton._chain is not None  # the batched path is the one in use
    q = np.random.default_rng(3).uniform(-1.2, 1.2, (25, 4))
    legs, cuffs = skeleton.points(q)
    ref_legs, ref_cuffs = skeleton._pinocchio(q)
    shift = np.array([0.1, 0.0, -0.2])
    assert np.allclose(legs, ref_legs + shift, rtol=0, atol=1e-12)
    assert np.allclose(cuffs, ref_cuffs + shift, rtol=0, atol=1e-12)
    for i in (0, 24):
        for s, side in enumerate(SIDES):
            foot = model.frame_position(q[i], f"{side}_foot")
            assert np.allclose(legs[i, s, 2] - shift, foot, rtol=0, atol=1e-12)


def test_the_scene_rides_on_the_pelvis(tmp_path, entity_columns):
    """With the pelvis on its guide both bodies' points move with it; the feet meet the belt."""
    from exo_ctrl.plant import ContactParams, PelvisParams

    config = SimConfig(
        duration_s=0.3,
        contact=ContactParams(enabled=True),
        pelvis=PelvisParams(supported=True, bws_fraction=0.5),
        sync=False,
        safety=False,
    )
    path = tmp_path / "bws.rrd"
    result = simulate(config, observers=[RerunRecorder(path)])
    exo = load_body(result.exo_source)
    q, z = result.signals["q"], result.signals["pelvis_z"]
    assert np.abs(z).max() > 1e-3  # the pelvis sank into the shoes
    for side in SIDES:
        ticks, joints = entity_columns(path, f"world/exo/{side}/joints", "Points3D:positions")
        for k, pts in zip(ticks, joints, strict=True):
            foot = exo.frame_position(q[k], f"{side}_foot") + np.array([0.0, 0.0, z[k]])
            assert np.allclose(np.asarray(pts)[2], foot, atol=1e-6)
