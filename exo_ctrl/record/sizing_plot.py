"""The drives' torque–speed operating points of a run, drawn against the drive's limits.

:class:`OperatingPoints` watches a run (a :class:`~exo_ctrl.sim.SimObserver`)
and keeps, per joint, the joint speed q̇ and the drive torque τ of every
tick (every ``stride``-th past :data:`MAX_POINTS`, so a long run's memory
stays bounded); :func:`write_torque_speed_plot` draws them, one panel per
joint, with the drive's limits at the joint:

- the current limit, |τ| = i_G k_m I_max;
- the supply voltage in steady state, τ = i_G k_m (U_max ∓ (i_G/k_E) q̇) / R
  (the torque the drive can still make against its back-EMF at that
  speed; beyond it the supply is exhausted);
- the URDF's effort limit of the joint.

A drive is large enough for the run when every point lies inside the
envelope with some margin.  matplotlib is needed (``pip install
"exo-ctrl[plots]"``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from .._io import atomic_write
from ..exceptions import MissingDependency
from ..model import JOINT_NAMES
from ..plant import MotorParams
from ..plant.drive import gear_factor

__all__ = ["MAX_POINTS", "OperatingPoints", "write_torque_speed_plot"]

#: Points kept per joint at the most; beyond, every n-th tick.
MAX_POINTS = 20_000

PLOTS_HINT = 'pip install "exo-ctrl[plots]"'


class OperatingPoints:
    """Joint speed and drive torque of a run's ticks (module docstring).

    Attributes:
        speed: joint speeds [rad/s], (N, 4).
        torque: drive torques at the joint [N·m], (N, 4).

    Raises:
        MissingDependency: matplotlib, which draws them, is not installed:
            said before the run, not after it.

    """

    def __init__(self) -> None:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise MissingDependency(
                f"the torque-speed plot needs matplotlib: {PLOTS_HINT}"
            ) from None
        self._speed: list[np.ndarray] = []
        self._torque: list[np.ndarray] = []
        self._stride = 1

    def start(self, result: Any) -> None:
        """Choose the stride so that at most :data:`MAX_POINTS` ticks are kept."""
        self._speed.clear()
        self._torque.clear()
        self._stride = max(1, -(-result.config.n_ticks // MAX_POINTS))

    def chunk(self, result: Any, start: int, rows: dict[str, np.ndarray]) -> None:
        """Keep the chunk's ticks on the stride."""
        first = (-start) % self._stride
        self._speed.append(np.array(rows["dq"][first :: self._stride]))
        self._torque.append(np.array(rows["drive_torque"][first :: self._stride]))

    def finish(self, result: Any) -> None:
        """Nothing to close."""

    @property
    def speed(self) -> np.ndarray:
        """Joint speeds of the kept ticks [rad/s], (N, 4)."""
        return np.concatenate(self._speed) if self._speed else np.zeros((0, 4))

    @property
    def torque(self) -> np.ndarray:
        """Drive torques of the kept ticks [N·m], (N, 4)."""
        return np.concatenate(self._torque) if self._torque else np.zeros((0, 4))


def envelope(motor: MotorParams, speed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The drive's steady-state torque limits at joint speeds ``speed`` [N·m]: (lower, upper).

    The motor's: upper = min(i_G k_m I_max, i_G k_m (U_max − k_b q̇) / R),
    lower likewise with −U_max (k_b = i_G/k_E, the back-EMF per joint
    speed); at the joint each times the gearbox's η^s (η motoring, 1/η
    braking, :func:`exo_ctrl.plant.drive.gear_factor`).
    """
    kt, kb = motor.torque_per_amp_Nm_per_A, motor.back_emf_V_per_rad_s
    cap = kt * motor.current_limit_A
    upper = np.minimum(cap, kt * (motor.supply_voltage_V - kb * speed) / motor.resistance_ohm)
    lower = np.maximum(-cap, kt * (-motor.supply_voltage_V - kb * speed) / motor.resistance_ohm)
    eta = motor.gear_efficiency
    return lower * gear_factor(eta, lower, speed), upper * gear_factor(eta, upper, speed)


def write_torque_speed_plot(
    points: OperatingPoints,
    motor: MotorParams,
    effort_limit_Nm: np.ndarray,
    path: str | os.PathLike[str],
    title: str = "",
) -> Path:
    """Draw the operating points and the drive's limits, one panel per joint, as a PNG.

    Args:
        points: the run's points.
        motor: the drive as it ran (its current limit capped by the URDF's
            effort, :func:`exo_ctrl.sim.drive_for`).
        effort_limit_Nm: the URDF's effort limit per joint [N·m], (4,).
        path: the PNG to write (atomically).
        title: what the figure shows (the scenario).

    Raises:
        MissingDependency: matplotlib is not installed.

    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise MissingDependency(f"the torque-speed plot needs matplotlib: {PLOTS_HINT}") from None
    speed, torque = points.speed, points.torque
    fig, axes = plt.subplots(2, 2, figsize=(11, 8), constrained_layout=True)
    for j, (ax, joint) in enumerate(zip(axes.flat, JOINT_NAMES, strict=True)):
        reach = max(float(np.max(np.abs(speed[:, j]), initial=0.0)) * 1.3, 0.5)
        omega = np.linspace(-reach, reach, 201)
        lower, upper = envelope(motor, omega)
        ax.fill_between(omega, lower, upper, color="0.93", label="drive envelope")
        ax.plot(omega, upper, color="0.3", lw=1.2, label="current / voltage limit")
        ax.plot(omega, lower, color="0.3", lw=1.2)
        effort = float(effort_limit_Nm[j])
        ax.axhline(effort, color="tab:red", ls="--", lw=1, label="URDF effort limit")
        ax.axhline(-effort, color="tab:red", ls="--", lw=1)
        ax.plot(speed[:, j], torque[:, j], ".", ms=2, color="tab:blue", label="operating points")
        ax.set_title(joint.replace("_", " "))
        ax.set_xlabel("joint speed q̇ [rad/s]")
        ax.set_ylabel("drive torque τ [N·m]")
        ax.set_xlim(-reach, reach)
        ax.set_ylim(-1.15 * effort, 1.15 * effort)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=4, frameon=False)
    fig.suptitle(title or "drive torque against joint speed")
    target = Path(path)
    with atomic_write(path, "wb") as handle:  # path, not target: its kind kept
        fig.savefig(handle, format="png", dpi=110)
    plt.close(fig)
    return target
