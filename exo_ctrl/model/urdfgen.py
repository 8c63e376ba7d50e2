"""Generate the exoskeleton and patient URDFs from body parameters.

Both models are planar two-leg chains in the sagittal plane, following ROS
REP-103 (x forward, y left, z up)::

    pelvis ──{side}_hip──> {side}_thigh ──{side}_knee──> {side}_shank
                               │                            ├── {side}_shank_cuff  (fixed)
                               └── {side}_thigh_cuff (fixed) └── {side}_foot       (fixed)

for ``side`` in ``("left", "right")``.  Joint zero is the leg hanging straight
down.  The hip axis is ``(0, -1, 0)`` and the knee axis ``(0, 1, 0)``, so a
positive joint angle is **flexion** for both joints: a positive hip angle
swings the thigh forward (+x), a positive knee angle swings the shank
backward (-x) relative to the thigh.  With both hip joints at
``y = ±hip_width/2`` on the pelvis, the absolute shank angle from the downward
vertical (forward positive) is ``q_hip - q_knee``.

The cuff and foot points are massless links attached by fixed joints; their
names are identical in the exoskeleton and the patient file, because a cuff
is defined by a pair of equally named frames.  Pinocchio merges fixed joints
into the parent joint, so each of these links becomes a frame (no extra
degree of freedom) whose placement is the fixed-joint origin.

The mass distribution of the thigh and shank links is that of
:func:`~exo_ctrl.model.body_params.segment_inertia`.  yourdfpy takes about a
second to import, so it is imported by the functions that build a model, not
with this module.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._io import atomic_write
from .body_params import BodyParams, segment_inertia
from .names import DEFAULT_URDF_NAMES, SIDES

if TYPE_CHECKING:
    import yourdfpy

__all__ = ["build_urdf", "urdf_xml", "write_urdf"]

_ROBOT_NAMES = {"exo": "exoskeleton", "patient": "patient"}
_RGBA = {"exo": (0.6, 0.6, 0.65, 1.0), "patient": (0.87, 0.72, 0.6, 0.6)}
_PELVIS_SIZE_X = 0.10  # pelvis box depth [m] (for its inertia and visual only)
_PELVIS_SIZE_Z = 0.10  # pelvis box height [m]


def build_urdf(params: BodyParams, scene: bool = True) -> yourdfpy.URDF:
    """Build the URDF model described by ``params`` (meshes are not loaded).

    Args:
        params: body parameters; ``params.kind`` selects the robot name
            (``"exoskeleton"`` or ``"patient"``).
        scene: build the model's scene graph (its visuals as trimesh
            geometry: 3.5 of the 4.1 ms a patient's model takes here; the
            XML does not need it).

    Returns:
        The yourdfpy model, with its scene graph built if ``scene``.

    """
    import yourdfpy

    links = [_pelvis_link(params)]
    joints: list[yourdfpy.Joint] = []
    for side in SIDES:
        side_links, side_joints = _leg(params, side)
        links += side_links
        joints += side_joints
    robot = yourdfpy.Robot(name=_ROBOT_NAMES[params.kind], links=links, joints=joints)
    return yourdfpy.URDF(robot=robot, build_scene_graph=scene, load_meshes=False)


def urdf_xml(params: BodyParams) -> str:
    """URDF text of ``params``, pretty-printed UTF-8 XML ending in a newline.

    Deterministic: the same parameters always give the same text.

    Args:
        params: body parameters.

    Returns:
        The XML document as a string (for ``pinocchio.buildModelFromXML``).

    """
    buffer = io.BytesIO()
    build_urdf(params, scene=False).write_xml().write(
        buffer, xml_declaration=True, pretty_print=True, encoding="UTF-8"
    )
    return buffer.getvalue().decode("utf-8")


def write_urdf(params: BodyParams, path: str | os.PathLike[str]) -> Path:
    """Write the URDF of ``params`` atomically (:func:`exo_ctrl._io.atomic_write`).

    The text goes to a temporary file in the target directory, which then
    replaces ``path`` in one step, so a failure never leaves a partial file;
    the file's mode follows the umask; an existing special file (a FIFO, a
    device) is written to directly.

    Args:
        params: body parameters.
        path: target file, or an existing directory to write
            ``DEFAULT_URDF_NAMES[params.kind]`` into.

    Returns:
        The path written.

    """
    target = Path(path)
    if target.is_dir():
        target = target / DEFAULT_URDF_NAMES[params.kind]
    data = urdf_xml(params).encode("utf-8")
    with atomic_write(target, "wb") as handle:
        handle.write(data)
    return target


def _origin(z: float = 0.0, y: float = 0.0) -> np.ndarray:
    transform = np.eye(4)
    transform[1, 3] = y
    transform[2, 3] = z
    return transform


def _material(params: BodyParams) -> yourdfpy.Material:
    import yourdfpy

    return yourdfpy.Material(
        name=f"{params.kind}_colour", color=yourdfpy.Color(rgba=np.array(_RGBA[params.kind]))
    )


def _pelvis_link(params: BodyParams) -> yourdfpy.Link:
    import yourdfpy

    m = params.pelvis_mass
    x, y, z = _PELVIS_SIZE_X, params.hip_width, _PELVIS_SIZE_Z
    inertia = np.diag([m * (y**2 + z**2), m * (x**2 + z**2), m * (x**2 + y**2)]) / 12.0
    visual = yourdfpy.Visual(
        name="pelvis_visual",
        origin=_origin(),
        geometry=yourdfpy.Geometry(box=yourdfpy.Box(size=np.array([x, y, z]))),
        material=_material(params),
    )
    return yourdfpy.Link(
        name="pelvis",
        inertial=yourdfpy.Inertial(origin=_origin(), mass=m, inertia=inertia),
        visuals=[visual],
    )


def _segment_link(params: BodyParams, side: str, segment: str) -> yourdfpy.Link:
    import yourdfpy

    seg = segment_inertia(params, segment)
    length = getattr(params, f"{segment}_length")
    visual = yourdfpy.Visual(
        name=f"{side}_{segment}_visual",
        origin=_origin(z=-length / 2.0),
        geometry=yourdfpy.Geometry(
            cylinder=yourdfpy.Cylinder(radius=getattr(params, f"{segment}_radius"), length=length)
        ),
        material=_material(params),
    )
    return yourdfpy.Link(
        name=f"{side}_{segment}",
        inertial=yourdfpy.Inertial(
            origin=_origin(z=-seg.com),
            mass=seg.mass,
            inertia=np.diag([seg.transverse, seg.transverse, seg.axial]),
        ),
        visuals=[visual],
    )


def _leg(params: BodyParams, side: str) -> tuple[list[yourdfpy.Link], list[yourdfpy.Joint]]:
    import yourdfpy

    sign = 1.0 if side == "left" else -1.0
    dynamics = yourdfpy.Dynamics(damping=params.joint_damping, friction=params.joint_friction)

    def limit(bounds: tuple[float, float]) -> yourdfpy.Limit:
        return yourdfpy.Limit(
            effort=params.effort_limit,
            velocity=params.velocity_limit,
            lower=bounds[0],
            upper=bounds[1],
        )

    thigh, shank = f"{side}_thigh", f"{side}_shank"
    joints = [
        yourdfpy.Joint(
            name=f"{side}_hip",
            type="revolute",
            parent="pelvis",
            child=thigh,
            origin=_origin(y=sign * params.hip_width / 2.0),
            axis=np.array([0.0, -1.0, 0.0]),
            limit=limit(params.hip_range),
            dynamics=dynamics,
        ),
        yourdfpy.Joint(
            name=f"{side}_knee",
            type="revolute",
            parent=thigh,
            child=shank,
            origin=_origin(z=-params.thigh_length),
            axis=np.array([0.0, 1.0, 0.0]),
            limit=limit(params.knee_range),
            dynamics=dynamics,
        ),
    ]
    links = [_segment_link(params, side, "thigh"), _segment_link(params, side, "shank")]
    frames = (
        (f"{side}_thigh_cuff", thigh, params.thigh_cuff),
        (f"{side}_shank_cuff", shank, params.shank_cuff),
        (f"{side}_foot", shank, params.shank_length),
    )
    for name, parent, distance in frames:
        links.append(yourdfpy.Link(name=name))  # massless: no <inertial>
        joints.append(
            yourdfpy.Joint(
                name=f"{name}_joint",
                type="fixed",
                parent=parent,
                child=name,
                origin=_origin(z=-distance),
            )
        )
    return links, joints
