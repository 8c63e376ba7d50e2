"""The QP controller in the closed loop: tracking, the bound within its stated margin, fallbacks.

The default 2.4 s scenario through :func:`exo_ctrl.sim.loop.simulate`,
default sensors (so the estimated cuff forces feed the QP), safety
supervisor off; the real cuff forces are the plant's elastic cuffs'.  Each
configuration is simulated once per module.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.control.qp import stated_margin
from exo_ctrl.plant import CuffParams
from exo_ctrl.sim import SimConfig, SimResult, simulate

#: The QP may track worse than CT by at most this, per joint (brief: 5 %),
#: where no bound binds.
RMS_TOLERANCE = 0.05

#: The hips' RMS error over CT's where the torque box binds (measured 1.6).
HIP_BOX_TOLERANCE = 1.8
#: A bound below CT's peak on the default run (≈ 106 N with the default sensors) [N].
F_TIGHT = 80.0
#: Stated margin of the real (elastic) cuff force over F_TIGHT on the passive run:
#: measured 87.6 N (+9.5 %, left shank; CT 104.6 N), asserted at 15 %.  The
#: error budget of the compliant prediction (the horizon model's ≤ 4.6 N given
#: the true cuff state, below, plus the cuff state reconstructed from a force
#: estimate lagging 5 ms after the controller's lead–lag) is absolute, so at
#: 80 N it is a larger fraction than at 150 N.
TIGHT_MARGIN = 0.15
#: The spastic scenario's bound [N] and its stated margin at the default 1.2 s
#: gait with the run's estimator (the default, the Kalman filter) and the
#: nominal patient, (5.5 N + 13.8 N + 1.5 N) / 150 N = 13.9 %
#: (exo_ctrl.control.qp.margin; the grid of gaits: test_load_held.py).
#: Measured 154.1 N (+2.7 %; CT 180.7 N); 157.6 N (+5.1 %) with the
#: momentum observer and the true patient model.
F_SPASTIC = 150.0
SPASTIC_MARGIN = stated_margin(1.2, F_SPASTIC, SimConfig().estimator)
#: URDF effort of every joint [N·m].
EFFORT = 150.0


def _run(**kwargs) -> SimResult:
    # The QP's cuff model is isotropic: its stated margins hold for such cuffs
    # (the default split cuffs cost them, reported in the QP's docstring).
    kwargs.setdefault("cuffs", CuffParams.isotropic())
    return simulate(SimConfig(safety=False, **kwargs))


@pytest.fixture(scope="module")
def ct_passive() -> SimResult:
    return _run(controller="ct")


@pytest.fixture(scope="module")
def qp_passive() -> SimResult:
    return _run(controller="qp")  # default cuff_force_limit_N = 120 N


@pytest.fixture(scope="module")
def qp_tight() -> SimResult:
    return _run(controller="qp", cuff_force_limit_N=F_TIGHT)


@pytest.fixture(scope="module")
def ct_spastic() -> SimResult:
    return _run(controller="ct", patient_torque="spastic")


@pytest.fixture(scope="module")
def qp_spastic() -> SimResult:
    return _run(controller="qp", cuff_force_limit_N=F_SPASTIC, patient_torque="spastic")


def rms(result: SimResult) -> np.ndarray:
    return np.array(list(result.summary()["rms_tracking_error_rad"].values()))


def peak_force(result: SimResult) -> np.ndarray:
    return np.array(list(result.summary()["peak_cuff_force_N"].values()))


def describe(name: str, result: SimResult) -> str:
    s = result.summary()
    torque = np.array(list(s["peak_drive_torque_Nm"].values()))
    return (
        f"{name}: {result.status}, RMS error {np.round(rms(result) * 1e3, 3)} mrad, "
        f"peak cuff force {np.round(peak_force(result), 1)} N, "
        f"peak drive torque {np.round(torque, 1)} N·m, {s['qp_failures']} fallbacks"
    )


def test_closed_loop_qp_tracks_as_well_as_ct(ct_passive, qp_passive) -> None:
    print(f"\n{describe('ct', ct_passive)}\n{describe('qp 120 N', qp_passive)}")
    assert ct_passive.status == qp_passive.status == "completed"
    assert qp_passive.qp_failures == 0
    # The knees: no bound binds, the QP's answer is the CT command.  The hips
    # pass through zero speed at 110–130 N·m, near the joint's 150 N·m effort
    # once the gearbox's 1/η of a braking joint is counted from the measured
    # speed's sign: the QP holds them in the box where CT's command goes
    # beyond it (the plant's current limit then caps CT).  Measured: hips
    # 0.92/0.76 mrad against CT's 0.58/0.53, knees equal.
    qp, ct = rms(qp_passive), rms(ct_passive)
    assert np.all(qp[[1, 3]] <= (1.0 + RMS_TOLERANCE) * ct[[1, 3]])
    assert np.all(qp[[0, 2]] <= HIP_BOX_TOLERANCE * ct[[0, 2]])
    # The cuff bound is not binding on this run: the peak is CT's, within 5 %
    # (the hips' box lowers it by 4 %).
    np.testing.assert_allclose(peak_force(qp_passive), peak_force(ct_passive), rtol=0.05)


def test_closed_loop_tight_bound_stays_within_the_stated_margin(ct_passive, qp_tight) -> None:
    peak = peak_force(qp_tight)
    print(
        f"\n{describe(f'qp {F_TIGHT:g} N', qp_tight)}\n"
        f"peak {peak.max():.1f} N = bound + {100 * (peak.max() / F_TIGHT - 1):.1f} % "
        f"(stated margin {100 * TIGHT_MARGIN:.0f} %); ct peak {peak_force(ct_passive).max():.1f} N"
    )
    assert qp_tight.status == "completed"
    assert np.all(np.isfinite(rms(qp_tight)))
    assert np.all(peak <= F_TIGHT * (1.0 + TIGHT_MARGIN))
    # Fallbacks are counted, in the summary and in the logged signal alike.
    assert qp_tight.summary()["qp_failures"] == qp_tight.qp_failures
    assert qp_tight.signals["qp_failures"][-1] == qp_tight.qp_failures


def test_closed_loop_tight_bound_lowers_the_peak_below_cts(ct_passive, qp_tight) -> None:
    assert peak_force(qp_tight).max() < peak_force(ct_passive).max() - 10.0


def test_closed_loop_tight_bound_needs_no_fallback(qp_tight) -> None:
    assert qp_tight.qp_failures == 0


@pytest.mark.parametrize(
    "run", ["ct_passive", "qp_passive", "qp_tight", "ct_spastic", "qp_spastic"]
)
def test_closed_loop_no_drive_torque_beyond_the_urdf_effort(request, run) -> None:
    result = request.getfixturevalue(run)
    peak = np.abs(result.signals["drive_torque"]).max()
    print(f"\n{run}: peak drive torque {peak:.3f} N·m")
    assert peak <= EFFORT + 1e-9


def test_closed_loop_spastic_patient_pushes_ct_beyond_the_bound(ct_spastic) -> None:
    print(f"\n{describe('ct spastic', ct_spastic)}")
    assert ct_spastic.status == "completed"
    assert peak_force(ct_spastic).max() > F_SPASTIC


def test_closed_loop_spastic_patient_qp_completes_and_counts_its_fallbacks(qp_spastic) -> None:
    summary = qp_spastic.summary()
    print(
        f"\n{describe(f'qp {F_SPASTIC:g} N spastic', qp_spastic)}; peak = "
        f"bound + {100 * (peak_force(qp_spastic).max() / F_SPASTIC - 1):.1f} %"
    )
    assert qp_spastic.status == "completed"
    assert np.all(np.isfinite(rms(qp_spastic)))
    assert isinstance(summary["qp_failures"], int) and summary["qp_failures"] >= 0
    assert summary["qp_failures"] == qp_spastic.qp_failures
    assert qp_spastic.signals["qp_failures"][-1] == qp_spastic.qp_failures
    assert np.all(np.diff(qp_spastic.signals["qp_failures"]) >= 0)


def test_closed_loop_spastic_patient_qp_keeps_the_bound_within_the_margin(qp_spastic) -> None:
    assert peak_force(qp_spastic).max() <= F_SPASTIC * (1.0 + SPASTIC_MARGIN)
