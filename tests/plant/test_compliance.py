"""Joint compliance: a spring–damper between each drive's rotor and its link.

The rotor (θ, J_r = i_G² J_rotor) and the link (q) are joined by
τ_s = K (θ − q) + C (θ̇ − q̇) (:mod:`exo_ctrl.plant.compliance`).  Checked
here: the rotor's free oscillation against a clamped link, the static
deflection τ/K, what the torque sensor reads, energy conservation of the
passive rotor–spring–link system and the damper's dissipation, convergence
to the rigid drive as K grows, the tracking with and without compliance,
the parameters' and the CLI's refusals.

"Open circuit": a drive with R = 1 MΩ, whose back-EMF damping
i_G² k_m / (k_E R) = 2.1e-5 N·m·s/rad is nothing against the spring, so
that the mechanics ring freely; its lossless gearbox (η = 1) leaves no
gear loss.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl import cli
from exo_ctrl.cli.simulate import sim_config
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyModel
from exo_ctrl.plant import CompliantJoint, CuffParams, EndStopParams, MotorParams, Plant
from exo_ctrl.plant.compliance import MAX_OMEGA_H
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.setup import build, start_on_plan

OPEN_CIRCUIT = MotorParams(resistance_ohm=1e6, gear_efficiency=1.0)
K = CompliantJoint().stiffness_Nm_per_rad
J_R = MotorParams().reflected_inertia_kgm2
H = 1e-3
#: A posture within every joint's range [rad] (hip, knee per leg).
POSTURE = np.array([0.3, 0.4, -0.2, 0.6])


def weightless(body: BodyModel) -> BodyModel:
    """The body with its model's gravity set to zero (a copy)."""
    model = pin.Model(body.model)
    model.gravity = pin.Motion.Zero()
    return dataclasses.replace(body, model=model)


def smallest_link_inertia(exo: BodyModel, q: np.ndarray) -> float:
    """λ_min of the exoskeleton's mass matrix at q [kg·m²]."""
    mass = pin.crba(exo.model, exo.model.createData(), q)
    return float(np.linalg.eigvalsh(np.triu(mass) + np.triu(mass, 1).T)[0])


def clamp(plant: Plant, q: np.ndarray) -> None:
    """Hold both bodies at q (8), at rest: only the rotors move."""
    plant.q[:] = q
    plant.v[:] = 0.0
    plant.acceleration[:] = 0.0


def rotor(plant: Plant, name: str) -> np.ndarray:
    """A compliance field of the plant's record (a view)."""
    return plant.record[name][0]


# --------------------------------------------------------------------------- parameters


def test_defaults_and_their_damping_ratio() -> None:
    joint = CompliantJoint()
    assert joint.enabled is False
    assert joint.stiffness_Nm_per_rad == 2.0e4 and joint.damping_Nm_s_per_rad == 15.0
    assert pytest.approx(0.288) == J_R
    assert joint.rotor_frequency_rad_s(MotorParams()) == pytest.approx(263.523, rel=1e-5)
    assert joint.damping_ratio(MotorParams()) == pytest.approx(0.0988, abs=1e-4)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"stiffness_Nm_per_rad": -1.0}, "joint_stiffness must be > 0 N·m/rad; got -1.0"),
        ({"stiffness_Nm_per_rad": 0.0}, "joint_stiffness must be > 0 N·m/rad; got 0.0"),
        ({"damping_Nm_s_per_rad": -2.0}, "joint_damping must be >= 0 N·m·s/rad; got -2.0"),
        ({"enabled": "yes"}, "joint_compliance.enabled must be True or False; got 'yes'"),
    ],
)
def test_bad_parameters_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        CompliantJoint(**kwargs)
    assert str(info.value) == message


def test_nan_stiffness_is_refused() -> None:
    with pytest.raises(InvalidParameter, match=r"^joint_stiffness must be a finite number"):
        CompliantJoint(stiffness_Nm_per_rad=float("nan"))


def test_compliance_needs_drives(exo, patient) -> None:
    with pytest.raises(InvalidParameter) as info:
        Plant(exo, patient, motors=None, compliance=CompliantJoint(enabled=True))
    assert str(info.value).startswith("joint_compliance must be disabled; got CompliantJoint(")
    assert str(info.value).endswith("(the plant has no drives to be compliant)")


