"""The Kalman filter fused with instrumented cuffs (exo_ctrl/estimation/kalman_cuff.py).

On the default scenario (CT, the device holding the published split cuffs,
the patient's cuffs scattered around them, 3.6 s), the errors per cuff after
the ramp-in, RMS error over RMS true value, with the sensors' noise, offset
(σ_b = 1 N, drawn per run) and drift on in every run, over three of the
sensors' seeds.  The goals the issue states (issue 31): with ``full`` cuff
sensors, the full vector within 5 % of its RMS; and sensors never worse
than none on the normal components.  Both hold here with the tare on
(``tare_s`` = 0.3 s: the device zeroes its sensors while it stands at the
start, on its standing model, which is right on this patient to under 1 N);
without the tare (the default, as the tare takes a wrong standing model's
error for an offset: exo_ctrl/sensing/cuff_load.py) the offsets (up to
3.3 N with the default seed) pass into the estimate.
"""

from __future__ import annotations

from functools import cache
from typing import Any

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

#: The bound on the tare's error per measured axis [N]: the device's model of the
#: standing forces (the hip torque's split between the thigh's normal and the
#: shank's along force comes from the cuff model; 0.9 N measured).
TARE_BOUND_N = 1.0

#: The bound on the tare's error on the axes the device's standing model gets right
#: [N]: the shank's normal (the knee torque sees it) and the thigh's along force.
TARE_OBSERVED_BOUND_N = 0.1


#: A bound on σ_c over the tare and the first fused samples [N] (2.0 N measured): below the 30 N
#: prior of the model-error force, which the tare keeps out of σ_c.
SIGMA_BOUND_N = 5.0


@cache
def _errors(mode: str, seed: int = 3, tare_s: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Per cuff, the full vector's and the normal's RMS error over RMS, after the ramp-in."""
    params = CuffSensorParams(mode=mode, seed=seed, tare_s=tare_s)
    summary = simulate(SimConfig(controller="ct", cuff_sensors=params)).summary()
    full = np.array(list(summary["cuff_force_estimate_rms_error_rel"].values()))
    normal = np.array(list(summary["cuff_force_estimate_normal_rms_error_over_rms"].values()))
    print(f"\n{mode} seed {seed} tare {tare_s} s: full vector {np.round(100 * full, 1)} %, "
          f"normal {np.round(100 * normal, 1)} %")  # fmt: skip
    return full, normal


@pytest.mark.parametrize("seed", SEEDS)
def test_full_sensors_hold_the_full_vector_within_5_percent(seed: int) -> None:
    full, _ = _errors("full", seed)
    assert np.all(full < GOAL), f"full-vector error {np.round(100 * full, 2)} % over the 5 % goal"
    assert np.all(full < _errors("none")[0])  # and below the joint torques' alone


@pytest.mark.parametrize("mode", ["normal", "full"])
@pytest.mark.parametrize("seed", SEEDS)
def test_sensors_are_never_worse_than_none_on_the_normal_components(mode: str, seed: int) -> None:
    _, normal = _errors(mode, seed)
    _, none = _errors("none")
    assert np.all(normal <= none), f"normal {np.round(100 * normal, 2)} % against none's"


def test_without_the_tare_the_offset_passes_into_the_estimate() -> None:
    """The default seed's offsets (3.3 N on the left thigh) put a cuff over the 5 %."""
    full, _ = _errors("full", 3, tare_s=0.0)
    assert np.max(full) > GOAL


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
