"""The 3-D scene of a recording: both bodies' legs, the cuff forces, the belt and the plan.

The poses come from the logged joint angles through the forward kinematics
of the two models, evaluated for many poses at once: for a model whose
joints are all revolute (Pinocchio's reduced models here), joint i's world
placement is

    ⁰Mᵢ = ⁰M_parent(i) · Pᵢ · Rot(aᵢ, qᵢ),

with Pᵢ its fixed placement in its parent, aᵢ its axis and Rot Rodrigues'
rotation I + sin q [a]ₓ + (1 − cos q) [a]ₓ²; a frame's point is
⁰p_f = ⁰pᵢ + ⁰Rᵢ · pᶠ for its placement pᶠ in its joint.  The result is
checked against Pinocchio's own ``framesForwardKinematics`` when the
skeleton is built; a model it does not fit (another joint type, or a
mismatch) is evaluated pose by pose through Pinocchio instead.

The patient's world is shifted in x and z so that its left hip sits on the
exoskeleton's (as the plant's ``patient_offset_xz`` does); y is the model's.
Positions are metres in the exoskeleton's world frame (x forward, z up).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
import pyarrow as pa
import rerun as rr

from ..model import CUFF_NAMES, SIDES, BodyModel
from ..plan import GaitParams, GaitPlan
from .columns import EntityBatch, list_offsets, pool_vector
from .format import COLORS, FORCE_ARROW_M_PER_N

__all__ = ["Skeleton", "log_scene_static", "send_scene"]

_STRIPE_SPACING_M = 0.1
#: Largest difference to Pinocchio's forward kinematics accepted for the batched one [m].
_FK_CHECK_M = 1e-9
#: Arrow types of rerun's Vec3D and LineStrip3D components (rerun 0.41).
_VEC3 = pa.list_(pa.field("item", pa.float32(), nullable=False), 3)
_STRIP = pa.list_(pa.field("item", _VEC3, nullable=False))
_POSITIONS = rr.Points3D.descriptor_positions()
_LINES = rr.LineStrips3D.descriptor_strips()
_ORIGINS = rr.Arrows3D.descriptor_origins()
_VECTORS = rr.Arrows3D.descriptor_vectors()


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


class Skeleton:
    """World points of one body's legs from its joint angles.

    Args:
        body: the body.
        offset_xz: shift of the body's world in (x, z) [m].

    """

    def __init__(self, body: BodyModel, offset_xz: tuple[float, float] = (0.0, 0.0)) -> None:
        self.model = body.model
        self.data = body.model.createData()
        self.q_index = np.asarray(body.q_index)
        self.q_model = pin.neutral(body.model)
        self.hips = body.joint_ids[0::2]
        self.knees = body.joint_ids[1::2]
        self.feet = body.foot_frame_ids
        self.cuffs = body.cuff_frame_ids
        self.offset = np.array([offset_xz[0], 0.0, offset_xz[1]])
        self._chain = self._revolute_chain()
        if self._chain is not None:
            probe = np.random.default_rng(0).uniform(-1.5, 1.5, (3, 4))
            batched, exact = self._batched(probe), self._pinocchio(probe)
            if max(float(np.max(np.abs(a - b))) for a, b in zip(batched, exact, strict=True)) > (
                _FK_CHECK_M
            ):
                self._chain = None

    def points(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Leg points and cuff points for joint angles q, (m, 4) in JOINT_NAMES order [rad].

        Returns:
            legs (m, 2, 3, 3): side, (hip, knee, foot), xyz [m];
            cuffs (m, 4, 3): cuff in CUFF_NAMES order, xyz [m].

        """
        legs, cuffs = self._batched(q) if self._chain is not None else self._pinocchio(q)
        legs += self.offset
        cuffs += self.offset
        return legs, cuffs

    def _revolute_chain(self) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray, int]] | None:
        """Per joint (parent, Pᵢ rotation, Pᵢ translation, [aᵢ]ₓ, q column), or None."""
        model, data = self.model, self.data
        chain = []
        for i in range(1, model.njoints):
            joint = model.joints[i]
            if joint.nq != 1 or joint.nv != 1:
                return None
            q = pin.neutral(model)
            q[joint.idx_q] += 1.0
            pin.forwardKinematics(model, data, q)
            motion = model.jointPlacements[i].actInv(data.liMi[i])
            axis = pin.log3(motion.rotation)
            if np.linalg.norm(motion.translation) > 1e-12 or abs(np.linalg.norm(axis) - 1) > 1e-9:
                return None  # not a revolute joint about a fixed axis
            placement = model.jointPlacements[i]
            chain.append(
                (
                    int(model.parents[i]),
                    placement.rotation.copy(),
                    placement.translation.copy(),
                    _skew(axis),
                    int(joint.idx_q),
                )
            )
        return chain

    def _batched(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = q.shape[0]
        qm = np.repeat(self.q_model[None], m, axis=0)
        qm[:, self.q_index] = q
        rot = [np.broadcast_to(np.eye(3), (m, 3, 3))]
        pos = [np.zeros((m, 3))]
        for parent, r_fix, t_fix, k, q_column in self._chain or ():
            theta = qm[:, q_column, None, None]
            turn = np.eye(3) + np.sin(theta) * k + (1.0 - np.cos(theta)) * (k @ k)
            pos.append(pos[parent] + rot[parent] @ t_fix)
            rot.append(rot[parent] @ (r_fix @ turn))

        def frame(f: int) -> np.ndarray:
            fr = self.model.frames[f]
            return pos[fr.parentJoint] + rot[fr.parentJoint] @ fr.placement.translation

        legs = np.empty((m, 2, 3, 3))
        for s in range(2):
            legs[:, s, 0] = pos[self.hips[s]]
            legs[:, s, 1] = pos[self.knees[s]]
            legs[:, s, 2] = frame(self.feet[s])
        cuffs = np.stack([frame(f) for f in self.cuffs], axis=1)
        return legs, cuffs

    def _pinocchio(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = q.shape[0]
        legs = np.empty((m, 2, 3, 3))
        cuffs = np.empty((m, 4, 3))
        model, data, qm = self.model, self.data, self.q_model.copy()
        for i in range(m):
            qm[self.q_index] = q[i]
            pin.framesForwardKinematics(model, data, qm)
            for s in range(2):
                legs[i, s, 0] = data.oMi[self.hips[s]].translation
                legs[i, s, 1] = data.oMi[self.knees[s]].translation
                legs[i, s, 2] = data.oMf[self.feet[s]].translation
            for c in range(4):
                cuffs[i, c] = data.oMf[self.cuffs[c]].translation
        return legs, cuffs


def _static(rec: rr.RecordingStream, entity: str, archetype: Any) -> None:
    rec.log(entity, archetype, static=True, strict=True)


def _vec3(points: np.ndarray) -> pa.Array:
    """Points (..., 3) [m] as rerun's Vec3D components (float32)."""
    vector, buffer = pool_vector(points.size, np.float32)
    vector.reshape(points.shape)[...] = points
    flat = pa.Array.from_buffers(pa.float32(), points.size, [None, buffer])
    return pa.FixedSizeListArray.from_arrays(flat, type=_VEC3)


def _strips(points: np.ndarray) -> pa.Array:
    """Line strips (k, p, 3) [m] as rerun's LineStrip3D components."""
    k, p = points.shape[:2]
    return pa.ListArray.from_arrays(list_offsets(k, p), _vec3(points), type=_STRIP)


def log_scene_static(
    rec: rr.RecordingStream,
    gait: GaitParams,
    exo: BodyModel,
    patient_feet: bool = False,
    ground: bool = True,
) -> dict[str, float]:
    """Styles of the moving entities, the belt and the planned foot paths (static).

    ``patient_feet``: the run's patient feet meet the belt (their force arrows);
    ``ground``: the belt's force on the exoskeleton's feet is drawn (the contact on).

    The foot path of each leg is the plan's foot position relative to the hip
    (:meth:`GaitPlan.feet` over one period) plus the exo's hip position.  The
    belt's top is at the stance-foot height, exo hip z - hip_height.

    Returns:
        The belt's geometry for its markings: ``x_min``, ``length``,
        ``y_min``, ``y_max``, ``z`` [m].

    """
    for body, radius in (("exo", 0.012), ("patient", 0.03)):
        for side in SIDES:
            base, color = f"world/{body}/{side}", COLORS[body]
            _static(rec, f"{base}/leg", rr.LineStrips3D.from_fields(radii=radius, colors=color))
            joints = rr.Points3D.from_fields(radii=1.6 * radius, colors=color)
            _static(rec, f"{base}/joints", joints)
            cuffs = rr.Points3D.from_fields(radii=1.3 * radius, colors=COLORS["cuff"])
            _static(rec, f"{base}/cuffs", cuffs)
    for cuff in CUFF_NAMES:
        arrows = rr.Arrows3D.from_fields(radii=0.006, colors=COLORS["force"])
        _static(rec, f"world/cuff_force/{cuff}", arrows)
    for side in SIDES:  # the belt's force on each exoskeleton foot (with the contact on)
        arrows = rr.Arrows3D.from_fields(radii=0.006, colors=COLORS["force"])
        if ground:
            _static(rec, f"world/ground_force/{side}", arrows)
        if patient_feet:  # and on each patient foot (ContactParams.patient_feet)
            _static(rec, f"world/patient_ground_force/{side}", arrows)
    data = exo.model.createData()
    pin.framesForwardKinematics(exo.model, data, pin.neutral(exo.model))
    hips = [data.oMi[exo.joint_ids[2 * s]].translation.copy() for s in range(2)]
    t = np.linspace(0.0, gait.period, 241)
    feet = GaitPlan(gait).feet(t).pos  # (N, leg, (x, z)) relative to the hip
    paths = np.repeat(np.stack(hips)[None], t.shape[0], axis=0)  # (N, leg, xyz)
    paths[..., [0, 2]] += feet
    for s, side in enumerate(SIDES):
        strips = rr.LineStrips3D([paths[:, s]], radii=0.004, colors=COLORS["plan"])
        _static(rec, f"world/plan/foot_path/{side}", strips)
    top = float(hips[0][2] - gait.hip_height)
    xs = paths[..., 0]
    half_length = max(0.8, 0.5 * float(xs.max() - xs.min()) + 0.5)
    half_width = max(abs(h[1]) for h in hips) + 0.2
    x_center = float(hips[0][0])
    y_center = 0.5 * float(hips[0][1] + hips[1][1])
    belt = rr.Boxes3D(
        centers=[[x_center, y_center, top - 0.01]],
        half_sizes=[[half_length, half_width, 0.01]],
        colors=COLORS["belt"],
        fill_mode=rr.components.FillMode.Solid,
    )
    _static(rec, "world/belt", belt)
    stripes = rr.LineStrips3D.from_fields(radii=0.003, colors=COLORS["stripe"])
    _static(rec, "world/belt/stripes", stripes)
    return {
        "x_min": x_center - half_length,
        "length": 2.0 * half_length,
        "y_min": y_center - half_width,
        "y_max": y_center + half_width,
        "z": top + 0.002,
    }


def send_scene(
    rec: rr.RecordingStream,
    ticks: np.ndarray,
    dt: float,
    bodies: tuple[tuple[str, Skeleton, np.ndarray], ...],
    cuff_force: np.ndarray,
    belt: dict[str, float],
    v_belt: float,
    ground_force: np.ndarray | None = None,
    pelvis_z: np.ndarray | None = None,
    patient_ground_force: np.ndarray | None = None,
) -> None:
    """Send the scene at the ticks ``ticks``, every entity in one record batch.

    Args:
        rec: the recording.
        ticks: the ticks k shown, (m,); their times are k Δt.
        dt: the control period Δt [s].
        bodies: ("exo" or "patient", its skeleton, its joint angles (m, 4) [rad]),
            the exoskeleton first (the force arrows start at its cuffs).
        cuff_force: cuff forces on the exoskeleton (m, 4, 2) [N].
        belt: the belt's geometry from :func:`log_scene_static`.
        v_belt: belt speed [m/s]; its top moves backwards (-x).
        ground_force: the belt's force on each exoskeleton foot (m, 2, 2) [N]
            (x, z), drawn at the feet (None: not drawn).
        pelvis_z: the pelvis's height above its nominal (m,) [m]: both bodies
            ride on it (:mod:`exo_ctrl.plant.pelvis`; None: fixed).
        patient_ground_force: the belt's force on each patient foot (m, 2, 2)
            [N], drawn at the patient's feet (None: not drawn).

    """
    m = ticks.shape[0]
    t = ticks * dt
    batch = EntityBatch(ticks, dt)
    one, two, three = list_offsets(m, 1), list_offsets(m, 2), list_offsets(m, 3)
    exo_cuffs, exo_feet = np.zeros((m, 4, 3)), np.zeros((m, 2, 3))
    feet = {"exo": exo_feet, "patient": np.zeros((m, 2, 3))}
    for body, skeleton, q in bodies:
        legs, cuffs = skeleton.points(q)
        if pelvis_z is not None:  # both bodies hang from the pelvis
            legs[..., 2] += pelvis_z[:, None, None]
            cuffs[..., 2] += pelvis_z[:, None]
        if body == "exo":
            exo_cuffs = cuffs
        feet[body] = legs[:, :, 2]
        for s, side in enumerate(SIDES):
            base = f"world/{body}/{side}"
            batch.add(f"{base}/leg", _LINES, _strips(legs[:, s]), one)
            batch.add(f"{base}/joints", _POSITIONS, _vec3(legs[:, s]), three)
            batch.add(f"{base}/cuffs", _POSITIONS, _vec3(cuffs[:, 2 * s : 2 * s + 2]), two)
    for c, cuff in enumerate(CUFF_NAMES):
        vectors = np.zeros((m, 3))
        vectors[:, [0, 2]] = FORCE_ARROW_M_PER_N * cuff_force[:, c]
        batch.add(f"world/cuff_force/{cuff}", _VECTORS, _vec3(vectors), one)
        batch.add(f"world/cuff_force/{cuff}", _ORIGINS, _vec3(exo_cuffs[:, c]), one)
    for body, entity, force in (
        ("exo", "ground_force", ground_force),
        ("patient", "patient_ground_force", patient_ground_force),
    ):
        for s, side in enumerate(SIDES if force is not None else ()):
            vectors = np.zeros((m, 3))
            vectors[:, [0, 2]] = FORCE_ARROW_M_PER_N * force[:, s]
            batch.add(f"world/{entity}/{side}", _VECTORS, _vec3(vectors), one)
            batch.add(f"world/{entity}/{side}", _ORIGINS, _vec3(feet[body][:, s]), one)
    length = belt["length"]
    ns = max(1, int(length / _STRIPE_SPACING_M))
    x0 = (np.arange(ns) + 0.5) * (length / ns)
    x = belt["x_min"] + np.mod(x0[None, :] - v_belt * t[:, None], length)  # (m, ns)
    stripes = np.empty((m, ns, 2, 3))
    stripes[..., 0] = x[..., None]
    stripes[..., 0, 1] = belt["y_min"]
    stripes[..., 1, 1] = belt["y_max"]
    stripes[..., 2] = belt["z"]
    batch.add("world/belt/stripes", _LINES, _strips(stripes.reshape(-1, 2, 3)), list_offsets(m, ns))
    batch.send(rec)
