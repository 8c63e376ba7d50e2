"""The benchmark's peer (tools/mujoco_peer.py) holds the same bodies and cuffs as a run.

The MuJoCo model is written from the run's Pinocchio models; these tests
hold its mass matrix, gravity and passive forces (cuffs and joint damping)
to Pinocchio's and the plant's at postures away from the start.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.sim import SimConfig, build

ROOT = Path(__file__).resolve().parents[1]
#: Postures [exo (4), patient (4)] [rad]: the patient within 10 mrad of the device.
POSTURES = [
    np.array([0.3, 0.8, -0.2, 0.4, 0.31, 0.8, -0.2, 0.4]),
    np.array([-0.1, 0.2, 0.6, 1.3, -0.1, 0.21, 0.595, 1.3]),
]


@pytest.fixture(scope="module")
def peer():
    spec = importlib.util.spec_from_file_location("mujoco_peer", ROOT / "tools" / "mujoco_peer.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def setup():
    return build(SimConfig(duration_s=0.5))


@pytest.mark.parametrize("q", POSTURES)
def test_the_peers_mass_matrix_is_pinocchios(peer, setup, q) -> None:
    ours, theirs = peer.mass_matrix_pair(setup, q)
    np.testing.assert_allclose(theirs, ours, rtol=0.0, atol=1e-10)


@pytest.mark.parametrize("q", POSTURES)
def test_the_peers_gravity_is_pinocchios(peer, setup, q) -> None:
    p = peer.Peer(setup)
    order = p.at(q)
    model = setup.plant.model
    gravity = pin.computeGeneralizedGravity(model, model.createData(), q)
    np.testing.assert_allclose(p.data.qfrc_bias[order], gravity, rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("q", POSTURES)
def test_the_peers_cuffs_are_the_plants(peer, setup, q) -> None:
    """The two tendons of a cuff give the split spring's force to first order in the stretch.

    At rest in speed the difference is the tendons' geometry, T/L of the force
    across them (< 1 % at these millimetre stretches); in motion at the
    start's posture the dampers alone, exact.
    """
    ours, theirs = peer.passive_pair(setup, q, np.zeros(8))
    assert np.abs(ours).max() > 10.0  # the cuffs are stretched
    np.testing.assert_allclose(theirs, ours, rtol=0.01, atol=0.05)
    v = np.array([0.5, -0.3, 0.2, 0.1, 0.4, -0.2, 0.3, 0.0])
    start = np.concatenate((q[:4], q[:4]))  # the frames coincide: no spring
    ours, theirs = peer.passive_pair(setup, start, v)
    np.testing.assert_allclose(theirs, ours, rtol=1e-9, atol=1e-9)
