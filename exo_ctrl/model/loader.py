"""Loading a two-legged body (exoskeleton or patient) from a URDF.

A body is any URDF with a sagittal hip and knee joint on each leg.  The joints
are found by name (``left_hip``, ``left_knee``, ``right_hip``, ``right_knee``
by default; a mapping selects the joints of another URDF) and every other
joint is locked at its neutral value.  Everything geometric is read from the
model (:mod:`exo_ctrl.model.geometry`): link lengths from the joint
placements, the sign and zero of each joint angle from its axis, the cuff and
foot points from named frames.  The file is checked first
(:mod:`exo_ctrl.model.checks`), because Pinocchio's parser accepts
non-physical models.

Frames: world x forward, y left, z up (REP-103); gravity 9.81 m/s² along -z.
"""

from __future__ import annotations

import contextlib
import os
import sysconfig
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np
import pinocchio as pin

from .._io import not_a_file
from ..exceptions import InvalidModel
from .body_params import BodyParams
from .checks import check_inertias, check_urdf_xml
from .geometry import LegGeometry, leg_geometry
from .names import CUFF_NAMES, DEFAULT_URDF_NAMES, JOINT_NAMES, SIDES
from .prescan import c_stderr, parser_reason, prescan_urdf
from .urdfgen import write_urdf

__all__ = [
    "Y_UP_TO_Z_UP",
    "BodyModel",
    "default_urdf_path",
    "human_urdf_path",
    "load_body",
    "load_exo",
    "load_human_patient",
    "load_patient",
]

#: Rotation taking a y-up, z-right model (example-robot-data's human) to
#: REP-103 (x forward, y left, z up).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

#: Cuff positions on an anatomical model without cuff frames, as fractions of
#: the link (0.39 / 0.52 and 0.45 / 0.52, paper Table I).
THIGH_CUFF_FRACTION = 0.39 / 0.52
SHANK_CUFF_FRACTION = 0.45 / 0.52


@dataclass
class BodyModel:
    """A two-legged body as a Pinocchio model.

    Attributes:
        name: a short name for messages ("exoskeleton", "patient").
        source: where the model came from (path or preset name).
        model: the reduced Pinocchio model (only the four driven joints move).
        joint_ids: Pinocchio joint ids, in :data:`JOINT_NAMES` order.
        q_index: index in q (and v; all joints are 1-DoF) per driven joint, in
            :data:`JOINT_NAMES` order.
        cuff_frame_ids: Pinocchio frame ids of the cuffs, in :data:`CUFF_NAMES`
            order.
        foot_frame_ids: frame ids of the left and right foot points.
        legs: sagittal geometry per side.

    """

    name: str
    source: str
    model: pin.Model
    joint_ids: tuple[int, ...]
    q_index: np.ndarray
    cuff_frame_ids: tuple[int, ...]
    foot_frame_ids: tuple[int, ...]
    legs: dict[str, LegGeometry]

    @property
    def position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper joint limits [rad], in :data:`JOINT_NAMES` order."""
        return (
            self.model.lowerPositionLimit[self.q_index].copy(),
            self.model.upperPositionLimit[self.q_index].copy(),
        )

    @property
    def effort_limit(self) -> np.ndarray:
        """Joint effort limits [N·m], in :data:`JOINT_NAMES` order."""
        return self.model.effortLimit[self.q_index].copy()

    @property
    def velocity_limit(self) -> np.ndarray:
        """Joint speed limits [rad/s], in :data:`JOINT_NAMES` order."""
        return self.model.velocityLimit[self.q_index].copy()

    @property
    def damping(self) -> np.ndarray:
        """Viscous joint damping from the URDF [N·m·s/rad], in JOINT_NAMES order."""
        return self.model.damping[self.q_index].copy()

    @property
    def friction(self) -> np.ndarray:
        """Coulomb joint friction from the URDF [N·m], in JOINT_NAMES order."""
        return self.model.friction[self.q_index].copy()

    @property
    def mass(self) -> float:
        """Mass of the moving links (thighs and shanks with what is fixed to them) [kg]."""
        return float(sum(self.model.inertias[j].mass for j in self.joint_ids))

    def require_legs_only(self, who: str) -> None:
        """Refuse a model whose q is not exactly the four leg joints in JOINT_NAMES order.

        Args:
            who: what needs it, for the message (``"the plant"``, ``"the estimator"``).

        Raises:
            InvalidModel: other joints, or the leg joints in another order.

        """
        if not np.array_equal(self.q_index, np.arange(4)) or self.model.nq != 4:
            raise InvalidModel(
                self.source, "", f"{who} needs exactly the joints {JOINT_NAMES} in that order"
            )

    def require_leg_chains(self, who: str) -> None:
        """:meth:`require_legs_only`, and each leg a hip on the fixed frame and a knee on the hip.

        The two-link legs a closed-form leg model assumes (each cuff's frame on
        its link is the loader's own check, :mod:`exo_ctrl.model.geometry`).

        Args:
            who: what needs it, for the message (``"the QP cuff model"``).

        Raises:
            InvalidModel: the joints of :meth:`require_legs_only`, or the first
                leg that is not such a chain, named by its hip.

        """
        self.require_legs_only(who)
        parents = self.model.parents
        for leg in (0, 1):
            hip, knee = self.joint_ids[2 * leg], self.joint_ids[2 * leg + 1]
            if parents[hip] != 0 or parents[knee] != hip:
                raise InvalidModel(
                    self.source,
                    self.model.names[hip],
                    f"{who} needs each leg as a hip on the fixed frame and a knee on the hip",
                )

    def to_model_q(self, q: np.ndarray) -> np.ndarray:
        """Joint vector in JOINT_NAMES order → the model's own q ordering."""
        out = np.zeros(self.model.nq)
        out[self.q_index] = q
        return out

    def frame_position(self, q: np.ndarray, frame: str) -> np.ndarray:
        """World position [m] of a named frame at joint angles q (JOINT_NAMES order)."""
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, self.to_model_q(q))
        return data.oMf[self.model.getFrameId(frame)].translation.copy()


