"""The torque-speed plot of a run: its points are the run's, inside the drive's envelope."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import cli
from exo_ctrl.model import load_exo
from exo_ctrl.plant import MotorParams
from exo_ctrl.record import sizing_plot
from exo_ctrl.record.sizing_plot import OperatingPoints, envelope, write_torque_speed_plot
from exo_ctrl.sim import SimConfig, drive_for, simulate


def test_the_points_are_the_runs_and_inside_the_current_limit(tmp_path: Path) -> None:
    config = SimConfig(duration_s=0.5, chunk_ticks=70)
    points = OperatingPoints()
    result = simulate(config, observers=[points])
    np.testing.assert_array_equal(points.speed, result.signals["dq"])
    np.testing.assert_array_equal(points.torque, result.signals["drive_torque"])
    exo = load_exo(None)
    motor = drive_for(config.motor, exo)
    lower, upper = envelope(motor, points.speed)
    assert np.all(points.torque <= upper + 1e-9) and np.all(points.torque >= lower - 1e-9)
    path = write_torque_speed_plot(points, motor, exo.effort_limit, tmp_path / "ts.png", "pd")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_long_run_keeps_at_most_max_points(monkeypatch) -> None:
    monkeypatch.setattr(sizing_plot, "MAX_POINTS", 100)
    points = OperatingPoints()
    result = simulate(SimConfig(duration_s=0.45, chunk_ticks=70), observers=[points])
    n = len(points.speed)
    assert 90 <= n <= 100  # every 5th of the 450 ticks
    np.testing.assert_array_equal(points.speed, result.signals["dq"][::5])


def test_the_envelope_is_the_current_and_the_voltage_limit() -> None:
    motor = MotorParams()
    kt, kb, r = motor.torque_per_amp_Nm_per_A, motor.back_emf_V_per_rad_s, motor.resistance_ohm
    # Voltage-bound, below the no-load speed: half the current limit's R I is left.
    fast = (motor.supply_voltage_V - 0.5 * r * motor.current_limit_A) / kb
    lower, upper = envelope(motor, np.array([0.0, fast]))
    eta = motor.gear_efficiency
    # At rest the gearbox passes the motor's torque whole; moving forward the
    # joint gets η of a forward torque (motoring) and 1/η of a backward one (braking).
    assert upper[0] == pytest.approx(kt * motor.current_limit_A, rel=1e-12)
    assert lower[0] == -upper[0]
    assert upper[1] == pytest.approx(eta * kt * (motor.supply_voltage_V - kb * fast) / r, rel=1e-9)
    assert lower[1] == pytest.approx(-kt * motor.current_limit_A / eta, rel=1e-9)


def test_the_cli_writes_the_plot_into_an_existing_directory(tmp_path: Path, capsys) -> None:
    argv = ["simulate", "--duration", "0.05", "--no-record", "--plots", str(tmp_path)]
    assert cli.main(argv) == 0
    assert (tmp_path / "torque_speed.png").read_bytes()[:4] == b"\x89PNG"
    missing = tmp_path / "no_such_dir"
    assert cli.main([*argv[:-1], str(missing)]) == 2
    err = capsys.readouterr().err
    assert f"--plots must be a writable file in an existing directory; got '{missing}" in err
    assert not missing.exists()
