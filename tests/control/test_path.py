"""Path control with free timing (exo_ctrl/control/modes/path.py): the tunnel, the wall, the phase.

The kernel is checked in isolation on the run's real plan and the device's
exoskeleton model (forward kinematics against the closed-form inverse
kinematics of the plan, the Jacobian against finite differences, the wall's
force against k (d − w)), then in the closed loop with an active patient who
walks 20 % slower than the plan.  Figures are printed (pytest -s).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from exo_ctrl.control.modes import PathParams
from exo_ctrl.control.modes.path import PathController, foot_kinematics, path_command
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import SIDES
from exo_ctrl.plan.kinematics import inverse_kinematics
from exo_ctrl.plant.patient_active import ActiveParams
from exo_ctrl.sim import Runner, SimConfig, build

PARAMS = PathParams(tunnel_width_m=0.03, wall_stiffness_N_per_m=2000.0)
FREE_TORQUE = np.array([5.0, -3.0, 2.0, 1.0])  # the transparent mode's torque [N·m]


@functools.cache
def _setup():
    return build(SimConfig(mode="path", path=PARAMS))


def _controller() -> PathController:
    s = _setup()
    return PathController(PARAMS, s.config.modes, s.plan, s.device_exo, s.device_motor, s.config.dt)


def _q_at(feet: np.ndarray) -> np.ndarray:
    """Joint angles [rad] of the device's legs putting the feet at ``feet`` (2, x/z) [m]."""
    exo = _setup().device_exo
    q = np.empty(4)
    for i, side in enumerate(SIDES):
        g = exo.legs[side]
        p1, p2 = inverse_kinematics(feet[i, 0], feet[i, 1], g.thigh_length, g.shank_length)
        q[2 * i : 2 * i + 2] = g.absolute_to_joint(p1, p2)
    return q


def _wall(ctrl: PathController, row: int, feet: np.ndarray) -> np.ndarray:
    """The kernel's tick at the periodic row ``row`` with the feet at ``feet``; its record."""
    rec = ctrl.record
    rec["in_cycle"] = 0  # the phase starts at the tick's row (tick = row in the period)
    free = ctrl._free.record  # at rest (q̇ = 0, η^s = 1): U = (R / k_t)(τ_free + τ_path)
    free["speed"] = 0.0
    free["tau_free"] = FREE_TORQUE
    assert path_command(rec, free, row, _q_at(feet), ctrl._pos, ctrl._tan) == 0
    return rec[0]


