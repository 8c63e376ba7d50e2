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
:func:`~exo_ctrl.model.body_params.segment_inertia`.

One description of the model (:func:`_description`: links and joints as plain
records) feeds both outputs: :func:`urdf_xml` writes it as text with the
standard library, in yourdfpy's serialisation (the same attributes in the same
order, numbers as Python's shortest repr, 2-space indentation), and
:func:`build_urdf` builds yourdfpy's object model from it.  A run that only
needs the text (every simulation's nominal patient, every sweep point's model
digest) never imports yourdfpy, which with trimesh, scipy and networkx takes
about half a second per process here.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import escape

import numpy as np

from .._io import DerivedOutput, atomic_write
from .body_params import BodyParams, segment_inertia
from .names import DEFAULT_URDF_NAMES, SIDES

if TYPE_CHECKING:
    import yourdfpy

__all__ = ["build_urdf", "urdf_xml", "write_urdf"]

_ROBOT_NAMES = {"exo": "exoskeleton", "patient": "patient"}
_RGBA = {"exo": (0.6, 0.6, 0.65, 1.0), "patient": (0.87, 0.72, 0.6, 0.6)}
_PELVIS_SIZE_X = 0.10  # pelvis box depth [m] (for its inertia and visual only)
_PELVIS_SIZE_Z = 0.10  # pelvis box height [m]

#: An origin's rotation as yourdfpy writes the identity (its Euler angles of the
#: identity matrix, pitch -0.0): every origin here is a pure translation.
_RPY_IDENTITY = "0.0 -0.0 0.0"


@dataclass(frozen=True)
class _Inertial:
    """A link's inertial: COM position [m], mass [kg], principal moments about the COM [kg·m²]."""

    xyz: tuple[float, float, float]
    mass: float
    inertia: tuple[float, float, float]  # ixx, iyy, izz; the products are zero


@dataclass(frozen=True)
class _Visual:
    """A link's visual: a box (size x, y, z) or a cylinder (radius, length) [m] at ``xyz``."""

    name: str
    xyz: tuple[float, float, float]
    shape: str  # "box" or "cylinder"
    size: tuple[float, ...]
    material: str
    rgba: tuple[float, float, float, float]


@dataclass(frozen=True)
class _Link:
    name: str
    inertial: _Inertial | None = None  # None: a massless frame
    visual: _Visual | None = None


@dataclass(frozen=True)
class _Joint:
    """A joint; ``limit`` (effort, velocity, lower, upper) and ``dynamics`` (damping, friction)."""

    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    axis: tuple[float, float, float] | None = None
    limit: tuple[float, float, float, float] | None = None
    dynamics: tuple[float, float] | None = None


def _description(params: BodyParams) -> tuple[str, list[_Link], list[_Joint]]:
    """The robot's name, links and joints, in the order they are written."""
    links = [_pelvis_link(params)]
    joints: list[_Joint] = []
    for side in SIDES:
        side_links, side_joints = _leg(params, side)
        links += side_links
        joints += side_joints
    return _ROBOT_NAMES[params.kind], links, joints