def default_urdf_path(kind: str) -> Path:
    """Path of the committed default URDF: ``kind`` is "exo" or "patient".

    The files live in the repository's ``urdf/`` folder.  When that folder is
    not beside the package (a non-editable install), the default file is
    generated from the default parameters into a per-user cache; a test
    checks that the committed files equal the generator's output.
    """
    if kind not in DEFAULT_URDF_NAMES:
        raise InvalidModel(kind, "", f"unknown default body {kind!r}; expected 'exo' or 'patient'")
    filename = DEFAULT_URDF_NAMES[kind]
    path = Path(__file__).resolve().parents[2] / "urdf" / filename
    if path.is_file():
        return path
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "exo_ctrl"
    cache.mkdir(parents=True, exist_ok=True)
    params = BodyParams.exo_default() if kind == "exo" else BodyParams.patient_default()
    return write_urdf(params, cache / filename)


def human_urdf_path() -> Path:
    """Path of example-robot-data's human model (``human_description``)."""
    rel = Path("cmeel.prefix/share/example-robot-data/robots/human_description/robots/human.urdf")
    candidates = [Path(sysconfig.get_paths()["purelib"]) / rel]
    with contextlib.suppress(metadata.PackageNotFoundError):
        candidates.append(Path(str(metadata.distribution("example-robot-data").locate_file(rel))))
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise InvalidModel(
        "human", "", "example-robot-data's human.urdf was not found; pip install example-robot-data"
    )


def load_body(
    source: str | os.PathLike[str],
    *,
    name: str = "body",
    joint_map: dict[str, str] | None = None,
    world_rotation: np.ndarray | None = None,
    extra_frames: bool = False,
) -> BodyModel:
    """Load a URDF as a two-legged body.

    Args:
        source: path of the URDF file.
        name: short name used in messages.
        joint_map: our joint name (``left_hip`` …) → the URDF's joint name;
            identity by default.
        world_rotation: 3×3 rotation applied to the whole model so that it
            follows REP-103 (x forward, y left, z up); identity by default.
        extra_frames: add the cuff and foot frames from the leg geometry when
            the URDF has none (for anatomical models; see
            :func:`load_human_patient`).

    Raises:
        InvalidModel: the file is missing or malformed, a joint or frame is
            missing, a joint is not a lateral revolute joint, or a link has a
            non-physical mass or inertia.

    """
    path = Path(source)
    src = str(path)
    if not path.is_file():
        raise InvalidModel(src, "", not_a_file(path))
    prescan_urdf(src, path)  # before any parser: Pinocchio's can crash the process
    xml = path.read_text(encoding="utf-8", errors="replace")
    check_urdf_xml(src, xml)
    error: Exception | None = None
    with c_stderr() as noise:  # urdfdom prints its reasons there, over several lines
        try:
            full = pin.buildModelFromXML(xml)
        except (ValueError, RuntimeError) as exc:
            error = exc
    if error is not None:
        said = parser_reason(noise)
        why = f"{error}; the parser said: {said}" if said else str(error)
        raise InvalidModel(src, "", f"Pinocchio could not build a model from it ({why})")
    joint_map = {j: j for j in JOINT_NAMES} if joint_map is None else dict(joint_map)
    missing_keys = [j for j in JOINT_NAMES if j not in joint_map]
    if missing_keys:
        raise InvalidModel(src, missing_keys[0], "the joint map has no entry for this joint")
    for ours in JOINT_NAMES:
        theirs = joint_map[ours]
        if not full.existJointName(theirs):
            raise InvalidModel(src, theirs, f"joint not found (needed as {ours})")
    keep = {full.getJointId(joint_map[j]) for j in JOINT_NAMES}
    lock = [j for j in range(1, full.njoints) if j not in keep]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    if world_rotation is not None:
        _rotate_model(model, np.asarray(world_rotation, dtype=float))
    model.gravity = pin.Motion(np.array([0.0, 0.0, -9.81, 0.0, 0.0, 0.0]))
    joint_ids = tuple(model.getJointId(joint_map[j]) for j in JOINT_NAMES)
    for ours, jid in zip(JOINT_NAMES, joint_ids, strict=True):
        if model.joints[jid].nq != 1 or model.joints[jid].nv != 1:
            raise InvalidModel(src, joint_map[ours], "must be a 1-DoF revolute joint")
        kind = model.joints[jid].shortname()  # JointModelRY, JointModelPY, ...Unaligned
        if kind.startswith(("JointModelP", "JointModelPrismatic")):
            raise InvalidModel(
                src,
                joint_map[ours],
                f"must be a revolute joint (the drive turns it); got a prismatic joint ({kind})",
            )
    check_inertias(src, model, joint_ids)
    if extra_frames:
        _add_anatomical_frames(model, joint_ids)
    cuff_ids = tuple(_frame_id(src, model, c + "_cuff") for c in CUFF_NAMES)
    foot_ids = tuple(_frame_id(src, model, f"{side}_foot") for side in SIDES)
    q_index = np.array([model.joints[j].idx_q for j in joint_ids], dtype=int)
    legs = leg_geometry(src, model, joint_ids, cuff_ids, foot_ids)
    return BodyModel(
        name=name,
        source=src,
        model=model,
        joint_ids=joint_ids,
        q_index=q_index,
        cuff_frame_ids=cuff_ids,
        foot_frame_ids=foot_ids,
        legs=legs,
    )


