"""The cuff-state observer: δ, δ̇ recovered from forces made by the cuff law; its parameters."""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.control.qp import (
    CuffHorizonModel,
    CuffKnowledge,
    CuffStateObserver,
    QPController,
)
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant.cuffs import CuffParams, CuffSet


def test_observer_recovers_deflection_and_rate_from_the_cuff_law(exo, patient, motor, plan):
    """f = −J (K δ + C δ̇): a force history from a known δ(t) gives δ̂ → δ, δ̂̇ → δ̇."""
    model = CuffHorizonModel(exo, patient, motor)
    cuffs = CuffParams()
    obs = CuffStateObserver(cuffs.stiffness_N_per_m, cuffs.damping_N_s_per_m, 1e-3, 0.0)
    q = plan.q[300]
    model.linearise(q, np.zeros(4))
    jac = model.jac
    for n in range(400):
        t = n * 1e-3
        delta = 2e-3 * np.array([np.sin(8 * t), np.cos(5 * t), np.sin(3 * t), 1.0])
        rate = 2e-3 * np.array([8 * np.cos(8 * t), -5 * np.sin(5 * t), 3 * np.cos(3 * t), 0.0])
        s = cuffs.stiffness_N_per_m * delta + cuffs.damping_N_s_per_m * rate
        force = np.concatenate([-jac[leg] @ s[2 * leg : 2 * leg + 2] for leg in (0, 1)])
        obs.update(model, force.reshape(4, 2), np.zeros(4))
    # Exact up to the zero-order hold of s: δ̂ lags by about h/2, so
    # |δ̂ − δ| ≤ (h/2) max|δ̇| = 0.5e-3 · 2e-3 · 8 = 8e-6 rad and
    # |δ̂̇ − δ̇| ≤ (K/C) · 8e-6 = 6.4e-4 rad/s.
    np.testing.assert_allclose(obs.delta, delta, atol=1e-5, rtol=0)
    np.testing.assert_allclose(obs.ddelta, rate, atol=8e-4, rtol=0)
    np.testing.assert_array_equal(obs.disturbance, 0.0)  # bandwidth 0


def test_observer_recovers_deflection_and_rate_from_the_split_cuff_law(exo, patient, motor, plan):
    """f_c = −𝒦_c J_c δ − 𝒞_c J_c δ̇, 𝒦_c = k_n n nᵀ + k_u u uᵀ (n, u from the plant's
    CuffSet at the state): the observer with the split cuff model recovers δ and δ̇ as
    the isotropic one does from the isotropic law; with the isotropic model it does not."""
    cuffs = CuffParams()  # the truth's: 8000/3700 N/m, 100/70 N·s/m
    model = CuffHorizonModel(exo, patient, motor, cuffs)
    args = (cuffs.stiffness_N_per_m, cuffs.damping_N_s_per_m, 1e-3, 0.0)
    split, iso = CuffStateObserver(*args), CuffStateObserver(*args)
    iso_model = CuffHorizonModel(exo, patient, motor, CuffParams.isotropic())
    q = plan.q[300]
    model.linearise(q, np.zeros(4))
    iso_model.linearise(q, np.zeros(4))
    along, normal = CuffSet(exo, patient, cuffs).directions(np.concatenate((q, q)))
    kn, ku = cuffs.stiffness_N_per_m, cuffs.shear_stiffness_N_per_m
    cn, cu = cuffs.damping_N_s_per_m, cuffs.shear_damping_N_s_per_m
    for n in range(400):
        t = n * 1e-3
        delta = 2e-3 * np.array([np.sin(8 * t), np.cos(5 * t), np.sin(3 * t), 1.0])
        rate = 2e-3 * np.array([8 * np.cos(8 * t), -5 * np.sin(5 * t), 3 * np.cos(3 * t), 0.0])
        force = np.zeros((4, 2))
        for c in range(4):
            leg, k = divmod(c, 2)
            jc = model.jac[leg, 2 * k : 2 * k + 2]
            dp, dv = jc @ delta[2 * leg : 2 * leg + 2], jc @ rate[2 * leg : 2 * leg + 2]
            u, nn = along[c], normal[c]
            force[c] = -(kn * (nn @ dp) + cn * (nn @ dv)) * nn - (ku * (u @ dp) + cu * (u @ dv)) * u
        split.update(model, force, np.zeros(4))
        iso.update(iso_model, force, np.zeros(4))
    # The zero-order hold's lag as in the isotropic test: h/2 · max|δ̇| = 8e-6 rad,
    # δ̂̇ within the fastest rate, (K/C) = 80 1/s, times that.
    np.testing.assert_allclose(split.delta, delta, atol=1e-5, rtol=0)
    np.testing.assert_allclose(split.ddelta, rate, atol=8e-4, rtol=0)
    assert np.abs(iso.delta - delta).max() > 10 * 1e-5  # the isotropic law misreads the cuffs