def build_urdf(params: BodyParams, scene: bool = True) -> yourdfpy.URDF:
    """Build the URDF model described by ``params`` (meshes are not loaded).

    Args:
        params: body parameters; ``params.kind`` selects the robot name
            (``"exoskeleton"`` or ``"patient"``).
        scene: build the model's scene graph (its visuals as trimesh
            geometry: 3.5 of the 4.1 ms a patient's model takes here).

    Returns:
        The yourdfpy model, with its scene graph built if ``scene``; its
        serialisation is :func:`urdf_xml`'s text.

    """
    import yourdfpy

    def origin(xyz: tuple[float, float, float]) -> np.ndarray:
        transform = np.eye(4)
        transform[:3, 3] = xyz
        return transform

    def link(spec: _Link) -> yourdfpy.Link:
        inertial = visuals = None
        if spec.inertial is not None:
            i = spec.inertial
            inertial = yourdfpy.Inertial(
                origin=origin(i.xyz), mass=i.mass, inertia=np.diag(i.inertia)
            )
        if spec.visual is not None:
            vis = spec.visual
            size = np.array(vis.size)
            geometry = (
                yourdfpy.Geometry(box=yourdfpy.Box(size=size))
                if vis.shape == "box"
                else yourdfpy.Geometry(cylinder=yourdfpy.Cylinder(radius=size[0], length=size[1]))
            )
            visuals = [
                yourdfpy.Visual(
                    name=vis.name,
                    origin=origin(vis.xyz),
                    geometry=geometry,
                    material=yourdfpy.Material(
                        name=vis.material, color=yourdfpy.Color(rgba=np.array(vis.rgba))
                    ),
                )
            ]
        return yourdfpy.Link(name=spec.name, inertial=inertial, visuals=visuals or [])

    def joint(spec: _Joint) -> yourdfpy.Joint:
        limit = dynamics = None
        if spec.limit is not None:
            effort, velocity, lower, upper = spec.limit
            limit = yourdfpy.Limit(effort=effort, velocity=velocity, lower=lower, upper=upper)
        if spec.dynamics is not None:
            dynamics = yourdfpy.Dynamics(damping=spec.dynamics[0], friction=spec.dynamics[1])
        return yourdfpy.Joint(
            name=spec.name,
            type=spec.type,
            parent=spec.parent,
            child=spec.child,
            origin=origin(spec.xyz),
            axis=None if spec.axis is None else np.array(spec.axis),
            limit=limit,
            dynamics=dynamics,
        )

    name, links, joints = _description(params)
    robot = yourdfpy.Robot(
        name=name, links=[link(x) for x in links], joints=[joint(x) for x in joints]
    )
    return yourdfpy.URDF(robot=robot, build_scene_graph=scene, load_meshes=False)


def urdf_xml(params: BodyParams) -> str:
    """URDF text of ``params``, pretty-printed UTF-8 XML ending in a newline.

    Deterministic: the same parameters always give the same text, the text
    yourdfpy writes for :func:`build_urdf`'s model (module docstring).

    Args:
        params: body parameters.

    Returns:
        The XML document as a string (for ``pinocchio.buildModelFromXML``).

    """
    name, links, joints = _description(params)
    out = ["<?xml version='1.0' encoding='UTF-8'?>", f"<robot{_attrs(name=name)}>"]
    for spec in links:
        _write_link(out, spec)
    for spec in joints:
        _write_joint(out, spec)
    out.append("</robot>\n")
    return "\n".join(out)


def _attrs(**values: object) -> str:
    """`` key="value"`` for each attribute, numbers as ``str`` (Python's shortest repr)."""
    parts = []
    for key, value in values.items():
        text = escape(str(value), {'"': "&quot;"})
        parts.append(f' {key}="{text}"')
    return "".join(parts)


def _words(values: tuple[float, ...]) -> str:
    return " ".join(str(x) for x in values)


def _origin(out: list[str], indent: str, xyz: tuple[float, float, float]) -> None:
    out.append(f"{indent}<origin{_attrs(xyz=_words(xyz), rpy=_RPY_IDENTITY)}/>")


def _write_link(out: list[str], spec: _Link) -> None:
    if spec.inertial is None and spec.visual is None:
        out.append(f"  <link{_attrs(name=spec.name)}/>")
        return
    out.append(f"  <link{_attrs(name=spec.name)}>")
    if spec.inertial is not None:
        i = spec.inertial
        ixx, iyy, izz = i.inertia
        out.append("    <inertial>")
        _origin(out, "      ", i.xyz)
        out.append(f"      <mass{_attrs(value=i.mass)}/>")
        inertia = _attrs(ixx=ixx, ixy=0.0, ixz=0.0, iyy=iyy, iyz=0.0, izz=izz)
        out.append(f"      <inertia{inertia}/>")
        out.append("    </inertial>")
    if spec.visual is not None:
        vis = spec.visual
        if vis.shape == "box":
            shape = f"<box{_attrs(size=_words(vis.size))}/>"
        else:
            shape = f"<cylinder{_attrs(radius=vis.size[0], length=vis.size[1])}/>"
        out += [f"    <visual{_attrs(name=vis.name)}>", "      <geometry>", f"        {shape}"]
        out.append("      </geometry>")
        _origin(out, "      ", vis.xyz)
        out.append(f"      <material{_attrs(name=vis.material)}>")
        out.append(f"        <color{_attrs(rgba=_words(vis.rgba))}/>")
        out += ["      </material>", "    </visual>"]
    out.append("  </link>")


