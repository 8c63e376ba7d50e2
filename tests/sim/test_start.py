"""The bumpless start (issue 15 item 5): standing at rest, the cuffs at static equilibrium.

The default run starts standing, with the patient settled into the cuffs and
the drives holding the exoskeleton, and ramps into the gait over one period.
Checked here on the real models and the real loop:

- the first 200 ms of the default run (pd, ct, qp) stay below 60 % of every
  drive's torque limit (the run's drive, capped by the URDF effort), and no
  drive current reaches its limit during the ramp;
- the cuff force at t = 0 is the static equilibrium's, computed here
  independently as the minimum of the patient's potential energy (gravity,
  the cuff springs, a spastic patient's hypertonia) from Pinocchio's frame
  placements, within 1 N; at t = 0 neither body accelerates;
- the cuff force has no spike over the first 200 ms (bound derived in
  :func:`test_cuff_force_has_no_spike_over_the_first_200_ms`), which the old
  slack start breaks;
- the options' bad values are refused with exact messages and exit 2.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import minimize

from exo_ctrl import cli
from exo_ctrl.cli.simulate import sim_config
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyModel
from exo_ctrl.plan import smoothstep
from exo_ctrl.plant import SpasticParams
from exo_ctrl.plant.equilibrium import settle_patient
from exo_ctrl.sensing import SensorParams
from exo_ctrl.sim import CONTROLLERS, SimConfig, build, drive_for, simulate, start_on_plan
from exo_ctrl.sim.tick import Runner

#: The window the issue's start checks look at [s].
WINDOW_S = 0.2


@pytest.fixture(scope="module")
def runs() -> dict:
    """The default run of each controller (SimConfig() defaults)."""
    return {c: simulate(SimConfig(controller=c)) for c in CONTROLLERS}


def torque_limits(config: SimConfig, exo: BodyModel) -> np.ndarray:
    """Each joint's torque limit [N·m]: the run's drive, capped by the URDF effort."""
    drive = drive_for(config.motor, exo)
    return np.minimum(drive.peak_torque_Nm, exo.effort_limit)


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_first_200_ms_stay_below_60_percent_of_the_torque_limits(
    runs: dict, exo: BodyModel, controller: str
) -> None:
    result = runs[controller]
    assert result.status == "completed"
    limit = torque_limits(result.config, exo)
    n = round(WINDOW_S / result.config.dt)
    peak = np.max(np.abs(result.signals["drive_torque"][:n]), axis=0)
    print(controller, "peak |τ| over the first 200 ms [N·m]", np.round(peak, 1), "of", limit)
    assert np.all(peak < 0.6 * limit)


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_no_drive_current_reaches_its_limit_during_the_ramp(
    runs: dict, exo: BodyModel, controller: str
) -> None:
    result = runs[controller]
    config = result.config
    i_max = drive_for(config.motor, exo).current_limit_A
    ramp = round(config.ramp_in / config.dt)
    peak = np.max(np.abs(result.signals["current"][:ramp]), axis=0)
    print(controller, "peak |I| during the ramp [A]", np.round(peak, 2), "limit", i_max)
    assert np.all(peak < 0.999 * i_max)


# --------------------------------------------------------------------------- the equilibrium


def xz_frames(body: BodyModel, q: np.ndarray) -> np.ndarray:
    """World (x, z) of the body's four cuff frames, (4, 2) [m] (the plant's cuff order)."""
    data = body.model.createData()
    pin.framesForwardKinematics(body.model, data, q)
    return np.array([data.oMf[f].translation[[0, 2]] for f in body.cuff_frame_ids])


def hypertonia(q: np.ndarray) -> tuple[float, np.ndarray]:
    """A spastic patient's hypertonic energy ½ Σ k_h (q - q_rest)² [J] and its stiffness."""
    p = SpasticParams()
    k, rest = np.array(p.stiffness_Nm_per_rad), np.array(p.rest_posture_rad)
    return 0.5 * float(np.sum(k * (q - rest) ** 2)), k


