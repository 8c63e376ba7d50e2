"""Helpers of the model tests: read a URDF's joints, world points of a body, broken files."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import ExoCtrlError, InvalidModel
from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES, BodyModel, load_body


def _joint_elements(path: Path) -> dict[str, ET.Element]:
    return {j.get("name"): j for j in ET.parse(path).getroot().findall("joint")}


def _xyz(el: ET.Element | None) -> np.ndarray:
    return np.array([float(v) for v in el.get("xyz").split()])


def _world_points(body: BodyModel, q: np.ndarray) -> tuple[pin.Data, dict[str, np.ndarray]]:
    """World positions of the driven joints and of the cuff and foot frames."""
    data = body.model.createData()
    pin.framesForwardKinematics(body.model, data, body.to_model_q(q))
    pts = {
        n: data.oMi[j].translation.copy() for n, j in zip(JOINT_NAMES, body.joint_ids, strict=True)
    }
    for name in [c + "_cuff" for c in CUFF_NAMES] + ["left_foot", "right_foot"]:
        pts[name] = data.oMf[body.model.getFrameId(name)].translation.copy()
    return data, pts


def _broken(tmp_path: Path, text: str, name: str = "bad.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _check_invalid(path: Path, message: str, **kwargs) -> InvalidModel:
    with pytest.raises(InvalidModel) as info:
        load_body(path, **kwargs)
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, ExoCtrlError)
    assert str(info.value) == message
    return info.value


@pytest.fixture
def joint_elements() -> Callable[[Path], dict[str, ET.Element]]:
    """The ``<joint>`` elements of a URDF file by name."""
    return _joint_elements


@pytest.fixture
def xyz() -> Callable[[ET.Element | None], np.ndarray]:
    """The ``xyz`` attribute of an element as a vector."""
    return _xyz


@pytest.fixture
def world_points() -> Callable[..., tuple[pin.Data, dict[str, np.ndarray]]]:
    """World positions of a body's driven joints, cuff and foot frames at q."""
    return _world_points


@pytest.fixture
def exo_text(exo_path: Path) -> str:
    """The committed exoskeleton URDF's text."""
    return exo_path.read_text(encoding="utf-8")


@pytest.fixture
def broken() -> Callable[..., Path]:
    """Write a (broken) URDF text into a folder; returns its path."""
    return _broken


@pytest.fixture
def check_invalid() -> Callable[..., InvalidModel]:
    """Load a file, expect InvalidModel with exactly ``message``; returns the error."""
    return _check_invalid
