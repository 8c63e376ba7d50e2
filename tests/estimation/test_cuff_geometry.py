"""Cuff geometry, cuff-force components and the torque ↔ force map, against Pinocchio.

The closed-loop runs (``ideal_run``) and the Pinocchio reference J_eᵀ f
(``true_tau_ext``) are fixtures of tests/estimation/conftest.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.estimation import (
    CuffGeometry,
    cuff_components,
    cuff_forces_from_torque,
    cuff_normal_components,
)
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import CUFF_NAMES


def test_cuff_components_signs_on_hanging_links(exo) -> None:
    """Links hanging straight down: n = +x (forward), u = −z (down), for every cuff."""
    q = np.zeros(4)
    forward = np.tile([10.0, 0.0], (4, 1))
    up = np.tile([0.0, 10.0], (4, 1))
    assert np.allclose(cuff_normal_components(q, forward, exo), 10.0)
    normal, along = cuff_components(q, up, exo)
    assert np.allclose(normal, 0.0, atol=1e-12) and np.allclose(along, -10.0)
    # A forward push on the thigh cuff flexes the hip (s_h = +1), on the shank
    # cuff it extends the knee (s_k = −1): τ = A f⊥.
    a = CuffGeometry.from_body(exo).torque_per_normal_force(q, stiffness_ratio=0.0)
    assert a[0, 0, 0] == pytest.approx(0.39) and a[0, 1, 1] == pytest.approx(-0.45)


def test_normal_components_reproduce_the_external_torque(ideal_run, true_tau_ext) -> None:
    """What the torques see: normal parts exactly, the thigh's along part not at all."""
    run = ideal_run
    exo = run.exo
    q = run.q_true[::10]
    force = run.force_true[::10]
    g = CuffGeometry.from_body(exo)
    normal, along = cuff_components(q, force, exo)
    # 1. Forces with their along-link parts removed: J_eᵀ (f⊥ n) is solved
    #    back to f⊥ exactly (κ = 0, the normal-only map).
    f_perp = normal[..., None] * g.normals(q)
    tau = true_tau_ext(exo, q, f_perp)
    back, back_force = cuff_forces_from_torque(q, tau, exo, stiffness_ratio=0.0)
    assert np.allclose(back, normal, rtol=0, atol=1e-9)
    assert np.allclose(back_force, f_perp, rtol=0, atol=1e-9)
    # 2. A force along the thigh (hip → cuff) gives no joint torque at all.
    f_thigh = np.zeros_like(force)
    f_thigh[:, 0::2] = 50.0 * g.alongs(q)[:, 0::2]
    assert np.allclose(true_tau_ext(exo, q, f_thigh), 0.0, atol=1e-10)
    # 3. The coaxial structure (f_t = F1 a n_t, f_s = F1 l1 n_k + F2 c n_s) is recovered
    #    in full with κ = 1, including the shank's along component.
    rng = np.random.default_rng(3)
    big_f = rng.normal(0.0, 100.0, size=(q.shape[0], 2, 2))  # (F1, F2) per leg
    _, psi_k, _ = g.directions(q)
    n_k = np.stack((-np.sin(psi_k), np.cos(psi_k)), axis=-1)  # (N, 2 legs, 2)
    nrm = g.normals(q)
    coax = np.zeros_like(force)
    coax[:, 0::2] = big_f[..., :1] * g.thigh_arm[:, None] * nrm[:, 0::2]
    coax[:, 1::2] = (
        big_f[..., :1] * g.knee_arm[:, None] * n_k
        + big_f[..., 1:] * g.shank_arm[:, None] * nrm[:, 1::2]
    )
    got_n, got_f = cuff_forces_from_torque(q, true_tau_ext(exo, q, coax), exo, stiffness_ratio=1.0)
    assert np.allclose(got_f, coax, rtol=0, atol=1e-8)
    assert np.allclose(got_n, cuff_normal_components(q, coax, exo), rtol=0, atol=1e-8)
    # 4. The true forces of the default run: how big the invisible parts are.
    peak_n = np.max(np.abs(normal), axis=0)
    peak_a = np.max(np.abs(along), axis=0)
    print("\ndefault run, peak |along-link component| / peak |normal component|:")
    for c, name in enumerate(CUFF_NAMES):
        print(f"  {name}: {peak_a[c]:.1f} N / {peak_n[c]:.1f} N = {peak_a[c] / peak_n[c]:.2f}")
    assert np.all(peak_a[0::2] < 0.02 * peak_n[0::2])  # thighs: ~1 %, invisible anyway
    assert np.all(peak_a[1::2] > 1.5 * peak_n[1::2])  # shanks: large, hence κ = 1


def test_live_mapping_equals_the_vectorised_one(ideal_run) -> None:
    run = ideal_run
    normal, force = cuff_forces_from_torque(run.q, run.tau_ext, run.exo)
    assert np.allclose(normal, run.normal, rtol=0, atol=1e-10)
    assert np.allclose(force, run.force, rtol=0, atol=1e-10)


def test_bad_shapes_are_refused(exo) -> None:
    with pytest.raises(InvalidParameter, match="shapes"):
        cuff_normal_components(np.zeros(4), np.zeros((4, 3)), exo)