def _write_joint(out: list[str], spec: _Joint) -> None:
    out.append(f"  <joint{_attrs(name=spec.name, type=spec.type)}>")
    out.append(f"    <parent{_attrs(link=spec.parent)}/>")
    out.append(f"    <child{_attrs(link=spec.child)}/>")
    _origin(out, "    ", spec.xyz)
    if spec.axis is not None:
        out.append(f"    <axis{_attrs(xyz=_words(spec.axis))}/>")
    if spec.limit is not None:
        effort, velocity, lower, upper = spec.limit
        limit = _attrs(effort=effort, velocity=velocity, lower=lower, upper=upper)
        out.append(f"    <limit{limit}/>")
    if spec.dynamics is not None:
        out.append(f"    <dynamics{_attrs(damping=spec.dynamics[0], friction=spec.dynamics[1])}/>")
    out.append("  </joint>")


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
    target: str | os.PathLike[str] = path
    if Path(path).is_dir():  # a file name the user did not give: never through a link
        target = DerivedOutput(Path(path) / DEFAULT_URDF_NAMES[params.kind])
    data = urdf_xml(params).encode("utf-8")
    with atomic_write(target, "wb") as handle:
        handle.write(data)
    return Path(target)


def _pelvis_link(params: BodyParams) -> _Link:
    m = params.pelvis_mass
    x, y, z = _PELVIS_SIZE_X, params.hip_width, _PELVIS_SIZE_Z
    inertia = (m * (y**2 + z**2) / 12.0, m * (x**2 + z**2) / 12.0, m * (x**2 + y**2) / 12.0)
    rgba = _RGBA[params.kind]
    return _Link(
        name="pelvis",
        inertial=_Inertial(xyz=(0.0, 0.0, 0.0), mass=m, inertia=inertia),
        visual=_Visual("pelvis_visual", (0.0, 0.0, 0.0), "box", (x, y, z), _material(params), rgba),
    )


def _material(params: BodyParams) -> str:
    return f"{params.kind}_colour"


def _segment_link(params: BodyParams, side: str, segment: str) -> _Link:
    seg = segment_inertia(params, segment)
    length = getattr(params, f"{segment}_length")
    radius = getattr(params, f"{segment}_radius")
    return _Link(
        name=f"{side}_{segment}",
        inertial=_Inertial(
            xyz=(0.0, 0.0, -seg.com),
            mass=seg.mass,
            inertia=(seg.transverse, seg.transverse, seg.axial),
        ),
        visual=_Visual(
            f"{side}_{segment}_visual",
            (0.0, 0.0, -length / 2.0),
            "cylinder",
            (radius, length),
            _material(params),
            _RGBA[params.kind],
        ),
    )


def _leg(params: BodyParams, side: str) -> tuple[list[_Link], list[_Joint]]:
    sign = 1.0 if side == "left" else -1.0
    dynamics = (params.joint_damping, params.joint_friction)

    def limit(bounds: tuple[float, float]) -> tuple[float, float, float, float]:
        return (params.effort_limit, params.velocity_limit, bounds[0], bounds[1])

    thigh, shank = f"{side}_thigh", f"{side}_shank"
    joints = [
        _Joint(
            f"{side}_hip",
            "revolute",
            "pelvis",
            thigh,
            (0.0, sign * params.hip_width / 2.0, 0.0),
            axis=(0.0, -1.0, 0.0),
            limit=limit(params.hip_range),
            dynamics=dynamics,
        ),
        _Joint(
            f"{side}_knee",
            "revolute",
            thigh,
            shank,
            (0.0, 0.0, -params.thigh_length),
            axis=(0.0, 1.0, 0.0),
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
        links.append(_Link(name))  # massless: no <inertial>
        joints.append(_Joint(f"{name}_joint", "fixed", parent, name, (0.0, 0.0, -distance)))
    return links, joints