def test_a_stiffness_the_step_cannot_integrate_is_refused(exo, patient, motor) -> None:
    """ω_max² = K (1/J_r + 1/λ_min) at the straight leg; ω_max h ≤ 1 allowed."""
    link = smallest_link_inertia(exo, np.zeros(4))
    most = (MAX_OMEGA_H / H) ** 2 / (1.0 / J_R + 1.0 / link)
    assert 5.7e4 < most < 5.9e4  # 58 000 N·m/rad at 1 ms for the default exoskeleton
    Plant(exo, patient, dt=H, motors=motor, compliance=CompliantJoint(0.99 * most, enabled=True))
    with pytest.raises(InvalidParameter) as info:
        Plant(exo, patient, dt=H, motors=motor, compliance=CompliantJoint(1e5, enabled=True))
    omega = math.sqrt(1e5 * (1.0 / J_R + 1.0 / link))
    assert str(info.value) == (
        f"joint_stiffness must be at most {most:.4g} N·m/rad at a plant step of 1 ms; got "
        f"100000.0 (its fastest mode, {omega:.4g} rad/s with the rotor's 0.288 kg·m² and the "
        f"link's {link:.4g} kg·m², needs ω h <= 1; more plant substeps allow a stiffer joint)"
    )
    # A tenth of the step takes it.
    Plant(exo, patient, dt=H / 10, motors=motor, compliance=CompliantJoint(1e5, enabled=True))


# --------------------------------------------------------------------------- the rotor alone


def ring(exo, patient, damping: float, steps: int) -> np.ndarray:
    """Deflections θ − q of rotors set off by a few mrad against clamped links, (steps, 4)."""
    plant = Plant(
        exo, patient, dt=H, motors=OPEN_CIRCUIT, compliance=CompliantJoint(K, damping, True)
    )
    plant.reset(POSTURE, np.zeros(4))
    q0 = plant.q.copy()
    rotor(plant, "rotor_q")[:] += np.array([1e-3, 2e-3, -1e-3, 3e-3])
    out = np.empty((steps, 4))
    for k in range(steps):
        plant.step(np.zeros(4))
        clamp(plant, q0)
        out[k] = rotor(plant, "rotor_q") - q0[:4]
    return out


def test_a_rotor_against_a_clamped_link_rings_at_sqrt_k_over_j(exo, patient) -> None:
    """The undamped rotor: ω from the zero crossings of θ − q over 0.4 s (about 17 periods).

    Leapfrog rings at (2/h) arcsin(ω h / 2), 0.29 % above √(K/J_r) = 263.5 rad/s at 1 ms.
    """
    x = ring(exo, patient, 0.0, 400)[:, 1]
    i = np.flatnonzero(np.sign(x[1:]) != np.sign(x[:-1]))
    crossings = (i + 1 + x[i] / (x[i] - x[i + 1])) * H  # row k is at t = (k + 1) h
    omega = math.pi / np.mean(np.diff(crossings))
    exact = math.sqrt(K / J_R)
    discrete = 2.0 / H * math.asin(exact * H / 2.0)
    print(f"rotor mode {omega:.3f} rad/s; sqrt(K/J_r) {exact:.3f}; leapfrog's {discrete:.3f}")
    assert len(crossings) >= 30
    assert omega == pytest.approx(discrete, rel=1e-4)
    assert omega == pytest.approx(exact, rel=(exact * H) ** 2 / 24 * 1.1)
    assert CompliantJoint().rotor_frequency_rad_s(MotorParams()) == pytest.approx(exact)


def test_the_damper_gives_its_damping_ratio(exo, patient) -> None:
    """Successive peaks fall by the log decrement 2π ζ / √(1 − ζ²), ζ = C / (2 √(K J_r))."""
    x = ring(exo, patient, 15.0, 300)[:, 1]
    peaks = x[[i for i in range(1, len(x) - 1) if x[i - 1] < x[i] >= x[i + 1]]]
    delta = math.log(peaks[0] / peaks[-1]) / (len(peaks) - 1)
    zeta = delta / math.sqrt(4.0 * math.pi**2 + delta**2)
    expected = CompliantJoint().damping_ratio(MotorParams())
    print(f"damping ratio {zeta:.4f} measured, {expected:.4f} expected")
    assert len(peaks) >= 5
    assert zeta == pytest.approx(expected, rel=0.05)  # the explicit damper: +3 % at 1 ms


