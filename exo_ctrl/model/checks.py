"""Checks of a URDF that Pinocchio's parser does not make: structure, masses, inertias.

Pinocchio accepts negative masses, non-physical inertias and two joints onto
one child link (ABA then returns NaN) and reports a malformed file only as
"not a valid URDF model".  These checks name the element at fault instead.

A rigid body's inertia is physical when its mass m > 0 and its 4×4
pseudo-inertia ``J = [[Σ, m c], [m cᵀ, m]]`` (``Σ = ½ tr(I) 1 - I + m c cᵀ``
for the rotational inertia I about the COM and the COM position c) is
positive definite; for I about the COM this is: principal moments > 0, each
smaller than the sum of the other two (the triangle inequality).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from ..exceptions import InvalidModel

__all__ = ["check_inertias", "check_urdf_xml"]


def check_urdf_xml(src: str, xml: str) -> None:
    """Check a URDF text: XML syntax, joints between defined links, one parent per link, inertias.

    Args:
        src: where the text came from (for messages).
        xml: the URDF document.

    Raises:
        InvalidModel: naming the line and column of an XML error, or the joint
            or link at fault (a mass ≤ 0 kg or not finite, a non-physical
            inertia, a joint referring to an undefined link, a link that is the
            child of two joints).

    """
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as exc:
        line, col = exc.position
        raise InvalidModel(src, "", f"malformed XML at line {line}, column {col}") from None
    if root.tag != "robot":
        raise InvalidModel(src, "", f"the root element is <{root.tag}>, expected <robot>")
    links: set[str | None] = set()
    for link in root.findall("link"):
        if link.get("name") in links:
            raise InvalidModel(src, link.get("name", "?"), "link defined twice")
        links.add(link.get("name"))
    children: dict[str, str] = {}
    reach: dict[str, float] = {}  # link → farthest child joint from its origin [m]
    below: dict[str, list[str]] = {}  # link → its child links
    for joint in root.findall("joint"):
        jname = joint.get("name", "?")
        parent = joint.find("parent")
        child = joint.find("child")
        if parent is None or child is None:
            raise InvalidModel(src, jname, "joint without <parent> or <child>")
        _check_joint(src, joint)
        offset = _xyz(src, jname, joint.find("origin"), "origin")
        pname = parent.get("link", "")
        reach[pname] = max(reach.get(pname, 0.0), float(np.linalg.norm(offset)))
        for end in (parent.get("link"), child.get("link")):
            if end not in links:
                raise InvalidModel(src, jname, f"refers to link {end!r}, which is not defined")
        cname = child.get("link", "")
        if cname in children:
            raise InvalidModel(
                src, cname, f"is the child of two joints ({children[cname]!r} and {jname!r})"
            )
        children[cname] = jname
        below.setdefault(pname, []).append(cname)
    _check_tree(src, links, children, below)
    for link in root.findall("link"):
        _check_link_inertial(src, link)
        _check_com(src, link, reach.get(link.get("name", ""), 0.0))


def _check_tree(
    src: str, links: set[str | None], children: dict[str, str], below: dict[str, list[str]]
) -> None:
    """The joints make one tree: one root link, every other link reached from it.

    Pinocchio's parser (urdfdom) reports a second root on several lines of
    its own and builds a model from a root when the joints also form a loop
    elsewhere; both are refused here by link name.
    """
    if len(links) <= 1:
        return
    roots = sorted(str(name) for name in links if name not in children)
    if not roots:
        raise InvalidModel(src, "", "no root link: the joints form a loop")
    if len(roots) > 1:
        shown = ", ".join(repr(r) for r in roots[:3]) + (", ..." if len(roots) > 3 else "")
        raise InvalidModel(
            src,
            "",
            f"{len(roots)} root links ({shown}); a URDF has one, every other link the child "
            "of a joint (a joint missing?)",
        )
    seen, todo = {roots[0]}, [roots[0]]
    while todo:
        for child in below.get(todo.pop(), []):
            if child not in seen:
                seen.add(child)
                todo.append(child)
    cut = sorted(str(name) for name in links if name not in seen)
    if cut:
        raise InvalidModel(
            src,
            cut[0],
            f"is not reached from the root link {roots[0]!r}: the joints form a loop "
            f"({children[cut[0]]!r} makes it a child of a link below it)",
        )


#: How far a link's centre of mass may lie from its joint: this many times the
#: link's length (its farthest child joint) plus :data:`COM_SLACK_M`.
COM_LENGTHS = 10.0
#: The fixed part of the bound on a centre of mass's distance from its joint [m].
COM_SLACK_M = 1.0


def _xyz(src: str, element: str, origin: ET.Element | None, what: str) -> np.ndarray:
    """An ``<origin>``'s xyz [m] (zero when absent), finite or refused by name."""
    if origin is None:
        return np.zeros(3)
    text = origin.get("xyz", "0 0 0")
    try:
        xyz = np.array([float(x) for x in text.split()])
    except ValueError:
        raise InvalidModel(src, element, f"{what} xyz={text!r} is not three numbers") from None
    if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
        raise InvalidModel(src, element, f"{what} xyz={text!r} must be three finite numbers [m]")
    return xyz


def _number(src: str, element: str, node: ET.Element, key: str) -> float | None:
    """Attribute ``key`` of ``node`` as a finite float (None when absent)."""
    text = node.get(key)
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise InvalidModel(src, element, f"{key}={text!r} must be a finite number")
    return value


