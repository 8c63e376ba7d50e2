"""The Kalman filter fused with instrumented cuffs (exo_ctrl/estimation/kalman_cuff.py).

On the default scenario (CT, the device holding the published split cuffs,
the patient's cuffs scattered around them, 3.6 s), the errors per cuff after
the ramp-in, RMS error over RMS true value, with the sensors' noise, offset
(σ_b = 1 N, drawn per run) and drift on in every run, over three of the
sensors' seeds.  The goals the issue states (issue 31): with ``full`` cuff
sensors, the full vector within 5 % of its RMS; and sensors never worse
than none on the normal components.  ``full`` meets both without the tare
(the default): the filter estimates each sensor's bias (offset and drift)
as a state of its own, told from the cuff model's error by the joint
torques' check (exo_ctrl/estimation/kalman_check.py) over the gait's
changing posture, and by the model's force where no joint torque sees the
component.  ``normal`` load cells leave the thighs' normal offset in the
estimate (the hip sees the shank's along force too, which they do not
read): they hold the goal on the normal components with the tare, and
without it are no worse than before the bias states.
"""

from __future__ import annotations

from functools import cache
from typing import Any
from unittest import mock

import numba
import numpy as np
import pytest
from numba.core import types

from exo_ctrl.estimation import CuffForceKalman
from exo_ctrl.estimation.kalman_step import kalman_step
from exo_ctrl.sensing import CuffSensorParams, CuffSensors
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.setup import build
from exo_ctrl.sim.tick import Runner

#: The issue's goal for the full vector with ``full`` sensors.
GOAL = 0.05

#: The sensors' seeds the goals are held on (3: the default).
SEEDS = (3, 0, 1)

#: The goal on the normal components with the joint torque sensors alone (thighs 10 %, shanks
#: 5 %, issue 31), which load cells without the tare must keep, per cuff (CUFF_NAMES) [-].
NORMAL_GOAL = np.array([0.10, 0.05, 0.10, 0.05])

#: The bound on the estimated bias's error per measured axis at the run's end [N], ``full``,
#: no tare: σ_b, the offset's own spread (0.9 N measured, a thigh's normal: the hip's split).
BIAS_BOUND_N = 1.0

#: The bound on the bias's RMS error over the eight axes [N]: half σ_b.
BIAS_RMS_BOUND_N = 0.5

#: The bound on the bias's error on the shanks' normal axes [N]: the knee torque sees that
#: component alone (0.35 N measured).
BIAS_KNEE_BOUND_N = 0.5

#: The bound on the tare's error per measured axis [N]: the device's model of the
#: standing forces (the hip torque's split between the thigh's normal and the
#: shank's along force comes from the cuff model; 0.9 N measured).
TARE_BOUND_N = 1.0

#: The bound on the tare's error on the axes the device's standing model gets right
#: [N]: the shank's normal (the knee torque sees it) and the thigh's along force.
TARE_OBSERVED_BOUND_N = 0.1


#: A bound on σ_c over the tare and the first fused samples [N] (2.0 N measured): the
#: model-error force's prior, set at the first fused sample, is gone after it.
SIGMA_BOUND_N = 5.0


class _Kept(Runner):
    """The run's Runner, kept for the test to read its filter's and sensors' records."""

    last: Runner | None = None

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        _Kept.last = self


@cache
def _run(mode: str, seed: int = 3, tare_s: float = 0.0) -> tuple[dict, np.ndarray, np.ndarray]:
    """The run's summary, and at its end the filter's record and the sensors' (the truth)."""
    params = CuffSensorParams(mode=mode, seed=seed, tare_s=tare_s)
    with mock.patch("exo_ctrl.sim.loop.Runner", _Kept):
        summary = simulate(SimConfig(controller="ct", cuff_sensors=params)).summary()
    runner = _Kept.last
    return summary, runner.estimator.record.copy(), runner.cuff_sensors.record.copy()


