"""Torque-sensor bias: the bound of its effect, its effect on a live run, its detection."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exo_ctrl.estimation import (
    bias_effect_bound,
    cuff_forces_from_torque,
    estimate_bias,
    estimate_series,
    normal_component_errors,
)
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant.cuffs import CuffParams
from exo_ctrl.sensing.sensors import SensorParams

DT = 1e-3
SKIP_S = 0.05
SKIP = round(SKIP_S / DT)


def test_bias_effect_bound_numbers(exo) -> None:
    bound = bias_effect_bound([1.0, 0.0, 0.0, 1.0], exo)
    # Thigh: |β_hip| / a; shank: |β_knee| / c (a = 0.39 m, c = 0.45 m, l1 = 0.52 m).
    assert bound == pytest.approx([1 / 0.39, 0.0, (0.97 / 0.45) / 0.39, 1 / 0.45])


def test_torque_bias_shifts_the_estimate_by_its_bounded_effect(
    ideal_run, closed_loop, show
) -> None:
    """A live run with biased (otherwise ideal) torque sensors against the unbiased one."""
    beta = np.array([1.0, -0.8, 0.5, 0.6])
    biased = closed_loop(dataclasses.replace(SensorParams.ideal(), torque_bias_Nm=tuple(beta)))
    assert np.allclose(biased.tau - ideal_run.tau, beta, atol=1e-9)
    shift = (biased.normal - ideal_run.normal)[300:]  # after 30 observer time constants
    # r → τ_ext − β: the estimate moves by the forces that explain −β.
    exact = cuff_forces_from_torque(biased.q[300:], np.broadcast_to(-beta, (shift.shape[0], 4)))[0]
    bound = bias_effect_bound(beta, biased.exo)
    show("\nbias (1.0, -0.8, 0.5, 0.6) N·m: max |shift of the estimate|", np.abs(shift).max(0), "N")
    show("bound", bound, "N")
    assert np.allclose(shift, exact, atol=1e-6)
    assert np.all(np.abs(shift).max(0) <= bound + 1e-9)
    # The shank's effect is exactly |β_knee| / c.
    assert np.allclose(np.abs(shift[:, 1::2]), np.abs(beta[1::2]) / 0.45, atol=1e-6)


def test_bias_is_detected_from_a_zero_interaction_run_and_removed(
    closed_loop, show, check_accuracy
) -> None:
    """Walk with the straps open (cuffs of negligible stiffness): the mean of r is the bias."""
    beta = (1.0, -0.8, 0.5, 0.6)
    open_straps = CuffParams.isotropic(1e-9, 0.0)
    calib = closed_loop(SensorParams(torque_bias_Nm=beta), cuffs=open_straps)
    found = estimate_bias(calib.tau_ext[100:], calib.exo)
    print("\nzero-interaction run with default sensors and a bias:\n" + found.report())
    assert np.all(found.detected)
    assert np.allclose(found.bias_Nm, beta, atol=0.05)
    clean = closed_loop(SensorParams(seed=1), cuffs=open_straps)
    none = estimate_bias(clean.tau_ext[100:], clean.exo)
    print("same without a bias:\n" + none.report())
    assert not np.any(none.detected)
    # Strapped run with the same biased sensors: uncorrected vs corrected.
    strapped = closed_loop(SensorParams(torque_bias_Nm=beta))
    raw_biased, _ = check_accuracy(strapped, "biased sensors, uncorrected")
    fixed = estimate_series(
        strapped.t,
        strapped.q,
        strapped.dq,
        strapped.tau,
        strapped.exo,
        dt=DT,
        torque_bias_Nm=found.bias_Nm,
    )
    errors = normal_component_errors(
        strapped.q_true, strapped.force_true, fixed.normal, strapped.exo, skip=SKIP
    )
    show("  corrected with the estimated bias: RMS error raw", errors.rms_error_rel)
    assert np.all(errors.rms_error_rel < 0.05)
    # The uncorrected bias was visible (shanks: |β_knee| / c ≈ 1.3–1.8 N constant offset).
    assert np.max(raw_biased) > 0.05
    assert np.all(raw_biased[1::2] > errors.rms_error_rel[1::2] + 0.005)


def test_short_window_is_refused(exo) -> None:
    with pytest.raises(InvalidParameter, match=r"tau_ext must be shape \(N, 4\) with N >= 10"):
        estimate_bias(np.zeros((5, 4)), exo)
