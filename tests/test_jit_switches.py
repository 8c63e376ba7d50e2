"""Compile only what the run uses: feature switches, one signature per callee (exo_ctrl._jit).

A feature the run leaves off (pelvis guide, belt contact, compliant drives,
split cuffs, the patient's feet on the belt) is pruned from its caller's
compiled code when its switch is None, so its kernels are not compiled; and
every caller of a shared callee passes the same argument types, so the
callee compiles once.  Both are properties of the typed code, read here from
a fresh, uncached compile of the caller (its callees' calls and their
argument types).
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import numba
import numpy as np
import pytest
from numba.core import types

from exo_ctrl._jit import switch
from exo_ctrl.control.qp import CuffStateObserver
from exo_ctrl.control.qp.observer import observe
from exo_ctrl.control.qp.prediction import CuffHorizonModel, gather, predict
from exo_ctrl.estimation import CuffForceKalman
from exo_ctrl.estimation.kalman_step import kalman_outputs
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import ContactParams, CuffParams, MotorParams, PelvisParams, Plant
from exo_ctrl.plant.compliance import CompliantJoint, rotor_forces, rotor_kick
from exo_ctrl.plant.step import drift_and_forces, kick_and_drift, plant_switches

PLAIN = numba.typeof(np.zeros(4))  # array(float64, 1d, C)


def callees(kernel: Any, *args: Any) -> dict[str, list[tuple]]:
    """The kernels ``kernel`` calls when compiled for ``args``' types: name → argument types."""
    fresh = numba.njit(cache=False, error_model="numpy")(kernel.py_func)
    fresh.compile(tuple(numba.typeof(a) for a in args))
    typed = next(iter(fresh.overloads.values())).type_annotation
    found: dict[str, list[tuple]] = defaultdict(list)
    for expr, sig in typed.calltypes.items():
        if getattr(expr, "op", None) == "call":
            func = typed.typemap[expr.func.name]
            if isinstance(func, types.Dispatcher):
                found[func.dispatcher.py_func.__name__].append(tuple(sig.args))
    return found


def test_switch_is_true_or_none() -> None:
    assert switch(True) is True and switch(False) is None
    assert switch(np.bool_(True)) is True and switch(np.bool_(False)) is None


def test_the_switches_follow_the_plants_flags(exo, patient) -> None:
    plain = Plant(exo, patient, motors=MotorParams(), cuffs=CuffParams.isotropic())
    assert plant_switches(plain.record) == (None, None, None, None, None)
    assert plain.cuffs.split_switch is None
    everything = Plant(
        exo,
        patient,
        motors=MotorParams(),
        cuffs=CuffParams(),  # split by default
        compliance=CompliantJoint(enabled=True),
        contact=ContactParams(enabled=True, patient_feet=True),
        pelvis=PelvisParams(supported=True),
        belt_height_m=GaitParams(hip_height=0.98).hip_height,
    )
    assert plant_switches(everything.record) == (True, True, True, True, True)
    assert everything.cuffs.split_switch is True


@pytest.fixture(scope="module")
def calls(exo, patient) -> dict[str, Any]:
    """The callees of the plant's step kernels, switches off and on, and of their callers'."""
    iso = Plant(exo, patient, motors=MotorParams(), cuffs=CuffParams.isotropic())
    plant = Plant(exo, patient, motors=MotorParams(), cuffs=CuffParams())
    rec, u, a = plant.record, np.zeros(4), np.zeros(8)
    kf = CuffForceKalman(exo, patient, 1e-3, cuffs=CuffParams())  # split cuffs: switch on
    return {
        "plant": plant,
        "drift off": callees(
            drift_and_forces, iso.record, u, u, False, None, None, None, None, None
        ),
        "drift on": callees(drift_and_forces, rec, u, u, False, True, True, True, True, True),
        "contact only": callees(kick_and_drift, rec, a, None, True, None, None),
        "kick on": callees(kick_and_drift, rec, a, True, True, True, True),
        "rotor_forces": callees(rotor_forces, rec[0], u, a, a, a),
        "rotor_kick": callees(rotor_kick, rec[0]),
        "kalman": callees(kalman_outputs, kf.record, kf.cuffs.record, kf.cuffs.split_switch),
    }


@pytest.mark.heavy
def test_switched_off_features_are_not_compiled_and_on_ones_are(calls) -> None:
    # isotropic cuffs: isotropic_forces alone, not forces_of (which would compile split_forces)
    assert set(calls["drift off"]) == {"isotropic_forces", "end_stop_torques", "step_drives"}
    assert {"pelvis_drift", "contact_forces", "rotor_forces"} <= set(calls["drift on"])
    assert {"pelvis_kick", "contact_commit", "rotor_kick"} <= set(calls["kick on"])
    assert "patient_forces" in calls["drift on"] and "feet_commit" in calls["kick on"]
    assert "feet_commit" not in calls["contact only"]  # the patient's feet off: pruned
    assert "contact_commit" in calls["contact only"]


@pytest.mark.heavy
def test_every_caller_passes_plain_arrays_to_shared_callees(calls) -> None:
    """forces_of, step_drives and book_drives: one signature for all callers, Python's included.

    forces_of takes no switch: the isotropic device model's kernels call
    isotropic_forces instead, so a run whose truth has split cuffs and whose
    device believes isotropic ones compiles each kernel once (two signatures
    of one kernel could cross in numba's cache index when two processes save
    them at once: exo_ctrl/sim/warmup.py).
    """
    seen: dict[str, set[tuple]] = defaultdict(set)
    for name in ("drift on", "kick on", "rotor_forces", "rotor_kick", "kalman"):
        for callee, args in calls[name].items():
            seen[callee].update(call[1:] for call in args)
    assert seen["forces_of"] == {(PLAIN, PLAIN)}
    # CuffSet.compute calls it from Python on the record itself: the plant's call.
    cuffs = calls["plant"].cuffs
    python = (cuffs.record[0], np.zeros(8), np.zeros(8))
    assert tuple(numba.typeof(a) for a in python) == calls["drift on"]["forces_of"][0]
    assert seen["step_drives"] == {(PLAIN, PLAIN)}
    assert seen["book_drives"] == {(PLAIN,)}


@pytest.mark.heavy
def test_the_qp_compiles_the_split_cuffs_code_only_for_a_split_cuff_model(
    exo, patient, motor
) -> None:
    """The QP's cuff model (isotropic by default) prunes split_cuffs' kernels from its tick."""
    model = CuffHorizonModel(exo, patient, motor)
    assert model.split_switch is None
    assert CuffHorizonModel(exo, patient, motor, CuffParams()).split_switch is True
    m, z = model.record[0], np.zeros(4)
    obs = CuffStateObserver(8000.0, 100.0).record[0]
    assert "split_gains" not in callees(gather, m, np.zeros((8, 8)), np.zeros(8), z, z, None)
    assert "split_rows" not in callees(predict, m, z, z, z, None)
    assert "filter_leg" not in callees(observe, obs, m, np.zeros((4, 2)), z, None)
    assert "filter_leg" in callees(observe, obs, m, np.zeros((4, 2)), z, True)