def test_a_held_load_deflects_the_spring_by_torque_over_k(exo, patient, motor) -> None:
    """Clamped links, a held voltage: at rest the stall torque k_t U / R sits in the spring."""
    plant = Plant(exo, patient, dt=H, motors=motor, compliance=CompliantJoint(enabled=True))
    plant.reset(POSTURE, np.zeros(4))
    q0 = plant.q.copy()
    torque = np.array([50.0, -30.0, 80.0, 10.0])  # [N·m]
    voltage = torque * motor.resistance_ohm / motor.torque_per_amp_Nm_per_A
    for _ in range(400):
        plant.step(voltage)
        clamp(plant, q0)
    np.testing.assert_allclose(rotor(plant, "deflection"), torque / K, rtol=1e-7)
    np.testing.assert_allclose(plant.sensor_torque, torque, rtol=1e-7)
    np.testing.assert_allclose(plant.drive_torque, torque, rtol=1e-7)


def test_the_legs_weight_held_at_rest_deflects_the_springs(exo, patient) -> None:
    """The default start, standing at rest: the held weight less the cuffs' share is K (θ − q)."""
    config = SimConfig(joint_compliance=CompliantJoint(enabled=True), duration_s=0.3)
    setup = build(config)
    start_on_plan(setup)
    plant, motor = setup.plant, setup.plant.motor_params
    q0, hold = plant.q[:4].copy(), plant.drive_torque.copy()
    voltage = hold * motor.resistance_ohm / motor.torque_per_amp_Nm_per_A
    for _ in range(300):
        plant.step(voltage)
    assert np.max(np.abs(hold)) > 20.0  # the hips hold the legs
    assert np.max(np.abs(plant.q[:4] - q0)) < 1e-6
    np.testing.assert_allclose(rotor(plant, "deflection"), hold / K, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(plant.sensor_torque, hold, rtol=1e-5, atol=1e-5)


def test_the_sensor_reads_the_spring_torque(exo, patient, motor) -> None:
    """τ_sensor = K (θ½ − q½) + C (θ̇½ − q̇½), from the state before each step; not the drive's."""
    joint = CompliantJoint(enabled=True)
    plant = Plant(exo, patient, dt=H, motors=motor, compliance=joint)
    plant.reset(POSTURE, np.zeros(4))
    differs = 0.0
    for k in range(200):
        theta, omega, alpha = (rotor(plant, n).copy() for n in ("rotor_q", "rotor_v", "rotor_acc"))
        q, v, a = plant.q[:4].copy(), plant.v[:4].copy(), plant.acceleration[:4].copy()
        plant.step(np.full(4, 2.0 * math.sin(40.0 * k * H)))
        stretch = (theta + 0.5 * H * omega) - (q + 0.5 * H * v)
        rate = (omega + 0.5 * H * alpha) - (v + 0.5 * H * a)
        expected = joint.stiffness_Nm_per_rad * stretch + joint.damping_Nm_s_per_rad * rate
        np.testing.assert_allclose(plant.sensor_torque, expected, rtol=1e-12, atol=1e-9)
        differs = max(differs, float(np.max(np.abs(plant.sensor_torque - plant.drive_torque))))
    assert differs > 1.0  # the rotor's inertia and the spring lie between the drive and the link


# --------------------------------------------------------------------------- energy


def passive(exo, patient, damping: float, h: float) -> Plant:
    """Weightless bodies, open-circuit drives, no joint losses, undamped cuffs, no stops."""
    return Plant(
        weightless(exo),
        weightless(patient),
        dt=h,
        motors=OPEN_CIRCUIT,
        cuffs=CuffParams.isotropic(damping_N_s_per_m=0.0),
        joint_losses=False,
        end_stops=EndStopParams(enabled=False),
        compliance=CompliantJoint(K, damping, True),
    )


def energy_run(plant: Plant, seconds: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Start at rest, the rotors deflected: E(0), then E and E + dissipated − drive work [J]."""
    plant.reset(POSTURE, np.zeros(4))
    rotor(plant, "rotor_q")[:] += np.array([4e-3, -3e-3, 2e-3, 5e-3])
    e0 = plant.mechanical_energy()
    energy, books = [], []
    for _ in range(round(seconds / plant.dt)):
        plant.step(np.zeros(4))
        energy.append(plant.mechanical_energy())
        work = float(np.sum(plant.record["motors"]["e_mechanical"][0]))
        books.append(energy[-1] + plant.rotors.dissipated_J - work)
    return e0, np.array(energy), np.array(books)


def leapfrog_bound(exo, h: float) -> float:
    """Störmer–Verlet's energy error over E at rest: x / (1 − x), x = (ω_max h)² / 4.

    A linear mode's E = ½ v² + ½ ω² y² oscillates between the conserved
    ½ v² (1 − x) + ½ ω² y² (E at rest) and that over (1 − x); ω_max² =
    K (1/J_r + 1/λ_min(M(q))) is the fastest mode at the posture.
    """
    omega = math.sqrt(K * (1.0 / J_R + 1.0 / smallest_link_inertia(exo, POSTURE)))
    x = (omega * h) ** 2 / 4.0
    return x / (1.0 - x)


def test_the_passive_rotor_spring_link_system_conserves_energy(exo, patient) -> None:
    """Undamped: |E − E(0)| within the leapfrog's bound, which falls as h² (1 ms and 0.25 ms)."""
    errors = []
    for h in (H, H / 4):
        e0, energy, books = energy_run(passive(exo, patient, 0.0, h), 0.5)
        error = float(np.max(np.abs(books - e0))) / e0
        bound = leapfrog_bound(exo, h)
        print(f"h = {h * 1e3:g} ms: max |E - E0| / E0 = {error:.3g}, bound {bound:.3g}")
        assert error <= bound
        assert np.max(np.abs(energy - books)) < 1e-4 * e0  # the open-circuit drives do ~nothing
        errors.append(error)
    assert 12.0 < errors[0] / errors[1] < 20.0  # second order: 16 for h / 4


def test_the_damper_dissipates_what_the_system_loses(exo, patient) -> None:
    """Damped: E + dissipated stays at E(0) within the same bound; nearly all is dissipated."""
    for h in (H, H / 4):
        plant = passive(exo, patient, CompliantJoint().damping_Nm_s_per_rad, h)
        e0, energy, books = energy_run(plant, 0.5)
        dissipated = books - energy
        error = float(np.max(np.abs(books - e0))) / e0
        print(
            f"h = {h * 1e3:g} ms: E(0.5 s) / E0 = {energy[-1] / e0:.4f}, balance error {error:.3g}"
        )
        assert error <= leapfrog_bound(exo, h)
        assert energy[-1] < 0.01 * e0
        assert np.all(np.diff(dissipated) > -1e-9 * e0)  # the damper never gives energy back
        assert dissipated[-1] > 0.98 * e0


# --------------------------------------------------------------------------- runs


def test_a_stiff_joint_converges_to_the_rigid_drive() -> None:
    """K = 2e5, 6e5, 2e6 N·m/rad against the rigid drive, 8 plant steps a tick (ω_max h ≤ 0.73).

    The link's path differs from the rigid one's by less than half the
    deflection τ_peak / K (measured 0.17-0.29 of it) and falls with K.
    """
    base = {"duration_s": 1.0, "ramp_in_s": 0.6, "plant_substeps": 8}
    rigid = simulate(SimConfig(**base)).signals
    peak = float(np.max(np.abs(rigid["drive_torque"])))
    errors = []
    for k in (2e5, 6e5, 2e6):
        run = simulate(SimConfig(joint_compliance=CompliantJoint(k, enabled=True), **base))
        assert run.status == "completed"
        error = float(np.max(np.abs(run.signals["q"] - rigid["q"])))
        print(f"K = {k:.0e} N·m/rad: max |q - q_rigid| = {error:.3g} rad, τ_peak/K {peak / k:.3g}")
        assert error < 0.5 * peak / k
        deflection = float(np.max(np.abs(run.signals["joint_deflection"])))
        assert 0.5 * peak / k < deflection < 1.5 * peak / k
        errors.append(error)
    assert errors[0] > errors[1] > errors[2] and errors[0] > 5.0 * errors[2]
    assert np.all(rigid["joint_deflection"] == 0.0)


def test_default_compliance_changes_the_tracking() -> None:
    """PD and CT on 1.5 s of the default run (ramp-in and a quarter period), rigid and compliant.

    Without the safety supervisor: its drive-model residual monitor
    (:mod:`exo_ctrl.safety.plausibility`) models a rigid drive (the sensor
    reading τ − i_G² J_rotor q̈), which a compliant joint leaves by up to the
    30 N·m threshold (it tripped at 0.92 s of the PD run).
    """
    rms = {}
    for controller in ("pd", "ct"):
        for joint in (CompliantJoint(), CompliantJoint(enabled=True)):
            config = SimConfig(
                controller=controller, duration_s=1.5, joint_compliance=joint, safety=False
            )
            run = simulate(config)
            assert run.status == "completed"
            errors = run.summary()["rms_tracking_error_rad"]
            rms[controller, joint.enabled] = np.array(list(errors.values()))
            deflection = np.max(np.abs(run.signals["joint_deflection"]), axis=0)
            print(
                f"{controller} {'compliant' if joint.enabled else 'rigid    '}: RMS tracking error "
                f"{np.round(1e3 * rms[controller, joint.enabled], 3)} mrad, peak deflection "
                f"{np.round(1e3 * deflection, 2)} mrad"
            )
    for controller in ("pd", "ct"):
        change = rms[controller, True] - rms[controller, False]
        print(f"{controller}: compliance changes the RMS error by {np.round(1e3 * change, 3)} mrad")
        assert np.any(change != 0.0)
        assert np.all(np.abs(change) < 0.2 * rms[controller, False])
    assert np.all(rms["ct", True] < rms["pd", True] / 5.0)  # CT stays far ahead


def test_the_cli_runs_a_compliant_joint(tmp_path: Path, capsys) -> None:
    summary = tmp_path / "s.json"
    args = ["simulate", "--duration", "0.2", "--no-record", "--summary", str(summary)]
    assert cli.main([*args, "--joint-stiffness", "2e4", "--joint-damping", "10"]) == 0
    capsys.readouterr()
    data = json.loads(summary.read_text())
    assert data["status"] == "completed"
    config = sim_config(cli.build_parser().parse_args(["simulate", "--joint-stiffness", "3e4"]))
    assert config.joint_compliance == CompliantJoint(3e4, 15.0, True)
    rigid = sim_config(cli.build_parser().parse_args(["simulate"]))
    assert rigid.joint_compliance == CompliantJoint()


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            ["--joint-stiffness", "-5"],
            "--joint-stiffness: joint_compliance.joint_stiffness: must be > 0 N·m/rad; got -5.0",
        ),
        (
            ["--joint-stiffness", "1e6"],
            "joint_stiffness must be at most 5.795e+04 N·m/rad at a plant step of 1 ms; "
            "got 1000000.0",
        ),
        (
            ["--joint-damping", "-1"],
            "--joint-damping: joint_compliance.joint_damping: must be >= 0 N·m·s/rad; got -1.0",
        ),
    ],
)
def test_the_cli_refuses_a_bad_joint(
    tmp_path: Path, capsys, args: list[str], expected: str
) -> None:
    out = tmp_path / "run.rrd"
    code = cli.main(["simulate", "--duration", "0.1", "--out", str(out), *args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith(f"exo-ctrl simulate: error: {expected}"), err
    assert "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()


def test_a_compliant_run_with_the_supervisor_raises_no_false_alarm() -> None:
    """The rigid drive-model check is off for compliant joints: the default PD run stays normal."""
    result = simulate(SimConfig(duration_s=1.5, joint_compliance=CompliantJoint(enabled=True)))
    assert result.status == "completed"
    assert result.summary()["safety_state"] == "normal", result.summary()["safety_events"]
