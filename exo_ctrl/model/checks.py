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
    links = {link.get("name") for link in root.findall("link")}
    children: dict[str, str] = {}
    for joint in root.findall("joint"):
        jname = joint.get("name", "?")
        parent = joint.find("parent")
        child = joint.find("child")
        if parent is None or child is None:
            raise InvalidModel(src, jname, "joint without <parent> or <child>")
        for end in (parent.get("link"), child.get("link")):
            if end not in links:
                raise InvalidModel(src, jname, f"refers to link {end!r}, which is not defined")
        cname = child.get("link", "")
        if cname in children:
            raise InvalidModel(
                src, cname, f"is the child of two joints ({children[cname]!r} and {jname!r})"
            )
        children[cname] = jname
    for link in root.findall("link"):
        _check_link_inertial(src, link)


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
