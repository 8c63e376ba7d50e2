"""The online gait generator: the paper's path at a steady speed, C¹ feet, stance at belt speed."""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.model import load_exo
from exo_ctrl.plan import GaitParams, GaitPlan, OnlineGait, SpeedAdaptation, plan_joints
from exo_ctrl.plan.online import FILTER_S
from exo_ctrl.plan.phase_curves import phase_rate
from exo_ctrl.plan.profile import SpeedProfile

DT = 1e-3


@pytest.fixture(scope="module")
def exo():
    return load_exo(None)


def run(gen: OnlineGait, speeds: np.ndarray) -> dict[str, np.ndarray]:
    """Step ``gen`` with the measured speeds, collecting its row per tick."""
    out = {n: [] for n in ("q", "dq", "ddq", "pos", "vel")}
    for k, v in enumerate(speeds):
        gen.step(k, float(v))
        p = gen.plan
        for name, arr in zip(out, (p.q, p.dq, p.ddq, p.foot_pos, p.foot_vel), strict=True):
            out[name].append(arr[0].copy())
    return {n: np.array(a) for n, a in out.items()}


def test_at_a_steady_measured_speed_it_is_the_papers_plan(exo) -> None:
    gait = GaitParams()
    gen = OnlineGait(SpeedAdaptation(gait), None, exo, DT)
    n = 3000
    got = run(gen, np.full(n, gait.belt_speed))
    ref = plan_joints(GaitPlan(gait), exo, np.arange(n) * DT)
    np.testing.assert_allclose(got["pos"], ref.foot_pos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["vel"], ref.foot_vel, rtol=0, atol=1e-11)
    np.testing.assert_allclose(got["q"], ref.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["dq"], ref.dq, rtol=0, atol=1e-11)
    # accelerations jump at touchdown and lift-off: equal except on those ticks
    bad = np.flatnonzero(np.abs(got["ddq"] - ref.ddq).max(axis=1) > 1e-8)
    boundaries = np.round(np.array([0.3, 0.9]) / DT).astype(int)  # B and D of the 1.2 s cycle
    assert np.all(np.isin(bad % 600, boundaries % 600)), bad


def test_the_phase_rate_derivative_matches_finite_differences() -> None:
    law = SpeedAdaptation(GaitParams(), max_step_m=0.5).kernel_params()
    for v in (0.3, 0.7, 1.5):  # below the cap and on it
        r, dr = phase_rate(law, v, 1.0)  # ṙ for v̇ = 1 m/s²
        h = 1e-6
        fd = (phase_rate(law, v + h, 0.0)[0] - phase_rate(law, v - h, 0.0)[0]) / (2 * h)
        assert dr == pytest.approx(fd, rel=1e-7)
        assert 1.0 / r == pytest.approx(SpeedAdaptation(GaitParams(), 0.5).period(v), rel=1e-14)


def measured_run(exo, dt: float) -> tuple[OnlineGait, dict, np.ndarray, np.ndarray]:
    """0.4 to 0.7 m/s over 3 s after a 1.2 s ramp-in, measured with dips and quantised."""
    gait = GaitParams()
    profile = SpeedProfile.parse("1.2:0.4,4.2:0.7")
    gen = OnlineGait(SpeedAdaptation(gait), profile, exo, dt, ramp_in_s=1.2)
    t = np.arange(round(5.4 / dt)) * dt
    v_set = np.array([gen.belt_speed(tk)[0] for tk in t])
    # the set speed slowed by a load at every touchdown, quantised to the encoder's 3.8 mm/s
    dip = 0.02 * np.exp(-np.mod(t, 0.6) / 0.1)
    measured = np.round((v_set - dip) / 0.0038) * 0.0038
    return gen, run(gen, measured), measured, v_set


def test_feet_stay_c1_and_the_stance_foot_moves_at_the_measured_speed(exo) -> None:
    gait = GaitParams()
    _, got, measured, v_set = measured_run(exo, DT)
    _, fine, _, _ = measured_run(exo, DT / 2)
    pos, vel = got["pos"], got["vel"]
    n = pos.shape[0]
    t = np.arange(n) * DT
    # C1: the position's differences are the mean velocity over the tick, and
    # the largest velocity change in a tick halves with the tick (a jump would not)
    fd = np.diff(pos, axis=0) / DT
    mid = 0.5 * (vel[1:] + vel[:-1])
    jump = np.abs(np.diff(vel, axis=0)).max()
    jump_fine = np.abs(np.diff(fine["vel"], axis=0)).max()
    print(
        f"finite differences vs velocity: max {np.abs(fd - mid).max() * 1e3:.2f} mm/s; "
        f"largest velocity change in a tick {jump * 1e3:.1f} mm/s at 1 ms, "
        f"{jump_fine * 1e3:.1f} mm/s at 0.5 ms"
    )
    assert np.abs(fd - mid).max() < 5e-3
    assert jump_fine < 0.6 * jump
    assert jump < 0.05
    # stance: moving back at the measured speed low-passed over FILTER_S, with the lag
    # the same filter puts on the set speed added back
    stance = np.isclose(pos[:, :, 1], -gait.hip_height, rtol=0, atol=1e-12)
    vbar, vset_bar = np.empty(n), np.empty(n)
    vbar[0] = vset_bar[0] = v_set[0]
    for k in range(1, n):
        vbar[k] = vbar[k - 1] + (measured[k] - vbar[k - 1]) * DT / (FILTER_S + DT)
        vset_bar[k] = vset_bar[k - 1] + (v_set[k] - vset_bar[k - 1]) * DT / (FILTER_S + DT)
    lead = vbar + (v_set - vset_bar)
    # on the profile's ramp (a = 0.1 m/s²) the added lag is τ_f a
    on_ramp = (t > 2.0) & (t < 4.2)
    np.testing.assert_allclose((v_set - vset_bar)[on_ramp], FILTER_S * 0.1, rtol=1e-6)
    both = np.broadcast_to(lead[:, None], (n, 2))
    np.testing.assert_allclose(-vel[:, :, 0][stance], both[stance], rtol=0, atol=1e-12)
    err = (-vel[:, :, 0] - v_set[:, None])[stance & (t[:, None] > 1.2)]
    print(f"stance foot vs the belt's set speed: RMS {1e3 * np.sqrt(np.mean(err**2)):.2f} mm/s")
    # the step adapts: the last whole stance covers the law's step at 0.7 m/s (the
    # measured speed's dip makes it shorter: the stance covers what the belt does)
    edges = np.flatnonzero(np.diff(stance[:, 0].astype(int)))
    if not stance[edges[-1], 0]:  # the run ends in a stance: take the one before
        edges = edges[:-1]
    start, end = edges[-2] + 1, edges[-1] + 1  # its touchdown and lift-off ticks
    covered = pos[start, 0, 0] - pos[end - 1, 0, 0]
    law = SpeedAdaptation(gait).step_length(0.7)
    print(f"last stance covers {covered:.4f} m; the law's step at 0.7 m/s {law:.4f} m")
    assert covered == pytest.approx(law, rel=0.03)