def _errors(mode: str, seed: int = 3, tare_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Per cuff, the full vector's and the normal's RMS error over RMS, after the ramp-in."""
    summary = _run(mode, seed, tare_s)[0]
    full = np.array(list(summary["cuff_force_estimate_rms_error_rel"].values()))
    normal = np.array(list(summary["cuff_force_estimate_normal_rms_error_over_rms"].values()))
    print(f"\n{mode} seed {seed} tare {tare_s} s: full vector {np.round(100 * full, 2)} %, "
          f"normal {np.round(100 * normal, 2)} %")  # fmt: skip
    return full, normal


@pytest.mark.parametrize("seed", SEEDS)
def test_full_sensors_hold_the_full_vector_within_5_percent_without_the_tare(seed: int) -> None:
    full, _ = _errors("full", seed)
    assert np.all(full < GOAL), f"full-vector error {np.round(100 * full, 2)} % over the 5 % goal"
    assert np.all(full < _errors("none")[0])  # and below the joint torques' alone


@pytest.mark.parametrize(("mode", "tare_s"), [("normal", 0.3), ("full", 0.0), ("full", 0.3)])
@pytest.mark.parametrize("seed", SEEDS)
def test_sensors_are_never_worse_than_none_on_the_normal_components(
    mode: str, tare_s: float, seed: int
) -> None:
    _, normal = _errors(mode, seed, tare_s)
    _, none = _errors("none")
    assert np.all(normal <= none), f"normal {np.round(100 * normal, 2)} % against none's"


@pytest.mark.parametrize("seed", SEEDS)
def test_normal_cells_without_the_tare_hold_the_normal_goal_and_beat_the_torques_on_the_shanks(
    seed: int,
) -> None:
    """The knee's check finds the shank cells' offsets; the thighs' stays (module docstring)."""
    _, normal = _errors("normal", seed)
    assert np.all(normal < NORMAL_GOAL), f"normal components {np.round(100 * normal, 2)} %"
    _, none = _errors("none")
    assert np.all(normal[[1, 3]] < none[[1, 3]])


@pytest.mark.parametrize("seed", SEEDS)
def test_the_estimated_bias_converges_to_the_sensors_offset(seed: int) -> None:
    """``full``, no tare: at the run's end β is each sensor's offset plus drift, within bounds.

    The filter never reads the truth: it is the sensors' record, read here after the run.
    """
    _, rec, truth = _run("full", seed)
    true = truth["offset"][0] + truth["drift"][0]
    error = rec["sensor_bias"][0] - true
    print(f"\nseed {seed}: bias [N] {np.round(rec['sensor_bias'][0], 2).tolist()}, "
          f"true {np.round(true, 2).tolist()}, error {np.round(error, 2).tolist()}")  # fmt: skip
    assert np.all(np.abs(error) < BIAS_BOUND_N)
    assert np.all(np.abs(error[[1, 3], 0]) < BIAS_KNEE_BOUND_N)  # the shanks' normal
    # over the eight axes, within half the offset's own spread (0.40 N measured, seed 1)
    assert np.sqrt(np.mean(error**2)) < BIAS_RMS_BOUND_N


@pytest.mark.parametrize("seed", SEEDS)
def test_the_tare_finds_the_drawn_offsets(seed: int) -> None:
    """After the tare's window the filter's offset is the drawn one, within the stated bounds."""
    params = CuffSensorParams(mode="full", seed=seed, tare_s=0.3)
    runner = Runner(build(SimConfig(controller="ct", cuff_sensors=params)))
    std = np.zeros((400, 4))
    for k in range(400):  # the filter's settling (50 ms) and the 0.3 s tare, at 1 kHz
        runner.tick(k, k % runner.chunk)
        std[k] = runner.estimator.force_std
    rec = runner.estimator.record
    # σ_c never carries the model-error force's 30 N prior: the margins stay the torques' own
    print(f"\nσ_c from 50 ms [N]: {np.round(std[50:].max(axis=0), 2).tolist()}")
    assert np.all(std[50:] < SIGMA_BOUND_N)
    error = rec["offset"][0] - runner.cuff_sensors.record["offset"][0]
    print(f"\nseed {seed}: tare error [N] {np.round(error, 2).tolist()}")
    assert np.all(rec["tare_n"][0] == 150)  # 0.3 s at 500 Hz, per axis
    assert np.all(np.abs(error) < TARE_BOUND_N)
    assert np.all(np.abs(error[[1, 3], 0]) < TARE_OBSERVED_BOUND_N)  # shanks' normal
    assert np.all(np.abs(error[[0, 2], 1]) < TARE_OBSERVED_BOUND_N)  # thighs' along


def _callees(kernel: Any, *args: Any) -> set[str]:
    """The kernels ``kernel`` calls, compiled afresh for ``args``' types (as test_jit_switches)."""
    fresh = numba.njit(cache=False, error_model="numpy")(kernel.py_func)
    fresh.compile(tuple(numba.typeof(a) for a in args))
    typed = next(iter(fresh.overloads.values())).type_annotation
    found = set()
    for expr in typed.calltypes:
        if getattr(expr, "op", None) == "call":
            func = typed.typemap[expr.func.name]
            if isinstance(func, types.Dispatcher):
                found.add(func.dispatcher.py_func.__name__)
    return found


@pytest.mark.heavy
def test_the_fusion_is_compiled_in_only_with_cuff_sensors(exo, patient) -> None:
    kf = CuffForceKalman(exo, patient, 1e-3)
    sensors = CuffSensors(CuffSensorParams(mode="full"), 1e-3)
    m, x = np.zeros((4, 4)), np.zeros(4)
    args = (kf.record, kf.cuffs.record, m, x, m, x, x, x, kf.cuffs.split_switch)
    fusion = {"cuff_sensor_update", "add_model_error"}
    assert not fusion & _callees(kalman_step, *args, None)
    assert fusion <= _callees(kalman_step, *args, sensors.readings)
    assert CuffForceKalman(exo, patient, 1e-3, cuff_sensors=sensors).cuff_meas is sensors.readings
    off = CuffSensors(CuffSensorParams(), 1e-3)
    assert CuffForceKalman(exo, patient, 1e-3, cuff_sensors=off).cuff_meas is None
