"""Parameters of the wrong type are refused by name, not met later as AttributeError or ValueError.

Found by constructing the parameter classes with wrong types field by field:
a float given as ``gait`` failed later with ``'float' object has no attribute
'pelvis_excursion'``, a numpy array given as a choice (``controller``) or a
switch (``enabled``) with "the truth value of an array is ambiguous".
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl import SimConfig
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.plant.drive import MotorParams
from exo_ctrl.plant.end_stops import EndStopParams
from exo_ctrl.sensing import CurrentSensorParams, SensorParams
from exo_ctrl.sim.belief import Belief
from exo_ctrl.sim.faults import Fault

CHOICE = np.array(["pd", "ct"])


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda: SimConfig(gait=1.0), "gait must be a GaitParams; got 1.0"),
        (lambda: SimConfig(exo=123), "exo must be a URDF path or None; got 123"),
        (lambda: SimConfig(safety="no"), "safety must be True or False; got 'no'"),
        (lambda: SimConfig(contact=None), "contact must be a ContactParams; got None"),
        (lambda: SimConfig(session=5), "session must be a SessionParams or None; got 5"),
        (
            lambda: SimConfig(controller=CHOICE),
            f"controller must be one of pd, ct, qp; got {CHOICE!r}",
        ),
        (
            lambda: SimConfig(estimator=["kalman"]),
            "estimator must be one of momentum, kalman; got ['kalman']",
        ),
        (lambda: SimConfig(mode=CHOICE), "mode must be one of tracking, guidance, "),
        (lambda: SimConfig(sync=np.array([True, False])), "sync must be True, False or None; "),
        (lambda: ContactParams(enabled=1), "contact enabled must be True or False; got 1"),
        (
            lambda: PelvisParams(supported="yes"),
            "pelvis supported must be True or False; got 'yes'",
        ),
        (lambda: EndStopParams(enabled=np.array([1, 0])), "end stops enabled must be True or "),
        (lambda: SensorParams(velocity=np.array(["true"])), "velocity must be 'encoder' or 'true'"),
        (lambda: SensorParams(torque_bias_Nm=np.array(True)), "torque_bias must be a finite "),
        (lambda: SensorParams(torque_bias_Nm=10**400), "torque_bias must be a finite number or 4"),
        (
            lambda: Belief(patient_sex={"male"}),
            "patient_sex must be one of female, male; got {'male'}",
        ),
        (lambda: Fault(kind=[1, 2], at_s=0.0), "fault kind must be one of "),
    ],
    ids=[
        "gait",
        "exo",
        "safety",
        "contact",
        "session",
        "controller",
        "estimator",
        "mode",
        "sync",
        "contact-enabled",
        "pelvis-supported",
        "end-stops",
        "velocity",
        "bias-0d-bool",
        "bias-huge-int",
        "sex",
        "fault-kind",
    ],
)
def test_a_wrong_type_is_refused_by_name(make, expected: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        make()
    assert str(info.value).startswith(expected)


def test_numpy_bools_and_arrays_of_the_right_kind_still_pass() -> None:
    assert ContactParams(enabled=np.bool_(True)).enabled is True
    assert SimConfig(sync=np.bool_(False)).sync is not None
    assert SensorParams(torque_bias_Nm=np.array(0.5)).torque_bias_Nm == (0.5,) * 4
    assert SensorParams(torque_bias_Nm=np.full(4, 0.25)).torque_bias_Nm == (0.25,) * 4


SANE = "(a sanity range: beyond it the models' arithmetic overflows)"


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (
            lambda: SensorParams(sample_rate_hz=1e-308),
            f"sample_rate must be in [0.01, 1e+06] Hz; got 1e-308 {SANE}",
        ),
        (
            lambda: SensorParams(velocity_filter_hz=1e-308),
            f"velocity_filter must be in [0.01, 1e+06] Hz; got 1e-308 {SANE}",
        ),
        (
            lambda: SensorParams(encoder_noise_std_rad=1e308),
            f"encoder_noise_std must be in [0, 1] rad; got 1e+308 {SANE}",
        ),
        (
            lambda: SensorParams(torque_noise_std_Nm=1e308),
            f"torque_noise_std must be in [0, 10000] N·m; got 1e+308 {SANE}",
        ),
        (
            lambda: CurrentSensorParams(noise_std_A=1e308),
            "current sensor noise_std must be in [0, 1000] A; got 1e+308 (a sanity range: "
            "beyond it the monitors' arithmetic overflows)",
        ),
        (
            lambda: MotorParams(inductance_H=1e308),
            "inductance_H must be in [1e-09, 1e+09] H; got 1e+308 (a sanity range for any drive)",
        ),
        (
            lambda: MotorParams(resistance_ohm=1e-308),
            "resistance_ohm must be in [1e-09, 1e+09] Ω; got 1e-308 (a sanity range for any drive)",
        ),
    ],
    ids=["sample-rate", "velocity-filter", "encoder-noise", "torque-noise", "current", "L", "R"],
)
def test_sensor_and_drive_numbers_that_overflowed_in_a_run_are_refused(make, expected) -> None:
    # before: OverflowError or ZeroDivisionError in simulate(), or a diverged run
    # whose summary held NaN energies
    with pytest.raises(InvalidParameter) as info:
        make()
    assert str(info.value) == expected