def independent_equilibrium(
    exo: BodyModel,
    patient: BodyModel,
    q_fit: np.ndarray,
    q_exo: np.ndarray,
    stiffness: float,
    spastic: bool = False,
    shear_stiffness: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(q_p, cuff forces on the exo (4, 2) [N]) minimising the patient's potential energy.

    The straps are closed with both at q_fit; the exoskeleton then stands at
    q_exo.  The patient's frames sit at p_p(q) + o, o aligning the hips, so a
    strap's stretch is Δp - r₀ = p_e(q_exo) - p_e(q_fit) - (p_p(q) - p_p(q_fit)):
    V(q) = Σ m g z + ½ K Σ |stretch|² (+ hypertonia).  No CuffSet involved.
    With ``shear_stiffness`` k_u (q_exo = q_fit only) the stretch is split
    along u (the exo link's joint → cuff direction at q_exo, fixed as the
    exoskeleton stands still) and n: V = Σ m g z + ½ Σ (K (n · s)² + k_u (u · s)²).
    """
    data = patient.model.createData()
    exo_shift = xz_frames(exo, q_exo) - xz_frames(exo, q_fit)
    base = xz_frames(patient, q_fit)
    stiff = np.full((4, 2, 2), np.eye(2) * stiffness)
    if shear_stiffness is not None:
        cuffs = xz_frames(exo, q_exo)
        exo_data = exo.model.createData()
        pin.forwardKinematics(exo.model, exo_data, q_exo)
        for c in range(4):
            joint = exo_data.oMi[exo.joint_ids[c]].translation[[0, 2]]
            u = (cuffs[c] - joint) / np.linalg.norm(cuffs[c] - joint)
            n = np.array([-u[1], u[0]])
            stiff[c] = stiffness * np.outer(n, n) + shear_stiffness * np.outer(u, u)

    def stretch(q: np.ndarray) -> np.ndarray:
        return exo_shift - (xz_frames(patient, q) - base)

    def energy(q: np.ndarray) -> float:
        v = float(pin.computePotentialEnergy(patient.model, data, q))
        s = stretch(q)
        v += 0.5 * float(np.einsum("ci,cij,cj->", s, stiff, s))
        if spastic:
            v += hypertonia(q)[0]
        return v

    best = minimize(energy, q_exo, method="BFGS", options={"gtol": 1e-10, "xrtol": 1e-12})
    q = best.x
    return q, -np.einsum("cij,cj->ci", stiff, stretch(q))


@pytest.mark.parametrize("patient_torque", ["none", "spastic"])
def test_cuff_force_at_t0_is_the_static_equilibrium(
    exo: BodyModel, patient: BodyModel, patient_torque: str
) -> None:
    config = SimConfig(controller="ct", patient_torque=patient_torque, duration_s=1.2)
    setup = build(config)
    start_on_plan(setup)
    plant = setup.plant
    q0, q_p = plant.q[:4].copy(), plant.q[4:].copy()
    assert np.all(plant.v == 0.0)  # at rest
    expected_q, expected_f = independent_equilibrium(
        exo,
        patient,
        q0,
        q0,
        config.true_cuffs.stiffness_N_per_m,
        patient_torque == "spastic",
        config.true_cuffs.shear_stiffness_N_per_m,
    )
    force = plant.cuff_force.copy()
    print(patient_torque, "cuff forces at t = 0 [N]", np.round(np.linalg.norm(force, axis=1), 2))
    np.testing.assert_allclose(force, expected_f, atol=1.0)
    np.testing.assert_allclose(q_p, expected_q, atol=1e-4)
    assert np.min(np.linalg.norm(force, axis=1)) > 20.0  # the patient really hangs in them
    # Neither body accelerates at t = 0: ABA with the cuff forces through Pinocchio's
    # frame Jacobians, the drives' torque and, for the spastic patient, its hypertonia.
    tau_e = plant.drive_torque.copy()
    tau_p = (
        np.zeros(4)
        if patient_torque == "none"
        else -hypertonia(q_p)[1] * (q_p - np.array(SpasticParams().rest_posture_rad))
    )
    for body, q, tau, sign in ((exo, q0, tau_e, 1.0), (patient, q_p, tau_p, -1.0)):
        data = body.model.createData()
        pin.computeJointJacobians(body.model, data, q)
        pin.framesForwardKinematics(body.model, data, q)
        for c, frame in enumerate(body.cuff_frame_ids):
            jac = pin.getFrameJacobian(body.model, data, frame, pin.LOCAL_WORLD_ALIGNED)
            tau = tau + sign * jac[[0, 2]].T @ force[c]
            if body is exo:
                # A split cuff also turns the exo link (cuffs.py): the moment
                # M = σ_n s_u - σ_u s_n = (f·n)(f·u)(1/k_u - 1/k_n) with the fit's r₀ = 0,
                # about -y (θ turns +x towards +z).
                u = xz_frames(exo, q)[c] - data.oMi[exo.joint_ids[c]].translation[[0, 2]]
                u /= np.linalg.norm(u)
                n = np.array([-u[1], u[0]])
                true = config.true_cuffs  # the patient's (scattered) cuffs, the plant's
                k_n, k_u = true.stiffness_N_per_m, true.shear_stiffness_N_per_m
                moment = (force[c] @ n) * (force[c] @ u) * (1.0 / k_u - 1.0 / k_n)
                tau = tau - jac[4] * moment
        acc = pin.aba(body.model, data, q, np.zeros(4), tau)
        np.testing.assert_allclose(acc, 0.0, atol=1e-6)


def test_patient_does_not_accelerate_in_the_first_step_unlike_the_slack_start() -> None:
    accelerations = {}
    for fit in ("equilibrium", "slack"):
        config = SimConfig(controller="ct", sensors=SensorParams.ideal(), cuff_fit=fit)
        runner = Runner(build(config))  # starts the plant (start_on_plan)
        runner.tick(0, 0)
        accelerations[fit] = np.max(np.abs(runner.setup.plant.acceleration[4:]))
    print("patient |q̈| over the first step [rad/s²]", accelerations)
    assert accelerations["equilibrium"] < 0.01
    assert accelerations["slack"] > 100 * accelerations["equilibrium"]


def test_cuff_force_has_no_spike_over_the_first_200_ms(
    runs: dict, exo: BodyModel, patient: BodyModel
) -> None:
    """|f(t) - f(0)| ≤ B per cuff over the first 200 ms, B = ΔF_qs + F_eq / 4.

    In the first 200 ms the ramp has covered S(0.2 / 1.2) = 3.5 % of its way:
    the static equilibrium at the planned posture moves by ΔF_qs (computed
    here, about 0.3 N).  Anything above that is the controllers' start
    transient; a quarter of the smallest equilibrium cuff force F_eq (≈ 8 N,
    1 mm of strap stretch at 8 N/mm) bounds it.  The slack start's drop into
    the straps goes beyond B on every cuff.
    """
    config = SimConfig()
    n = round(WINDOW_S / config.dt)
    assert smoothstep(WINDOW_S / config.ramp_in)[0] < 0.04
    plan = build(config).plan
    k_cuff = config.true_cuffs.stiffness_N_per_m
    f0 = independent_equilibrium(exo, patient, plan.q[0], plan.q[0], k_cuff)[1]
    moved = max(
        np.max(
            np.linalg.norm(
                independent_equilibrium(exo, patient, plan.q[0], plan.q[k], k_cuff)[1] - f0,
                axis=1,
            )
        )
        for k in range(0, n + 1, 50)
    )
    bound = moved + 0.25 * np.min(np.linalg.norm(f0, axis=1))
    print(f"quasi-static change {moved:.3f} N, bound {bound:.2f} N")
    assert moved < 1.0
    for controller, result in runs.items():
        f = result.signals["cuff_force"][:n]
        change = np.max(np.linalg.norm(f - f[0], axis=2), axis=0)
        print(controller, "max |f(t) - f(0)| over 200 ms [N]", np.round(change, 2))
        assert np.all(change <= bound)
    slack = simulate(SimConfig(controller="ct", cuff_fit="slack")).signals["cuff_force"][:n]
    change = np.max(np.linalg.norm(slack - slack[0], axis=2), axis=0)
    print("slack start: max |f(t) - f(0)| over 200 ms [N]", np.round(change, 2))
    assert np.all(change > bound)


def test_equilibrium_that_does_not_exist_is_refused(exo: BodyModel, patient: BodyModel) -> None:
    """A patient torque that jumps across the balance (a relay) leaves Newton no root."""
    setup = build(SimConfig(duration_s=1.2))
    q0 = setup.plan.q[0]

    def relay(t: float, q: np.ndarray, dq: np.ndarray, out: np.ndarray) -> np.ndarray:
        out[:] = np.where(q > q0 - 0.001, -200.0, 200.0)
        return out

    with pytest.raises(InvalidParameter) as info:
        settle_patient(setup.plant.cuffs, patient.model, q0, relay)
    message = str(info.value)
    assert message.startswith(
        "cuff_fit must be 'slack' for cuffs that cannot hold this patient at rest; got "
        "'equilibrium' (no static equilibrium of the patient in the cuffs: Newton's method "
        "left a joint torque residual of "
    )
    assert "stiffer cuffs hold it" in message


def test_start_on_the_gait_at_speed_with_the_patient_settled() -> None:
    """ramp_in_s = 0 with the equilibrium fit: on the gait at speed, the patient in the straps."""
    setup = build(SimConfig(ramp_in_s=0.0, duration_s=1.2))
    start_on_plan(setup)
    plant = setup.plant
    np.testing.assert_array_equal(plant.v[:4], setup.plan.dq[0])
    np.testing.assert_array_equal(plant.v[4:], setup.plan.dq[0])
    assert np.max(np.abs(plant.q[4:] - plant.q[:4])) > 1e-3  # settled, not aligned
    assert np.min(np.linalg.norm(plant.cuff_force, axis=1)) > 20.0


# --------------------------------------------------------------------------- the options


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--ramp-in", "-1"], "--ramp-in: run.ramp_in_s: must be >= 0 s; got -1.0"),
        (["--ramp-in", "nan"], "--ramp-in: run.duration_s: must be a finite number [s]; got nan"),
        (["--ramp-out", "-0.5"], "--ramp-out: run.ramp_out_s: must be >= 0 s; got -0.5"),
        (
            ["--ramp-in", "5", "--duration", "3"],
            "--ramp-in: run.ramp_in_s: must be at most 3 s, within the run; got 5.0 (the run "
            "lasts 3 s)",
        ),
        (
            ["--ramp-in", "2", "--ramp-out", "1.5", "--duration", "3"],
            "--ramp-in: run.ramp_in_s: must be at most 1.5 s, within the run; got 2.0 "
            "(the run lasts 3 s, of which the ramp-out takes the last 1.5 s)",
        ),
        (
            ["--ramp-out", "4", "--duration", "3"],
            "--ramp-out: run.ramp_out_s: must be at most 3 s, within the run; got 4.0 (the run "
            "lasts 3 s)",
        ),
    ],
)
def test_bad_ramp_options_are_refused(
    tmp_path, capsys: pytest.CaptureFixture, args: list, message: str
) -> None:
    code = cli.main(["simulate", *args, "--out", str(tmp_path / "r.rrd")])
    assert code == 2
    assert capsys.readouterr().err == f"exo-ctrl simulate: error: {message}\n"
    assert list(tmp_path.iterdir()) == []


def test_ramp_option_that_is_not_a_number_is_a_usage_error(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as info:
        cli.main(["simulate", "--ramp-in", "soon"])
    assert info.value.code == 2
    assert capsys.readouterr().err.endswith(
        "exo-ctrl simulate: error: argument --ramp-in: invalid float value: 'soon'\n"
    )


@pytest.mark.parametrize(
    ("args", "duration", "ramp_in", "ramp_out"),
    [
        ([], 3.6, 1.2, 0.0),  # ramp-in (one period) + 2 cycles
        (["--cycles", "1", "--ramp-in", "0.5", "--ramp-out", "0.7"], 2.4, 0.5, 0.7),
        (["--ramp-in", "0"], 2.4, 0.0, 0.0),  # the old start: 2 cycles at speed
        (["--duration", "2", "--ramp-out", "0.5"], 2.0, 1.2, 0.5),  # the ramps inside it
    ],
)
def test_cycles_are_counted_after_the_ramp_in(
    args: list, duration: float, ramp_in: float, ramp_out: float
) -> None:
    config = sim_config(cli.build_parser().parse_args(["simulate", *args]))
    assert config.duration_s == pytest.approx(duration, abs=1e-12)
    assert (config.ramp_in, config.ramp_out_s) == pytest.approx((ramp_in, ramp_out), abs=1e-12)
    assert config.cuff_fit == "equilibrium"


def test_a_ramp_in_too_short_for_the_drives_is_refused_naming_it() -> None:
    """The speed check sees the ramp's rows: a 50 ms ramp-in needs knees far beyond the gait's."""
    with pytest.raises(InvalidParameter) as info:
        build(SimConfig(ramp_in_s=0.05))
    message = str(info.value)
    assert message.startswith("planned left_knee speed must be at most ")
    assert message.endswith(
        "of a gait with period 1.2 s and step_length 0.35 m: in its 0.05 s ramp-in: "
        "a longer ramp-in or a shorter step slows it)"
    )
    build(SimConfig(ramp_in_s=0.6))  # half a period is slow enough
