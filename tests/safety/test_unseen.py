"""The along-shank force the device cannot see (exo_ctrl/safety/unseen.py).

The reach ‖Aᵀu‖ against A built from explicit rotation matrices and its along part maximised
over every direction of the knee offset; the widening moves only the shanks' along components,
by exactly unseen_N ‖Aᵀu‖, and nothing at the fit posture.  The closed loop: on clinic-spastic
with the knee 2 cm back and up, the true shank force passes ISO's 130 N unseen; the supervisor
on the widened estimate stops the run with every true force within the limit.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exo_ctrl import simulate
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import load_exo, load_patient
from exo_ctrl.plant import CuffParams, CuffSet
from exo_ctrl.plant.misalignment import Misalignment
from exo_ctrl.safety import ISO_TS_15066_CUFF_FORCE_N
from exo_ctrl.safety.unseen import AlongWidening, along_reach_into
from exo_ctrl.scenario import preset

SHANK = ISO_TS_15066_CUFF_FORCE_N[1]


@pytest.fixture(scope="module")
def cuffs() -> CuffSet:
    return CuffSet(load_exo(), load_patient(None), CuffParams())


def _rot(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


def test_the_reach_is_the_largest_along_stretch_over_every_offset_direction(cuffs) -> None:
    rng = np.random.default_rng(3)
    select, along0 = cuffs.select[:4, :4], cuffs.along0
    directions = np.linspace(0.0, 2.0 * np.pi, 7200, endpoint=False)
    unit = np.stack((np.cos(directions), np.sin(directions)))  # (2, n): every d with |d| = 1
    for _ in range(20):
        q, q_fit = rng.uniform(-1.0, 1.5, 4), rng.uniform(-0.5, 1.0, 4)
        out = np.empty(2)
        along_reach_into(select, along0, q, q_fit, out)
        theta, theta0 = select @ q, select @ q_fit
        for leg in range(2):
            t, s = 2 * leg, 2 * leg + 1
            a = _rot(theta[s]) - _rot(theta[t]) - _rot(theta0[s]) + _rot(theta0[t])
            u = _rot(theta[s]) @ along0[s]
            assert out[leg] == pytest.approx(np.abs(u @ a @ unit).max(), rel=1e-6, abs=1e-9)


def test_only_the_shanks_along_components_widen(cuffs) -> None:
    rng = np.random.default_rng(4)
    widening = AlongWidening(cuffs.select, cuffs.along0, 80.0)
    q_fit = np.array([0.28, 0.56, 0.28, 0.56])
    force = rng.normal(0.0, 60.0, (4, 2))
    np.testing.assert_array_equal(widening(force, q_fit), force)  # the fit: nothing to add
    q = np.array([0.1, 1.1, 0.5, 0.2])
    out = widening(force, q)
    np.testing.assert_array_equal(out[0::2], force[0::2])
    theta = cuffs.select[:4, :4] @ q
    for leg, s in enumerate((1, 3)):
        u = _rot(theta[s]) @ cuffs.along0[s]
        u /= np.linalg.norm(u)
        n = np.array([-u[1], u[0]])
        assert n @ out[s] == pytest.approx(n @ force[s], abs=1e-9)
        grown = abs(u @ out[s]) - abs(u @ force[s])
        assert grown == pytest.approx(80.0 * widening.reach[leg], rel=1e-12)
        assert np.sign(u @ out[s]) == np.sign(u @ force[s])


def _misaligned(widen: bool):
    base = preset("clinic-spastic").config
    return dataclasses.replace(
        base, misalignment=Misalignment(knee_xz=(-0.02, 0.02)), safety_widen=widen
    )


def test_the_widened_estimate_keeps_the_limit_the_estimate_misses() -> None:
    """clinic-spastic, the knee 2 cm back and 2 cm up: on the estimate the run walks with a
    true shank force past 130 N; on the widened estimate it stops first, every true shank force
    within 130 N (the sentence before the run said it would stop)."""
    walked = simulate(_misaligned(False))
    assert walked.safety_state == "normal"
    peak = np.linalg.norm(walked.cuff_force, axis=2)[:, 1::2].max()
    assert peak > SHANK
    stopped = simulate(_misaligned(True))
    cause = next(e for e in stopped.events if e["kind"] == "violation")
    assert cause["quantity"].startswith("widened cuff force estimate")
    assert "shank" in cause["quantity"]
    assert np.linalg.norm(stopped.cuff_force, axis=2)[:, 1::2].max() <= SHANK
    assert any("will likely stop the run" in w for w in stopped.warnings)


@pytest.mark.parametrize(
    "change",
    [{"controller": "qp"}, {"safety": False}, {"safety_use_estimate": False}],
)
def test_widening_needs_a_supervisor_on_the_estimate_and_not_the_qp(change) -> None:
    with pytest.raises(InvalidParameter) as info:
        dataclasses.replace(_misaligned(True), **change)
    assert str(info.value) == (
        "safety_widen must be with the safety supervisor on, watching the estimated cuff "
        "forces, and a controller other than the QP (which tightens its own bound); got True"
    )