def _check_joint(src: str, joint: ET.Element) -> None:
    """A joint's ``<limit>`` and ``<dynamics>``: what the drive and the safety limits need.

    A revolute or prismatic joint needs a ``<limit>`` with effort > 0 N·m and
    velocity > 0 rad/s and lower ≤ upper [rad]; damping [N·m·s/rad] and
    friction [N·m] are ≥ 0.
    """
    jname = joint.get("name", "?")
    kind = joint.get("type", "")
    limit = joint.find("limit")
    if kind in ("revolute", "prismatic") and limit is None:
        raise InvalidModel(src, jname, f"a {kind} joint needs a <limit> (effort, velocity, range)")
    if limit is not None:
        for key, unit in (("effort", "N·m"), ("velocity", "rad/s")):
            value = _number(src, jname, limit, key)
            if value is not None and value <= 0.0:
                raise InvalidModel(src, jname, f"{key} limit must be > 0 {unit}; got {value:g}")
        lower, upper = _number(src, jname, limit, "lower"), _number(src, jname, limit, "upper")
        if lower is not None and upper is not None and lower > upper:
            raise InvalidModel(
                src, jname, f"lower limit {lower:g} rad is above the upper limit {upper:g} rad"
            )
    dynamics = joint.find("dynamics")
    if dynamics is not None:
        for key, unit in (("damping", "N·m·s/rad"), ("friction", "N·m")):
            value = _number(src, jname, dynamics, key)
            if value is not None and value < 0.0:
                raise InvalidModel(src, jname, f"{key} must be >= 0 {unit}; got {value:g}")


def _check_com(src: str, link: ET.Element, length: float) -> None:
    """A link's centre of mass within :data:`COM_LENGTHS` link lengths + :data:`COM_SLACK_M`."""
    inertial = link.find("inertial")
    if inertial is None:
        return
    lname = link.get("name", "?")
    com = _xyz(src, lname, inertial.find("origin"), "centre of mass")
    bound = COM_LENGTHS * length + COM_SLACK_M
    distance = float(np.linalg.norm(com))
    if distance > bound:
        raise InvalidModel(
            src,
            lname,
            f"centre of mass {distance:.4g} m from its joint; at most {COM_LENGTHS:g} times the "
            f"link's length ({length:.4g} m) + {COM_SLACK_M:g} m = {bound:.4g} m",
        )


def _check_link_inertial(src: str, link: ET.Element) -> None:
    """Check one link's ``<inertial>``: mass > 0 kg, a physical inertia [kg·m²]."""
    lname = link.get("name", "?")
    inertial = link.find("inertial")
    if inertial is None:
        return
    mass_el = inertial.find("mass")
    inertia_el = inertial.find("inertia")
    try:
        mass = float(mass_el.get("value", "nan")) if mass_el is not None else math.nan
        keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        moments = {k: float(inertia_el.get(k, "0")) for k in keys} if inertia_el is not None else {}
    except ValueError:
        raise InvalidModel(src, lname, "mass or inertia is not a number") from None
    if not math.isfinite(mass) or mass <= 0.0:
        raise InvalidModel(src, lname, f"mass must be a finite number > 0 kg; got {mass:g}")
    if inertia_el is None:
        return
    inertia = np.array(
        [
            [moments["ixx"], moments["ixy"], moments["ixz"]],
            [moments["ixy"], moments["iyy"], moments["iyz"]],
            [moments["ixz"], moments["iyz"], moments["izz"]],
        ]
    )
    if not np.all(np.isfinite(inertia)):
        raise InvalidModel(src, lname, "inertia has a non-finite entry")
    reason = _inertia_fault(inertia)
    if reason:
        raise InvalidModel(src, lname, f"inertia is not physically valid: {reason}")


def _inertia_fault(inertia: np.ndarray) -> str:
    """Why a rotational inertia about the COM [kg·m²] is not physical ("" if it is).

    The test is the module docstring's, in plain numpy (Pinocchio's own
    ``Inertia`` constructor throws a bare ``RuntimeError`` on a negative
    diagonal entry): each diagonal entry > 0, then the principal moments
    λ_i > 0 with λ_i < λ_j + λ_k, i.e. Σ = ½ tr(I) 1 - I positive definite.
    """
    for axis, name in enumerate(("ixx", "iyy", "izz")):
        if not inertia[axis, axis] > 0.0:
            return f"{name} = {inertia[axis, axis]:.4g} kg·m² must be > 0"
    eig = np.linalg.eigvalsh(inertia)
    if eig[0] > 0.0 and np.sum(eig) - 2.0 * eig[-1] > 0.0:
        return ""
    return (
        f"the principal moments {', '.join(f'{e:.4g}' for e in eig)} kg·m² must be > 0 "
        "and each smaller than the sum of the other two"
    )


def _pseudo_inertia_pd(inertia: pin.Inertia) -> bool:
    """Whether the pseudo-inertia of ``inertia`` is finite and positive definite."""
    pseudo = inertia.toPseudoInertia().toMatrix()
    if not np.all(np.isfinite(pseudo)):
        return False
    return bool(np.linalg.eigvalsh(0.5 * (pseudo + pseudo.T))[0] > 0.0)


def check_inertias(src: str, model: pin.Model, joint_ids: tuple[int, ...]) -> None:
    """Check the body each driven joint moves (links merged by locked joints included).

    Raises:
        InvalidModel: a body with mass ≤ 0 kg or a non-physical inertia.

    """
    for jid in joint_ids:
        inertia = model.inertias[jid]
        body = model.names[jid]
        if not inertia.mass > 0.0:
            raise InvalidModel(
                src, body, f"the body moved by this joint has mass {inertia.mass:g} kg"
            )
        if not _pseudo_inertia_pd(inertia):
            raise InvalidModel(src, body, "the body moved by this joint has a non-physical inertia")