def load_human_patient() -> BodyModel:
    """example-robot-data's human model as a patient.

    The sagittal joints ``left_hip_Z``, ``left_knee_Z`` (and right) are the
    driven ones; every other joint is locked at zero.  The model is y-up, so
    it is rotated into REP-103.  It has no cuff frames: the thigh cuff is
    placed at 0.75 of the hip–knee distance below the hip and the shank cuff
    at 0.865 of the knee–ankle distance below the knee (the fractions of the
    paper's 0.39 m and 0.45 m on its 0.52 m links); the foot point is the
    ankle joint.
    """
    joint_map = {j: j + "_Z" for j in JOINT_NAMES}
    return load_body(
        human_urdf_path(),
        name="patient",
        joint_map=joint_map,
        world_rotation=Y_UP_TO_Z_UP,
        extra_frames=True,
    )


def load_exo(source: str | os.PathLike[str] | None = None) -> BodyModel:
    """The exoskeleton from a URDF path, or None for the committed default."""
    return load_body(source or default_urdf_path("exo"), name="exoskeleton")


def load_patient(source: str | os.PathLike[str] | None) -> BodyModel:
    """A patient from a URDF path, ``"human"`` (example-robot-data) or None (default)."""
    if source is None:
        return load_body(default_urdf_path("patient"), name="patient")
    if str(source) == "human":
        return load_human_patient()
    return load_body(source, name="patient")


def _rotate_model(model: pin.Model, rotation: np.ndarray) -> None:
    """Turn the whole model by ``rotation`` (3×3, proper): the joints and frames on the root."""
    if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-9) or np.linalg.det(rotation) < 0:
        raise InvalidModel("world_rotation", "", "must be a proper rotation matrix")
    turn = pin.SE3(rotation, np.zeros(3))
    for jid in range(1, model.njoints):
        if model.parents[jid] == 0:
            model.jointPlacements[jid] = turn * model.jointPlacements[jid]
    for fid in range(model.nframes):
        frame = model.frames[fid]
        if frame.parentJoint == 0 and fid > 0:
            frame.placement = turn * frame.placement
            model.frames[fid] = frame


def _frame_id(src: str, model: pin.Model, frame: str) -> int:
    """Id of a named frame, or InvalidModel naming it."""
    if not model.existFrame(frame):
        raise InvalidModel(src, frame, "frame not found (cuffs and feet are named frames)")
    return model.getFrameId(frame)


def _add_anatomical_frames(model: pin.Model, joint_ids: tuple[int, ...]) -> None:
    """Cuff and foot frames for a model that has none (the human model)."""
    for s, side in enumerate(SIDES):
        hip, knee = joint_ids[2 * s], joint_ids[2 * s + 1]
        hip_to_knee = model.jointPlacements[knee].translation
        ankle = _child_point(model, knee)
        frames = {
            f"{side}_thigh_cuff": (hip, THIGH_CUFF_FRACTION * hip_to_knee),
            f"{side}_shank_cuff": (knee, SHANK_CUFF_FRACTION * ankle),
            f"{side}_foot": (knee, ankle),
        }
        for fname, (parent, offset) in frames.items():
            if model.existFrame(fname):
                continue
            parent_frame = model.getFrameId(model.names[parent])
            placement = pin.SE3(np.eye(3), np.asarray(offset, dtype=float))
            model.addFrame(
                pin.Frame(fname, parent, parent_frame, placement, pin.FrameType.OP_FRAME)
            )


def _child_point(model: pin.Model, joint: int) -> np.ndarray:
    """Origin of the first joint (locked or not) after ``joint``, in its frame."""
    for frame in model.frames:
        if (
            frame.parentJoint == joint
            and frame.type == pin.FrameType.FIXED_JOINT
            and np.linalg.norm(frame.placement.translation) > 1e-6
        ):
            return frame.placement.translation.copy()
    raise InvalidModel("model", model.names[joint], "no joint below it to place the foot at")