def test_split_filter_reduces_to_the_isotropic_one(exo, patient, motor, plan):
    """k_u = k_n, C_u = C_n: the matrix filter e^{−hA}, A = G_C⁻¹G_K = (K/C) I, is the
    isotropic a_δ: the same δ̂, δ̂̇ and d̂ to rounding."""
    cuffs = CuffParams.isotropic()
    models = [CuffHorizonModel(exo, patient, motor, cuffs) for _ in range(2)]
    models[1].record["split"] = True  # the split kernels on isotropic parameters,
    models[1].split_switch = True  # compiled in (exo_ctrl._jit.switch)
    observers = [CuffStateObserver(8000.0, 100.0, 1e-3, 30.0) for _ in range(2)]
    rng = np.random.default_rng(2)
    for n in range(200):
        q, dq = plan.q[300 + n], plan.dq[300 + n]
        force = rng.normal(0.0, 40.0, (4, 2))
        for model, obs in zip(models, observers, strict=True):
            model.linearise(q, dq)
            obs.update(model, force, dq)
    iso, split = observers
    for name in ("delta", "ddelta", "disturbance"):
        ref = getattr(iso, name)
        np.testing.assert_allclose(getattr(split, name), ref, rtol=0, atol=1e-9 * np.abs(ref).max())


def test_bad_horizon_and_observer_parameters_are_refused(exo, patient, motor) -> None:
    with pytest.raises(InvalidParameter, match="horizon_ticks must be strictly increasing"):
        CuffHorizonModel(exo, patient, motor, horizon_ticks=(10, 5))
    with pytest.raises(InvalidParameter, match="horizon_ticks"):
        CuffHorizonModel(exo, patient, motor, horizon_ticks=(0, 5))
    with pytest.raises(InvalidParameter, match="dt"):
        CuffHorizonModel(exo, patient, motor, dt=0.0)
    with pytest.raises(InvalidParameter, match="disturbance_bandwidth"):
        CuffStateObserver(8000.0, 100.0, 1e-3, -1.0)
    with pytest.raises(InvalidParameter, match="cuff damping"):
        CuffStateObserver(8000.0, 0.0)


@pytest.mark.parametrize("cuffs", [CuffParams(), CuffParams.isotropic()], ids=["split", "iso"])
def test_the_first_estimate_starts_the_cuffs_at_rest(exo, patient, motor, plan, cuffs) -> None:
    """A run starts standing: the first f̂ = −𝒦 J δ₀ gives δ̂ = δ₀ and δ̂̇ = 0 at once."""
    model = CuffHorizonModel(exo, patient, motor, cuffs)
    obs = CuffStateObserver(cuffs.stiffness_N_per_m, cuffs.damping_N_s_per_m, 1e-3, 0.0)
    model.linearise(plan.q[0], np.zeros(4))
    delta0 = np.array([3e-3, -2e-3, 1e-3, 4e-3])  # [rad]
    force = np.zeros((4, 2))
    for leg in (0, 1):
        j = slice(2 * leg, 2 * leg + 2)
        stiff = model.wk[leg] if model.split else cuffs.stiffness_N_per_m * model.jac[leg]
        force[2 * leg : 2 * leg + 2] = (-stiff @ delta0[j]).reshape(2, 2)
    obs.update(model, force, np.zeros(4))
    np.testing.assert_allclose(obs.delta, delta0, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(obs.ddelta, 0.0, atol=1e-9)


def test_with_cuff_sensors_the_estimates_split_is_held_over_the_horizon(
    exo, patient, motor, plan, on_plan
) -> None:
    """An estimate with a part the joint torques do not see (a leg's cuffs pulling against
    each other): with cuff sensors the prediction carries it at every horizon point; without
    them the prediction is the model's split of the joint-space load alone."""
    k = 300
    probe = CuffHorizonModel(exo, patient, motor, CuffParams())
    probe.linearise(plan.q[k], plan.dq[k])
    internal = np.zeros((4, 2))
    for leg in (0, 1):
        # null(Jᵀ) of the leg: the last two right-singular vectors of Jᵀ (2 × 4).
        _, _, vt = np.linalg.svd(probe.jac[leg].T)
        internal[2 * leg : 2 * leg + 2] = (30.0 * vt[2] + 12.0 * vt[3]).reshape(2, 2)
        np.testing.assert_allclose(
            probe.jac[leg].T @ internal[2 * leg : 2 * leg + 2].ravel(), 0.0, atol=1e-9
        )
    # A load the model itself would split so: its cuffs at rest at δ₀ (f = −W_K δ₀).
    delta0 = np.array([4e-3, -2e-3, 3e-3, 1e-3])  # [rad]
    load = np.concatenate([-probe.wk[leg] @ delta0[2 * leg : 2 * leg + 2] for leg in (0, 1)])
    load = load.reshape(4, 2)
    preds = {}
    for sensors in ("none", "full"):
        ctrl = QPController(
            plan, exo, patient, motor, cuffs=CuffParams(), tighten=False,
            cuff_knowledge=CuffKnowledge(sensors=sensors),
        )  # fmt: skip
        ctrl.command(k, on_plan(plan, k, load + internal))
        preds[sensors] = ctrl.cuff_model.b.reshape(-1, 4, 2).copy()
    held = preds["full"] - preds["none"]
    # The model's split reproduces the load's joint-space part exactly: what is held is the rest.
    np.testing.assert_allclose(held, np.broadcast_to(internal, held.shape), atol=1e-9)
