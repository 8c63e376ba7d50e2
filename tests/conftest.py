"""Shared fixtures: the default bodies, drive and gait plan, the human patient, other lengths."""

from __future__ import annotations

import importlib.util
import os
import sys
import textwrap
from pathlib import Path

# Under pytest-xdist (the suite's default, pyproject.toml) each worker keeps its
# own numba cache, set before numba is imported: two processes compiling two
# signatures of one kernel at once can cross numba's cache index
# (exo_ctrl/sim/warmup.py), and the workers run tests of different feature sets
# side by side.  ``.pytest_cache/numba/<worker>`` (or ``$NUMBA_CACHE_DIR/<worker>``),
# refreshed on source changes as the package's own (exo_ctrl/_jit_cache.py).
_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
if _WORKER:
    _CACHE = os.environ.get("NUMBA_CACHE_DIR") or Path(__file__).resolve().parents[1] / (
        ".pytest_cache/numba"
    )
    os.environ["NUMBA_CACHE_DIR"] = str(Path(_CACHE) / _WORKER)

import numpy as np
import pytest

from exo_ctrl.model import BodyModel, default_urdf_path, load_body, load_human_patient
from exo_ctrl.model.urdfgen import BodyParams, write_urdf
from exo_ctrl.plan.gait import GaitParams, GaitPlan
from exo_ctrl.plan.kinematics import JointTrajectory, plan_joints
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.plant.drive import MotorParams
from exo_ctrl.sim import SimConfig, drive_for

# The fault campaign (tools/faults.py), importable by the tests as ``fault_campaign``
# (its dataclasses look their module up by that name).
_spec = importlib.util.spec_from_file_location(
    "fault_campaign", Path(__file__).resolve().parents[1] / "tools" / "faults.py"
)
_campaign = importlib.util.module_from_spec(_spec)
sys.modules["fault_campaign"] = _campaign
_spec.loader.exec_module(_campaign)

#: Thigh and shank of the "other lengths" exoskeleton [m].
SHORT_THIGH = 0.45
SHORT_SHANK = 0.40


def short_exo_params() -> BodyParams:
    """Exoskeleton with a 0.45 m thigh and a 0.40 m shank.

    The default shank cuff sits 0.45 m below the knee, which does not fit on a
    0.40 m shank (BodyParams refuses it), so the cuff is moved to 0.35 m.
    """
    return BodyParams.exo_default(
        thigh_length=SHORT_THIGH, shank_length=SHORT_SHANK, shank_cuff=0.35
    )


@pytest.fixture(scope="session")
def exo_path() -> Path:
    """Path of the committed default exoskeleton URDF."""
    return default_urdf_path("exo")


@pytest.fixture(scope="session")
def exo(exo_path: Path) -> BodyModel:
    """The default exoskeleton (paper Table I: 0.52 m links)."""
    return load_body(exo_path, name="exoskeleton")


@pytest.fixture(scope="session")
def patient() -> BodyModel:
    """The default patient (modules may define their own)."""
    return load_body(default_urdf_path("patient"), name="patient")


@pytest.fixture(scope="session")
def motor(exo: BodyModel) -> MotorParams:
    """The default drive, configured for the default exoskeleton (modules may define their own)."""
    return drive_for(MotorParams(), exo)


@pytest.fixture(scope="session")
def plan(exo: BodyModel) -> JointTrajectory:
    """The default gait's joint targets over 1.2 s at 1 kHz (modules may define their own)."""
    return plan_joints(GaitPlan(GaitParams()), exo, np.arange(1201) * 1e-3)


@pytest.fixture(scope="session")
def short_exo_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A URDF of an exoskeleton with a 0.45 m thigh and a 0.40 m shank."""
    return write_urdf(short_exo_params(), tmp_path_factory.mktemp("short_exo") / "x.urdf")


@pytest.fixture(scope="session")
def short_exo(short_exo_path: Path) -> BodyModel:
    """The 0.45 m / 0.40 m exoskeleton, loaded."""
    return load_body(short_exo_path, name="exoskeleton")


@pytest.fixture(scope="session")
def human() -> BodyModel:
    """example-robot-data's human model as a patient."""
    return load_human_patient()


@pytest.fixture(scope="session")
def supported_qp() -> SimConfig:
    """The QP at a 300 N bound on the belt, the pelvis supported at 40 % (the departure stop's)."""
    return SimConfig(
        controller="qp",
        cuff_force_limit_N=300.0,
        contact=ContactParams(enabled=True),
        pelvis=PelvisParams(supported=True, bws_fraction=0.4),
    )


@pytest.fixture
def write_short_urdf():
    """Helper writing the 0.45 m / 0.40 m exoskeleton URDF to a given path."""

    def write(path: Path) -> Path:
        return write_urdf(short_exo_params(), path)

    return write


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The tests marked ``heavy`` first (in their order), the rest after, in theirs.

    pytest-xdist's workers take tests in order; a long test (a cold compile, a
    process pool, a cluster) that starts last keeps one worker busy while the
    others have nothing left to do.
    """
    items.sort(key=lambda item: item.get_closest_marker("heavy") is None)


@pytest.fixture
def user_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """Write a user's module into ``tmp_path``: ``write(prefix, source)`` returns its name.

    The name is unique to the test and importable (``tmp_path`` on ``sys.path``);
    the module is dropped from ``sys.modules`` after the test.
    """
    names: list[str] = []

    def write(prefix: str, source: str) -> str:
        name = f"{prefix}_{tmp_path.name.replace('-', '_')}"
        (tmp_path / f"{name}.py").write_text(textwrap.dedent(source))
        monkeypatch.setattr(sys, "path", [str(tmp_path), *sys.path])
        names.append(name)
        return name

    yield write
    for name in names:
        sys.modules.pop(name, None)
