"""Guidance's force loop: its own first-order low-pass, and the closed loop it keeps bounded.

Guidance (0 < G < 1) low-passes the cuff-force estimate it feeds back, so
that the Kalman filter and the momentum observer give the same forces; the
measurements are in :mod:`exo_ctrl.control.modes.controller`'s module
docstring.  The figures are printed (pytest -s) as well as checked.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from exo_ctrl.control import PDController
from exo_ctrl.control.modes import InteractionController, ModeParams
from exo_ctrl.plant.patient_active import ActiveParams
from exo_ctrl.sensing.readings import SensorReadings
from exo_ctrl.sim import SimConfig, build, simulate

#: The healthy active patient of tests/sim/test_modes_run.py: their own 1.0 s,
#: 0.30 m gait against the plan's 1.2 s, 0.35 m.  Their cycles and the plan's
#: beat with a period of 1 / (1/1.0 - 1/1.2) = 6 s, so the forces swell and
#: ebb over 6 s even when the loop is bounded: seconds [1, 2) and [7, 8) are
#: the same phase of the beat.
HEALTHY = ActiveParams(period_s=1.0, step_length_m=0.30)
EARLY, LATE = (1.0, 2.0), (7.0, 8.0)
#: force_filter_hz that makes the low-pass's step weight 1 in double precision: no filter.
UNFILTERED_HZ = 1e9


@pytest.fixture(scope="module")
def setup():
    return build(SimConfig(duration_s=3.0))


def _mode(setup, mode: str, **params) -> InteractionController:
    tracking = PDController(setup.plan, setup.config.gains) if mode == "guidance" else None
    return InteractionController(
        mode,
        ModeParams(**params),
        setup.plan,
        setup.device_exo,
        setup.device_motor,
        tracking=tracking,
        dt=setup.config.dt,
    )


@pytest.mark.parametrize(
    ("mode", "g"), [("guidance", 0.3), ("guidance", 0.0), ("guidance", 1.0), ("transparent", 0.0)]
)
def test_guidance_low_passes_the_fed_back_torque(setup, mode: str, g: float) -> None:
    """A step of the estimated force: K_f τ_lp in τ_free, τ_lp = τ̂ (1 - (1 - α)^n).

    α = 1 - exp(-2π f_f Δt) for guidance with 0 < G < 1; elsewhere no
    filter (α = 1): transparent, and guidance at G = 0 or 1.
    """
    f_f, dt = 8.0, setup.config.dt
    k0 = 1500
    row = setup.plan.row(k0)
    q, dq = setup.plan.q[row].copy(), setup.plan.dq[row].copy()
    force = np.array([[30.0, -20.0], [10.0, 40.0], [-25.0, 5.0], [15.0, -35.0]])
    no_lead = {"force_lead_s": 0.0}  # transparent's lead: tests/control/test_modes.py
    ctrl = _mode(setup, mode, guidance=g, force_filter_hz=f_f, **no_lead)
    ref = _mode(setup, mode, guidance=g, force_filter_hz=f_f, **no_lead)
    zero = SensorReadings(q=q, dq=dq, tau=np.zeros(4), cuff_force_est=np.zeros((4, 2)))
    step = SensorReadings(q=q, dq=dq, tau=np.zeros(4), cuff_force_est=force)
    ctrl.command(k0, zero)
    ref.command(k0, zero)
    filtered = 0.0 < g < 1.0 and mode == "guidance"
    alpha = 1.0 - math.exp(-2.0 * math.pi * f_f * dt) if filtered else 1.0
    kf = np.asarray(ModeParams().force_gain_for(mode))  # the Kalman filter's (the default)
    for n in range(1, 60):
        ctrl.command(k0, step)
        ref.command(k0, zero)
        est = ctrl.record["tau_int_est"][0]
        want = est * (1.0 - (1.0 - alpha) ** n)
        np.testing.assert_allclose(ctrl.record["tau_int_lp"][0], want, rtol=1e-12, atol=1e-12)
        diff = ctrl.record["tau_free"][0] - ref.record["tau_free"][0]
        np.testing.assert_allclose(diff, kf * want, rtol=1e-9, atol=1e-9)
    assert np.all(np.abs(est) > 1.0)  # the step reached every joint


@functools.cache
def _run(estimator: str, g: float, filter_hz: float | None = None):
    modes = (
        ModeParams(guidance=g)
        if filter_hz is None
        else ModeParams(guidance=g, force_filter_hz=filter_hz)
    )
    config = SimConfig(
        mode="guidance",
        modes=modes,
        patient_torque="active",
        patient_active=HEALTHY,
        safety=False,
        estimator=estimator,
        duration_s=8.0,
    )
    return simulate(config)


def _rms(result, span: tuple[float, float]) -> float:
    """RMS over the span's ticks of the four true cuff forces' magnitudes [N]."""
    m = (result.t >= span[0]) & (result.t < span[1])
    return float(np.sqrt(np.mean(np.sum(result.signals["cuff_force"][m] ** 2, axis=-1))))


def _per_second(result) -> list[float]:
    return [_rms(result, (s, s + 1.0)) for s in range(8)]


@pytest.mark.parametrize("g", [0.1, 0.25, 0.4])
def test_guidance_stays_bounded_with_the_kalman_filter(g: float) -> None:
    """The true cuff forces at the same phase of the beat, 6 s apart: no growth (within 15 %).

    Before the filter (the loop fed the Kalman estimate unfiltered) the
    late second was 2.4 times the early one at G = 0.25
    (:func:`test_the_unfiltered_loop_grows`).
    """
    r = _run("kalman", g)
    early, late = _rms(r, EARLY), _rms(r, LATE)
    print(
        f"\nG = {g}, kalman: RMS true force per second [N] "
        + " ".join(f"{x:.0f}" for x in _per_second(r))
        + f"; late/early {late / early:.2f}"
    )
    assert late < 1.15 * early


def test_guidance_forces_do_not_depend_on_the_estimator() -> None:
    """With the loop's own filter the Kalman filter and the observer give the same forces.

    Second by second within 10 % + 2 N (their estimates differ by their
    noise and lag, the loop no longer by its bandwidth).
    """
    k, m = _per_second(_run("kalman", 0.25)), _per_second(_run("momentum", 0.25))
    print(
        "\nG = 0.25, RMS true force per second [N]: kalman "
        + " ".join(f"{x:.0f}" for x in k)
        + "; momentum "
        + " ".join(f"{x:.0f}" for x in m)
    )
    np.testing.assert_allclose(k, m, rtol=0.1, atol=2.0)


def test_the_unfiltered_loop_stays_bounded() -> None:
    """Fed the Kalman estimate unfiltered, guidance no longer grows.

    The same run as above at G = 0.25 with the filter's step weight 1.  The
    growth once measured here (2.4× from the 2nd to the 8th second, at 5-6 Hz)
    came from the patient's reflex damping acting 60 ms late; with the
    intrinsic damping acting at once (:mod:`exo_ctrl.plant.patient_active`)
    the late second is within 15 % of the early one (measured 1.07×) and the
    3-9 Hz share of the cuff forces does not rise.
    """
    r = _run("kalman", 0.25, UNFILTERED_HZ)
    early, late = _rms(r, EARLY), _rms(r, LATE)

    def band(span):
        m = (r.t >= span[0]) & (r.t < span[1])
        x = r.signals["cuff_force"][m].reshape(int(m.sum()), -1)
        x = x - x.mean(axis=0)
        spec = np.abs(np.fft.rfft(x * np.hanning(len(x))[:, None], axis=0)) ** 2
        freq = np.fft.rfftfreq(len(x), r.config.dt)
        return float(spec[(freq >= 3.0) & (freq <= 9.0)].sum()), float(spec.sum())

    (b0, t0), (b1, t1) = band(EARLY), band(LATE)
    print(
        "\nG = 0.25, kalman, unfiltered: RMS true force per second [N] "
        + " ".join(f"{x:.0f}" for x in _per_second(r))
        + f"; late/early {late / early:.2f}; 3-9 Hz share {b0 / t0:.2f} -> {b1 / t1:.2f}"
    )
    assert late < 1.15 * early
    assert b1 / t1 <= b0 / t0
