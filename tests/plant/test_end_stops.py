"""The exoskeleton's hard stops at the URDF limits: they hold, push without pulling, dissipate.

References: the stop's own law (static penetration d = |τ_stop| / K), the
energy of the passive system (kinetic + gravity + springs) before and after
a contact, and the URDF's limits.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant import CuffParams, EndStopParams, MotorParams, Plant
from exo_ctrl.sim import SimConfig, drive_for, simulate

KNEE = 1  # left knee


def passive(exo, patient, stops: EndStopParams) -> Plant:
    return Plant(
        exo,
        patient,
        dt=1e-3,
        motors=None,
        cuffs=CuffParams(damping_N_s_per_m=0.0),
        joint_losses=False,
        end_stops=stops,
    )


def test_the_stops_sit_at_the_urdf_limits(exo, patient) -> None:
    plant = Plant(exo, patient)
    lower, upper = exo.position_limits
    np.testing.assert_array_equal(plant.record["stop_lower"][0], lower)
    np.testing.assert_array_equal(plant.record["stop_upper"][0], upper)


def test_a_joint_driven_into_its_stop_is_held_at_the_penetration_of_the_law(exo, patient) -> None:
    """A saturated drive presses the left knee into its upper stop for 0.5 s.

    At rest the stop's torque balances everything else, and the penetration
    is |τ_stop| / K.  Bound: the drive's effort cap plus the weight of both
    legs at full length (a torque no joint can exceed at rest).
    """
    motor = drive_for(MotorParams(), exo)
    plant = Plant(exo, patient, dt=1e-3, motors=motor, cuffs=CuffParams())
    stops = plant.end_stops
    upper = exo.position_limits[1]
    q0 = np.array([0.3, upper[KNEE] - 0.02, 0.3, 1.0])
    plant.reset(q0, np.zeros(4))
    u = np.zeros(4)
    u[KNEE] = motor.supply_voltage_V  # full voltage: the current goes to its limit
    depth = []
    for _ in range(500):
        plant.step(u)
        depth.append(plant.q[KNEE] - upper[KNEE])
    d = depth[-1]
    tau_stop = plant.end_stop_torque[KNEE]
    weight = (exo.mass + patient.mass) * 9.81 * (0.52 + 0.52)
    bound = (motor.peak_torque_Nm + weight) / stops.stiffness_Nm_per_rad
    print(f"\nknee held {1e3 * d:.2f} mrad into its stop by {tau_stop:.1f} N·m")
    print(f"bound {1e3 * bound:.1f} mrad")
    assert abs(plant.v[KNEE]) < 1e-3  # at rest
    assert 0.0 < d <= bound
    assert tau_stop < 0.0  # the upper stop pushes the joint back
    assert d == pytest.approx(-tau_stop / stops.stiffness_Nm_per_rad, rel=1e-2)
    assert max(depth) <= 2.0 * bound  # the impact too stays within the stop


def impact(exo, patient, stops: EndStopParams) -> tuple[float, float, np.ndarray]:
    """Energy before and after the left knee hits its lower stop at 3 rad/s; stop torques."""
    plant = passive(exo, patient, stops)
    lower, _ = exo.position_limits
    q0 = np.array([0.0, lower[KNEE] + 0.03, 0.0, 0.3])
    v0 = np.zeros(4)
    v0[KNEE] = -3.0
    plant.reset(q0, v0)  # the patient moves with the exoskeleton, straps fitted
    e_before = plant.mechanical_energy()
    torques = []
    touched = False
    for _ in range(400):
        plant.step(np.zeros(4))
        torques.append(plant.end_stop_torque[KNEE])
        touched = touched or torques[-1] != 0.0
        if touched and plant.q[KNEE] > lower[KNEE] + 1e-3 and plant.v[KNEE] > 0:
            break  # left the stop again
    assert touched
    return e_before, plant.mechanical_energy(), np.array(torques)


def test_a_stop_dissipates_on_impact_and_never_pulls(exo, patient) -> None:
    e0, e1, torques = impact(exo, patient, EndStopParams())
    undamped0, undamped1, _ = impact(exo, patient, EndStopParams(damping_Nm_s_per_rad=0.0))
    print(f"\nimpact at 3 rad/s: {e0 - e1:.3f} J dissipated")
    print(f"undamped stop: {undamped0 - undamped1:.4f} J")
    assert np.all(torques >= 0.0)  # the lower stop only ever pushes the joint up
    # The exoskeleton's shank alone (4.5 kg, 0.52 m) has I ≥ 0.05 kg·m² about the
    # knee: at 3 rad/s at least 0.225 J, which a damping ratio of ~0.5 mostly absorbs.
    kinetic = 0.5 * 3.0**2 * 0.05
    assert e0 - e1 > kinetic  # the damper took energy
    assert abs(undamped0 - undamped1) < 0.2 * (e0 - e1)  # and it was the damper


def test_a_default_run_never_touches_the_stops() -> None:
    result = simulate(SimConfig(duration_s=0.3))
    assert np.all(result.signals["end_stop_torque"] == 0.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"stiffness_Nm_per_rad": 0.0}, "end_stop_stiffness must be > 0 N·m/rad; got 0.0"),
        ({"damping_Nm_s_per_rad": -1.0}, "end_stop_damping must be >= 0 N·m·s/rad; got -1.0"),
    ],
)
def test_bad_stop_parameters_are_refused(kwargs, message) -> None:
    with pytest.raises(InvalidParameter, match="^" + message.replace("(", r"\(") + "$"):
        EndStopParams(**kwargs)
