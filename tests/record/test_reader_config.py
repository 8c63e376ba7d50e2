"""Tests of the reader's rebuilding of a run's SimConfig from its recorded JSON.

A recording stores ``SimConfig.to_dict()`` (``dataclasses.asdict``): every
nested parameter set becomes a dict, every tuple a list.  The reader must
give back the very config the run had, equal field by field, whatever the
field's annotation: a nested dataclass (``pelvis``, ``contact.belt``,
``foot_load``), an optional one (``belief.cuffs: CuffParams | None``,
``belief.motor``, ``session``, ``speed_profile``), a tuple of them
(``faults``, ``session.segments``) or of tuples (``segments[i].params``).
"""

from __future__ import annotations

import dataclasses
import json
import typing
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.cli import build_parser
from exo_ctrl.cli import main as cli_main
from exo_ctrl.cli.simulate import sim_config
from exo_ctrl.control import PDGains
from exo_ctrl.control.modes import ModeParams, PathParams
from exo_ctrl.model import CUFF_NAMES
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import (
    CompliantJoint,
    ContactParams,
    CuffParams,
    EndStopParams,
    Misalignment,
    MotorParams,
    PelvisParams,
)
from exo_ctrl.plant.belt import BeltParams
from exo_ctrl.plant.cuff_scatter import CuffScatter
from exo_ctrl.plant.patient import SpasticParams
from exo_ctrl.plant.patient_active import ActiveParams
from exo_ctrl.record import RerunRecorder, estimate_file, read_recording
from exo_ctrl.record.reader import _config_from_dict
from exo_ctrl.safety import SafetyLimits
from exo_ctrl.sensing import (
    BeltEncoderParams,
    CuffSensorParams,
    CurrentSensorParams,
    FootLoadParams,
    SensorParams,
)
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief
from exo_ctrl.sim.faults import Fault
from exo_ctrl.sim.plain import from_plain
from exo_ctrl.sim.session import Segment, SessionParams

#: Every nested parameter set away from its default; the pelvis supported
#: (so contact on), the device's cuffs split and its drive another, a
#: session whose second segment sets a belt speed (SimConfig derives the
#: speed profile from it).  Sync off: the run is shorter than a gait period.
FULL = SimConfig(
    duration_s=0.2,
    chunk_ticks=64,
    sync=False,
    gait=GaitParams(step_length=0.33, pelvis_excursion=0.01),
    gains=PDGains(kp=(300.0, 310.0, 320.0, 330.0), kd=9.0),
    motor=MotorParams(gear_ratio=125.0),
    cuffs=CuffParams(
        stiffness_N_per_m=7500.0,
        damping_N_s_per_m=90.0,
        shear_stiffness_N_per_m=3500.0,
        shear_damping_N_s_per_m=60.0,
    ),
    misalignment=Misalignment(hip_xz=(0.005, -0.003)),
    cuff_scatter=CuffScatter(spread_rel=0.1, seed=3),
    end_stops=EndStopParams(stiffness_Nm_per_rad=2000.0),
    joint_compliance=CompliantJoint(enabled=True),
    contact=ContactParams(
        enabled=True, friction_coeff=0.7, belt=BeltParams(mass_kg=25.0, bandwidth_hz=8.0)
    ),
    pelvis=PelvisParams(supported=True, bws_fraction=0.3, body_mass_kg=75.0),
    belt_encoder=BeltEncoderParams(window_s=0.02),
    foot_load=FootLoadParams(noise_std_N=2.0, seed=3),
    sensors=SensorParams(torque_bias_Nm=(0.1, 0.0, -0.1, 0.0), seed=5),
    current_sensor=CurrentSensorParams(noise_std_A=0.02),
    cuff_sensors=CuffSensorParams(mode="full", offset_std_N=0.5),
    safety_limits=SafetyLimits(cuff_force_N=(400.0, 350.0, 400.0, 350.0)),
    belief=Belief(
        patient_height_m=1.78,
        patient_mass_kg=78.0,
        motor=MotorParams(gear_ratio=118.0),
        cuffs=CuffParams(),
        belt=BeltParams(mass_kg=22.0),
    ),
    faults=(Fault("torque_bias_step", 0.15, "left_knee", magnitude=1.0),),
    modes=ModeParams(guidance=0.6),
    path=PathParams(tunnel_width_m=0.02),
    session=SessionParams(
        (
            Segment(0.1, "tracking"),
            Segment(0.1, "guidance", belt_speed_mps=0.5, params=(("guidance", 0.5),)),
        ),
        blend_s=0.02,
        belt_ramp_s=0.05,
    ),
    patient_active=ActiveParams(
        spastic_params=SpasticParams(stiffness_Nm_per_rad=(1.0, 2.0, 1.0, 2.0))
    ),
)


def _as_recorded(config: SimConfig) -> dict:
    """The config as the recording holds it: ``to_dict`` through JSON text."""
    return json.loads(json.dumps(config.to_dict()))


def _dataclasses_in(hint: object) -> list[type]:
    """The dataclass types an annotation names (``X``, ``X | None``, ``tuple[X, ...]``)."""
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        return [hint]
    return [c for arg in typing.get_args(hint) for c in _dataclasses_in(arg)]


