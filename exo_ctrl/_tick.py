"""The control tick of a PD or CT run in two compiled calls around the ABA.

:meth:`exo_ctrl.simulate.Runner.tick` composes the stages through their
public methods — sensors, estimator, controller, supervisor, plant, logging
— about a dozen calls from Python a tick, each a compiled kernel or a
Pinocchio call with some Python around it.  For the common configuration (a
PD or computed-torque controller, one plant step per tick, no patient-torque
model) :class:`FusedTick` runs the same kernels in the same order in two
compiled calls:

- :func:`_front`, after the sensor read and the estimator's Pinocchio calls:
  the observer step, the log of the measured state, the PD (+ feedforward)
  voltage, the supervisor's monitor and the plant's first half-step;
- :func:`_back`, after the plant's ABA: its second half-step and the log of
  what was applied.

Same kernels, same arguments, same order: a fused run is bit-identical to a
composed one (tests/test_simulate.py).  Where the composed tick branches
into Python — the estimator's first update or a new step length, a
supervisor that is stopping or sees a violation — the tick goes on along
the composed path from that stage, so the rare branches exist once.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ._jit import kernel
from .control import ComputedTorqueController, PDController
from .control.pd import pd_volts
from .estimation import _observer_kernel
from .plant import MAX_JOINT_SPEED_RAD_S, _drift_and_forces, _kick_and_drift
from .safety import _monitor_kernel

if TYPE_CHECKING:
    from .simulate import Runner

#: What :func:`_front` returns.
_DONE, _SUPERVISOR, _ARMATURE = 0, 1, 2


class FusedTick:
    """The fused tick of a runner (module docstring); build it with :meth:`of`."""

    def __init__(self, runner: Runner) -> None:
        setup = runner.setup
        self.runner = runner
        plant, ctrl, est = setup.plant, setup.controller, runner.estimator
        self._plant = plant
        self._ctrl = ctrl
        self._est = est
        self._sup = sup = runner.supervisor
        self._read = runner.sensor_model.read
        self._read_args = (runner._q_e, runner._v_e, plant.sensor_torque)
        if sup is None:
            self._sup_args = (np.zeros((4, 2)), np.zeros(4))  # unused
        else:
            force = runner.sensors.cuff_force_est if sup.use_estimate else plant.cuff_force
            self._sup_args = (force, runner._mean_current)
        self._sup_work = sup._work if sup is not None else np.zeros(1)
        self._est_args = (est.dt, est._work, runner.wide)
        self._measured = runner._measured
        self._pd_args = (ctrl._u, ctrl._gains, ctrl.plan.q, ctrl.plan.dq)
        self._plant_args = plant._pre_args[1:]
        self._plant_more = (plant.patient_torque, *plant._pre_more)
        self._aba = plant._aba
        plant._flags[2] = False  # no patient torque, here and in the composed ticks
        self._back_args = (plant._s8, plant._s4)
        self._back_more = (plant._flags, *plant._post_more, runner.wide, ctrl._u)
        #: Ticks run fused (the others went the composed way).
        self.ticks = 0

    @classmethod
    def of(cls, runner: Runner) -> FusedTick | None:
        """The fused tick of ``runner``, or None if its configuration needs the composed one."""
        ctrl = runner.setup.controller
        fits = (
            type(ctrl) in (PDController, ComputedTorqueController)
            and runner._substeps == 1
            and runner.patient_model is None
            and runner.setup.plant.motors is not None
        )
        return cls(runner) if fits else None

    def tick(self, k: int, row: int) -> bool:
        """Run tick k into buffer row ``row``; False (nothing done) if it must be composed.

        The estimator must have started at the control period (after the
        first composed tick).
        """
        est = self._est
        if not est.running_at(est.dt):
            return False
        sensors = self._read(k, *self._read_args)
        q, dq = sensors.q, sensors.dq
        mass, coriolis, gravity = est.model_terms(q, dq)
        ctrl = self._ctrl
        plan_row, u_ff = ctrl.feedforward(k)
        runner = self.runner
        sup = self._sup
        normal = sup is None or sup.normal_at(k * runner._dt)
        plant = self._plant
        h_est, est_work, wide = self._est_args
        code = _front(
            mass, coriolis, gravity, q, dq, sensors.tau, h_est, est_work,
            wide, row, *self._measured,
            *self._pd_args, plan_row, u_ff,
            sup is not None, *self._sup_args, normal, self._sup_work,
            plant.dt, *self._plant_args, *self._plant_more,
        )  # fmt: skip
        if code == _SUPERVISOR:  # the supervisor acts: composed from here
            runner._apply(k, row, sensors, ctrl._u)
            return True
        # From here as the end of Plant.step.
        if code == _ARMATURE:
            plant._model.armature = plant._arm
        acc = pin.aba(*self._aba)
        plant.t += plant.dt
        speed2 = _back(plant.dt, *self._back_args, acc, *self._back_more, row)
        self.ticks += 1
        if not speed2 < MAX_JOINT_SPEED_RAD_S**2:
            plant._diverged()
        return True


@kernel
def _front(
    mass, coriolis, gravity, q, dq, tau, h_est, est_work,
    wide, row, state, readings, estimates,
    u, gains, q_des, dq_des, plan_row, u_ff,
    supervised, force, current, normal, sup_work,
    h, s8, s4, losses, flags, patient_torque, cuff_m, cuff_p, cuff_out, motor_p, motor_s,
):  # fmt: skip
    """Observer, log of the measured state, PD voltage, monitor, plant half-step (module doc).

    Returns 1 (the plant untouched) when the supervisor must act — not in its
    normal state, or a violation — else 2 if the plant's armature changed,
    else 0.  Inputs are the runner's own buffers, of the kernels' shapes.
    """
    _observer_kernel(mass, coriolis, gravity, q, dq, tau, h_est, est_work)
    _log_measured(wide, row, state, readings, estimates)
    pd_volts(u, gains, q_des, dq_des, plan_row, q, dq, u_ff)
    if supervised:
        worst = _monitor_kernel(force, q, dq, tau, current, u, normal, sup_work)
        if not (normal and worst <= 0.0):
            return _SUPERVISOR
        wide[row, 52] = 0.0  # the supervisor's state code: normal
    changed = _drift_and_forces(
        h, s8, s4, losses, flags, u, patient_torque, cuff_m, cuff_p, cuff_out, motor_p, motor_s
    )
    return _ARMATURE if changed else _DONE


@kernel
def _back(h, s8, s4, acc, flags, motor_s, cuff_out, outputs, wide, u, row):
    """The plant's second half-step and the log of what was applied; returns |v⁺|²."""
    speed2 = _kick_and_drift(h, s8, s4, acc, flags, motor_s, cuff_out, outputs)
    _log_applied(wide, row, u, outputs)
    return speed2


@kernel
def _log_measured(
    wide: np.ndarray, row: int, state: np.ndarray, readings: np.ndarray, estimates: np.ndarray
) -> None:
    """Columns 0-15 (q, v of both bodies) and 53-80 (readings, estimates) of a log row."""
    for i in range(16):
        wide[row, i] = state[i]
        wide[row, 65 + i] = estimates[i]
    for i in range(12):
        wide[row, 53 + i] = readings[i]


@kernel
def _log_applied(wide: np.ndarray, row: int, u_cmd: np.ndarray, outputs: np.ndarray) -> None:
    """Columns 16-19 (commanded voltage) and 20-43 (the plant's outputs) of a log row."""
    for i in range(4):
        wide[row, 16 + i] = u_cmd[i]
    for i in range(24):
        wide[row, 20 + i] = outputs[i]
