"""The release bound of a pushed hold (exo_ctrl/safety/release.py).

- Λ_c, the reduced inertia at each cuff, against an independent computation:
  the articulated-body algorithm's response of each free body (gravity off,
  the drives' rotor inertia as the exoskeleton's armature) to the cuff's
  force and its reaction: Λ_c (a_e − a_p) = f.
- The energy bound on a two-mass spring integrated in time: released with
  the cuff at F₀ and the limb closing at v, the force peaks at
  √(F₀² + k m v²), m the reduced mass.
- What the supervisor gets from it per tick: the first reading of a hold
  has no rate, a loading cuff adds ḟᵀ Λ ḟ / k, an unloading one nothing, a
  new hold posture starts over; a bad stiffness is refused by name (also by
  the supervisor, which passes its ``cuff_stiffness`` on).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.safety import SafetyLimits, SafetySupervisor
from exo_ctrl.safety.release import ReleaseBound
from exo_ctrl.sim import SimConfig, build

DT = 1e-3
#: A hold posture of tests/safety/test_hold_pushed.py [rad] (hips flexed, knees bent).
Q_HOLD = np.array([0.70, 1.00, 0.35, 1.00])


@pytest.fixture(scope="module")
def setup():
    return build(SimConfig())


def _cuff_acceleration(body, armature: float, c: int, force: np.ndarray) -> np.ndarray:
    """x–z acceleration of cuff c of a body at rest under the force [N] at it (ABA, no gravity)."""
    model = pin.Model(body.model)
    model.gravity = pin.Motion.Zero()
    model.armature[body.q_index] += armature
    data = model.createData()
    q = pin.neutral(model)
    q[body.q_index] = Q_HOLD
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    jac = pin.getFrameJacobian(model, data, body.cuff_frame_ids[c], pin.LOCAL_WORLD_ALIGNED)
    jac = jac[[0, 2]]
    ddq = pin.aba(model, data, q, np.zeros(model.nv), jac.T @ force)
    return jac @ ddq  # at rest: no J̇ q̇ term


def test_the_reduced_inertia_is_the_two_bodies_response_to_the_cuff_force(setup) -> None:
    exo, patient, motor = setup.device_exo, setup.device_patient, setup.device_motor
    bound = ReleaseBound(exo, patient, motor, DT)
    bound.start(Q_HOLD)
    arm = motor.reflected_inertia_kgm2
    for c in range(4):
        # A thigh cuff moves only across its link: the force along Λ's one axis.
        axis = np.linalg.eigh(bound.inertia[c])[1][:, -1]
        force = 100.0 * (axis if c % 2 == 0 else np.array([math.cos(0.4), math.sin(0.4)]))
        a_rel = _cuff_acceleration(exo, arm, c, force) - _cuff_acceleration(patient, 0.0, c, -force)
        np.testing.assert_allclose(bound.inertia[c] @ a_rel, force, atol=1e-6)
    eig = np.array([np.linalg.eigvalsh(bound.inertia[c]) for c in range(4)])
    print(f"\nΛ eigenvalues per cuff [kg]: {np.round(eig, 2).tolist()}")
    assert np.all(eig[0::2, 0] < 1e-9) and np.all(eig[1::2, 0] > 0.5)  # thigh: one axis


def test_the_energy_bound_is_the_peak_of_a_released_two_mass_spring() -> None:
    k, m_e, m_p, f0, v = 8000.0, 5.0, 2.5, 100.0, 0.4  # N/m, kg, kg, N, m/s
    m = m_e * m_p / (m_e + m_p)
    x, xd, h, peak = f0 / k, v, 1e-6, 0.0  # compression, its rate, step [s]
    for _ in range(60_000):  # 60 ms, beyond a quarter period (π/2 √(m/k) = 27 ms)
        xd -= h * k * x / m
        x += h * xd
        peak = max(peak, k * x)
    expected = math.sqrt(f0**2 + k * m * v**2)
    print(f"\ntwo-mass spring: peak {peak:.2f} N, bound {expected:.2f} N")
    assert math.isclose(peak, expected, rel_tol=1e-4)


def test_per_tick_the_rate_of_a_loading_cuff_adds_its_energy(setup) -> None:
    bound = ReleaseBound(setup.device_exo, setup.device_patient, setup.device_motor, DT)
    f = np.zeros((4, 2))
    f[1] = (-60.0, 35.0)
    first = bound.peak_squared(f, Q_HOLD)
    np.testing.assert_allclose(first, np.sum(f * f, axis=1))  # no predecessor: no rate
    rate = np.array([-1.3e3, 4.6e3])  # N/s, loading (f · ḟ > 0)
    g = f.copy()
    g[1] += rate * DT
    peak = bound.peak_squared(g, Q_HOLD)
    expected = g[1] @ g[1] + rate @ bound.inertia[1] @ rate / 8000.0
    assert math.isclose(peak[1], expected, rel_tol=1e-9)
    # (about the trigger of tests/safety/test_hold_pushed.py: 70 N rising at 4.8 N/ms)
    print(f"\nshank at {np.linalg.norm(g[1]):.1f} N rising 4.8 N/ms: release peak ", end="")
    print(f"{math.sqrt(peak[1]):.1f} N")
    unloading = bound.peak_squared(f, Q_HOLD)  # back down: the hold's own sway
    np.testing.assert_allclose(unloading, np.sum(f * f, axis=1))
    moved = bound.peak_squared(g, Q_HOLD + 0.1)  # a new hold starts over
    np.testing.assert_allclose(moved, np.sum(g * g, axis=1))


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, "8000", True])
def test_a_bad_cuff_stiffness_is_refused_by_name(setup, bad) -> None:
    models = (setup.device_exo, setup.device_patient, setup.device_motor)
    with pytest.raises(InvalidParameter, match="cuff_stiffness"):
        ReleaseBound(*models, DT, bad)
    with pytest.raises(InvalidParameter, match="cuff_stiffness"):
        SafetySupervisor(SafetyLimits(), *models, DT, cuff_stiffness=bad)