def test_full_config_sets_every_nested_parameter_set() -> None:
    """FULL's coverage: each SimConfig field that holds a dataclass differs from the default."""
    default = SimConfig()
    hints = typing.get_type_hints(SimConfig)
    nested = [f.name for f in dataclasses.fields(SimConfig) if _dataclasses_in(hints[f.name])]
    assert {"pelvis", "foot_load", "belief", "faults", "session", "speed_profile"} <= set(nested)
    same = [name for name in nested if getattr(FULL, name) == getattr(default, name)]
    assert same == [], f"set a non-default value of {same} in FULL"
    assert FULL.contact.belt != BeltParams()  # a dataclass nested two levels down
    assert FULL.speed_profile is not None  # derived from the session's belt speed


def test_recorded_json_rebuilds_the_same_config() -> None:
    back = _config_from_dict(Path("x.rrd"), _as_recorded(FULL))
    assert back == FULL
    assert isinstance(back.belief.cuffs, CuffParams)  # X | None
    assert isinstance(back.belief.motor, MotorParams)
    assert isinstance(back.contact.belt, BeltParams)  # nested twice
    assert isinstance(back.pelvis, PelvisParams) and back.pelvis.supported
    assert isinstance(back.faults[0], Fault)  # tuple[X, ...]
    assert back.session.segments[1].params == (("guidance", 0.5),)  # tuple of tuples
    assert back.gains.kp == (300.0, 310.0, 320.0, 330.0)  # tuple[float, ...] | float


@dataclass(frozen=True)
class _Inner:
    value_m: float = 0.0


@dataclass(frozen=True)
class _Outer:
    inner: _Inner = dataclasses.field(default_factory=_Inner)
    maybe: _Inner | None = None
    items: tuple[_Inner, ...] = ()
    pair: tuple[_Inner, float] = (_Inner(), 0.0)
    pairs: tuple[tuple[str, float], ...] = ()
    either: tuple[float, ...] | float = 0.0


@pytest.mark.parametrize(
    "value",
    [
        _Outer(),
        _Outer(
            inner=_Inner(1.0),
            maybe=_Inner(2.0),
            items=(_Inner(3.0), _Inner(4.0)),
            pair=(_Inner(5.0), 6.0),
            pairs=(("a", 7.0), ("b", 8.0)),
            either=(9.0, 10.0),
        ),
    ],
)
def test_annotations_drive_the_conversion(value: _Outer) -> None:
    """Each annotation form comes back from JSON as the value it was, types included."""
    back = from_plain(_Outer, json.loads(json.dumps(dataclasses.asdict(value))))
    assert back == value
    assert all(isinstance(x, _Inner) for x in (back.inner, back.pair[0], *back.items))
    assert back.maybe is None or isinstance(back.maybe, _Inner)


def test_full_config_recording_reads_back_the_same_run(tmp_path: Path, assert_same_run) -> None:
    path = tmp_path / "full.rrd"
    result = simulate(FULL, observers=[RerunRecorder(path)])
    assert result.status == "completed"  # precondition
    back = read_recording(path)
    assert back.config == FULL
    assert_same_run(back, result)
    assert back.events == result.events
    assert back.summary() == result.summary()


def test_given_cuffs_recording_reads_back_and_estimates(tmp_path: Path, capsys) -> None:
    """``--controller-cuffs isotropic``: the recorded device cuffs come back, estimate uses them.

    The offline Kalman filter, rebuilt on the recording's device models,
    must give the live estimate; PD does not read the cuff model, so a run
    whose device holds the default (published split) cuffs has the same
    readings and a different estimate: the given cuffs were read back, not
    defaulted.
    """
    args = ["--controller-cuffs", "isotropic", "--duration", "0.6"]
    config = sim_config(build_parser().parse_args(["simulate", *args]))
    cuffs = config.belief.cuffs
    assert cuffs == CuffParams.isotropic()
    path = tmp_path / "split.rrd"
    assert cli_main(["simulate", *args, "--out", str(path)]) == 0
    back = read_recording(path)
    assert back.config == config
    assert back.config.belief.cuffs == cuffs

    summary_path = tmp_path / "estimate.json"
    assert cli_main(["estimate", str(path), "--summary", str(summary_path)]) == 0
    assert "the Kalman filter" in capsys.readouterr().out
    live = simulate(config)
    offline = json.loads(summary_path.read_text())
    errors = live.summary()["cuff_force_estimate_rms_error_N"]
    for cuff in CUFF_NAMES:
        assert offline["cuff_force_estimate_rms_error_N"][cuff] == pytest.approx(
            errors[cuff], rel=1e-9
        )
    est = estimate_file(path)
    np.testing.assert_allclose(est.series.force, live.signals["cuff_force_est"], rtol=0, atol=1e-9)

    published = simulate(replace(config, belief=replace(config.belief, cuffs=None)))
    np.testing.assert_array_equal(published.signals["tau_sensor"], live.signals["tau_sensor"])
    gap = np.max(np.abs(est.series.force - published.signals["cuff_force_est"]))
    assert gap > 1.0  # N: the published cuff model's filter is another estimate