def _stance_row(ctrl: PathController, leg: int) -> int:
    """A periodic row in the middle of ``leg``'s stance (a straight path: z constant)."""
    lead, period = ctrl.plan.lead_ticks, ctrl.plan.period_ticks
    z = ctrl._pos[lead : lead + period, leg, 1]
    flat = np.flatnonzero(np.abs(z - z.min()) < 1e-12)
    return int(flat[len(flat) // 2]) + lead


def _swing_top_row(ctrl: PathController, leg: int) -> int:
    """The periodic row at the top of ``leg``'s swing (the path curves there most)."""
    lead, period = ctrl.plan.lead_ticks, ctrl.plan.period_ticks
    return int(np.argmax(ctrl._pos[lead : lead + period, leg, 1])) + lead


def test_forward_kinematics_and_jacobian_of_the_device_model() -> None:
    """p(q) at the plan's angles is the plan's foot; J = ∂p/∂q by central differences."""
    s = _setup()
    legs = _controller().record[0]
    out, worst_p, worst_j = np.empty(8), 0.0, 0.0
    for row in range(0, s.plan.q.shape[0], 97):
        for leg in range(2):
            qh, qk = s.plan.q[row, 2 * leg], s.plan.q[row, 2 * leg + 1]
            foot_kinematics(legs, leg, qh, qk, 0.0, 0.0, out)
            worst_p = max(worst_p, float(np.abs(out[:2] - s.plan.foot_pos[row, leg]).max()))
            jac = out[4:].reshape(2, 2).T  # rows x/z, columns hip/knee
            h = 1e-6
            for c, (dh, dk) in enumerate(((h, 0.0), (0.0, h))):
                plus, minus = np.empty(8), np.empty(8)
                foot_kinematics(legs, leg, qh + dh, qk + dk, 0.0, 0.0, plus)
                foot_kinematics(legs, leg, qh - dh, qk - dk, 0.0, 0.0, minus)
                fd = (plus[:2] - minus[:2]) / (2 * h)
                worst_j = max(worst_j, float(np.abs(fd - jac[:, c]).max()))
    print(f"\nFK vs plan {worst_p:.2e} m, J vs central differences {worst_j:.2e} m/rad")
    assert worst_p < 1e-9
    assert worst_j < 1e-7


def test_inside_the_tunnel_the_wall_force_is_exactly_zero() -> None:
    """Feet within w of the path: F_wall = 0, τ_path = 0 exactly, U = transparent's."""
    ctrl = _controller()
    lead = ctrl.plan.lead_ticks
    for row in (_stance_row(ctrl, 0), lead + 300, lead + 900):
        feet = ctrl._pos[row].copy()
        tan = ctrl._tan[row]
        feet[:, 0] += 0.9 * PARAMS.tunnel_width_m * -tan[:, 1]  # along the normal
        feet[:, 1] += 0.9 * PARAMS.tunnel_width_m * tan[:, 0]
        rec = _wall(ctrl, row, feet)
        assert np.all(rec["distance"] <= PARAMS.tunnel_width_m)
        assert np.all(rec["wall_force"] == 0.0)
        assert np.all(rec["tau_path"] == 0.0)
        r_over_kt = ctrl._free.record["drive"][0, 0]
        np.testing.assert_array_equal(rec["u_cmd"], r_over_kt * FREE_TORQUE)


@pytest.mark.parametrize("depth", [0.01, 0.05])
def test_a_foot_outside_meets_the_wall_of_its_stiffness(depth: float) -> None:
    """Static foot at d = w + δ: |F| = k δ towards the path, τ = Jᵀ F (virtual work).

    On a stance row the path is straight (exact to rounding); on a swing
    row it curves, and the polyline's nearest point is within 1 %.
    """
    ctrl = _controller()
    k, w = PARAMS.wall_stiffness_N_per_m, PARAMS.tunnel_width_m
    legs = ctrl.record[0]
    for leg, (row, tol) in enumerate(
        ((_stance_row(ctrl, 0), 1e-9), (_swing_top_row(ctrl, 1), 1e-2))
    ):
        feet = ctrl._pos[row].copy()
        normal = np.array([-ctrl._tan[row, leg, 1], ctrl._tan[row, leg, 0]])
        if leg == 0:
            normal = np.array([0.0, -1.0])  # below the stance line: the belt side
        feet[leg] += (w + depth) * normal
        rec = _wall(ctrl, row, feet)
        force = rec["wall_force"][leg]
        expected = k * depth
        print(
            f"\n{SIDES[leg]} row {row}: d = {rec['distance'][leg] * 1e3:.3f} mm, "
            f"|F| = {np.linalg.norm(force):.4f} N, k (d − w) = {expected:.4f} N"
        )
        assert np.linalg.norm(force) == pytest.approx(expected, rel=tol)
        assert force @ normal == pytest.approx(-expected, rel=tol)  # pushes back
        q = _q_at(feet)
        h, tau = 1e-6, np.empty(2)
        for c in range(2):
            dq = np.zeros(2)
            dq[c] = h
            plus, minus = np.empty(8), np.empty(8)
            foot_kinematics(legs, leg, *(q[2 * leg : 2 * leg + 2] + dq), 0.0, 0.0, plus)
            foot_kinematics(legs, leg, *(q[2 * leg : 2 * leg + 2] - dq), 0.0, 0.0, minus)
            tau[c] = force @ (plus[:2] - minus[:2]) / (2 * h)
        np.testing.assert_allclose(
            rec["tau_path"][2 * leg : 2 * leg + 2], tau, rtol=1e-6, atol=1e-6
        )
        other = 1 - leg
        assert np.all(rec["wall_force"][other] == 0.0)
        r_over_kt = ctrl._free.record["drive"][0, 0]
        np.testing.assert_allclose(
            rec["u_cmd"], r_over_kt * (FREE_TORQUE + rec["tau_path"]), rtol=1e-12
        )


def test_path_params_are_checked() -> None:
    with pytest.raises(InvalidParameter, match=r"tunnel_width must be >= 0 m; got -0.01"):
        PathParams(tunnel_width_m=-0.01)
    with pytest.raises(InvalidParameter, match=r"search_window must be in \(0, 0.5\]"):
        PathParams(search_window=0.7)
    with pytest.raises(InvalidParameter, match="path control follows the phase"):
        SimConfig(mode="path", gait=SimConfig().gait.__class__(period=1.2345))


def test_the_phase_follows_a_patient_who_walks_20_percent_slower() -> None:
    """The device's phase advances at 1/1.2 of the plan's rate with a 1.2× slower patient.

    A healthy active patient whose own period is 1.44 s against the plan's
    1.2 s (same step).  Over the settled ticks (3.0 s to the end of a 7.2 s
    run: the 1.2 s ramp-in and a cycle to settle) the phase advances by
    Δσ / Δk rows per tick; expected 1 / 1.2 = 0.833 within 5 % (the
    patient's cycle time varies 2 % step to step, ActiveParams.period_cv).
    The same patient at the plan's period: 1.00 within 2 %.  The supervisor
    never stops the device.
    """
    rates = {}
    for ratio in (1.2, 1.0):
        config = SimConfig(
            mode="path",
            path=PARAMS,
            patient_torque="active",
            patient_active=ActiveParams(period_s=1.2 * ratio),
            duration_s=7.2,
        )
        setup = build(config)
        runner = Runner(setup)
        rec = setup.controller.record
        start, progress, outside = round(3.0 / config.dt), 0, 0
        for k in range(config.n_ticks):
            runner.tick(k, k % runner.chunk)
            if k == start:
                progress = int(rec["progress"][0])
            if k >= start:
                outside += int(np.any(rec["distance"][0] > PARAMS.tunnel_width_m))
        n = config.n_ticks - 1 - start
        rates[ratio] = (int(rec["progress"][0]) - progress) / n
        print(
            f"\npatient period {1.2 * ratio:.2f} s: phase rate {rates[ratio]:.4f} rows/tick "
            f"(expected {1 / ratio:.4f}), feet outside the tunnel {100 * outside / n:.1f} % "
            "of the ticks"
        )
        assert runner.supervisor.state == "normal"
        assert not runner.supervisor.events
    assert rates[1.2] == pytest.approx(1 / 1.2, rel=0.05)
    assert rates[1.0] == pytest.approx(1.0, rel=0.02)
