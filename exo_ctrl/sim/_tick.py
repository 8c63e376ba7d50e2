"""The control tick of a PD, CT or QP run in three compiled calls.

:meth:`exo_ctrl.sim.loop.Runner.tick` composes the stages through their
public methods — sensors, estimator, controller, supervisor, plant, logging
— about a dozen calls from Python a tick, each a compiled kernel or a
Pinocchio call with some Python around it.  For the common configuration (a
PD, computed-torque or QP controller, one plant step per tick, no
patient-torque model) :class:`FusedTick` runs the same kernels in the same order in three
compiled calls between the Pinocchio calls:

- :func:`_sense`: the sensors' read;
- :func:`_front`, after the estimator's (and the QP cuff model's) Pinocchio
  calls: the observer step, the log of the measured state, the PD (+
  feedforward) voltage, the QP up to proxsuite
  (:func:`~exo_ctrl.control.qp.controller._qp_step`), the supervisor's monitor and the
  plant's first half-step;
- :func:`_back`, after the plant's ABA: its second half-step and the log of
  what was applied.

Same kernels, same arguments, same order: a fused run is bit-identical to a
composed one (tests/test_simulate.py).  The calls take the buffers they work
on as one table of addresses (:func:`exo_ctrl._jit.address_table`, rows
:data:`_ROWS`), built with the fused tick: passed one by one, their 40
arrays would cost about 5 µs of dispatch a tick.  The Pinocchio calls'
results are read where Pinocchio leaves them (its data's ``M``, ``nle``,
``ddq``).  Where the composed tick branches into Python — the estimator's
first update or a new step length, a supervisor that is stopping or sees a
violation, a QP tick that must call proxsuite — the tick goes on along the
composed path from that stage, so the rare branches exist once.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from .._jit import address_table, kernel, matrix_at, tensor_at, vector_at
from ..control import ComputedTorqueController, PDController, QPController
from ..control.pd import pd_volts
from ..control.qp.controller import _QP_INFO, _qp_step
from ..control.qp.prediction import _pair
from ..estimation.observer import _observer_kernel
from ..plant.plant import MAX_JOINT_SPEED_RAD_S, _drift_and_forces, _kick_and_drift
from ..safety.supervisor import _monitor_kernel
from ..sensing.sensors import _read_kernel

if TYPE_CHECKING:
    from .loop import Runner

#: What :func:`_front` returns.
_DONE, _SUPERVISOR, _ARMATURE = 0, 1, 2

#: The rows of the address table, in order.
_ROWS = (
    # h_est, h_plant [s], supervised, force transposed, Δt [s], e-stop time [s],
    # QP (0/1), the plan's period in ticks (0: none),
    # feedforward per plan row (CT, QP: 1; PD: 0)
    "params",
    "q_true", "dq_true", "tau_true", "noise", "sensor",  # the sensors' read
    "q_all", "v_all",  # the QP cuff model's paired state
    "mass", "nle",  # the estimator's Pinocchio data: M, n = C q̇ + g
    "q", "dq", "tau",  # the sensor readings
    "est", "wide", "state", "readings", "estimates",
    "u", "gains", "q_des", "dq_des", "u_ff", "force_est", "cmd", "last_row",
    "force", "current", "sup",
    "s8", "s4", "losses", "patient_torque", "cuff_m", "cuff_p", "cuff_out",
    "motor_p", "motor_s", "outputs", "acc",
)  # fmt: skip
(
    _PARAMS, _Q_TRUE, _DQ_TRUE, _TAU_TRUE, _NOISE, _SENSOR, _Q_ALL, _V_ALL, _MASS, _NLE,
    _Q, _DQ, _TAU, _EST, _WIDE, _STATE, _READINGS, _ESTIMATES, _U, _GAINS, _Q_DES, _DQ_DES, _U_FF,
    _FORCE_EST, _CMD, _LAST_ROW,
    _FORCE, _CURRENT, _SUP, _S8, _S4, _LOSSES, _PATIENT_TORQUE, _CUFF_M, _CUFF_P,
    _CUFF_OUT, _MOTOR_P, _MOTOR_S, _OUTPUTS, _ACC,
) = range(len(_ROWS))  # fmt: skip


class FusedTick:
    """The fused tick of a runner (module docstring); build it with :meth:`of`."""

    def __init__(self, runner: Runner, table: np.ndarray, arrays: list[np.ndarray]) -> None:
        setup = runner.setup
        self.runner = runner
        plant, est = setup.plant, runner.estimator
        self._plant = plant
        self._ctrl = setup.controller
        self._est = est
        self._sup = runner.supervisor
        self._sensor_model = runner.sensor_model
        self._sensors = runner.sensors
        q, dq = runner.sensors.q, runner.sensors.dq
        # CuffForceEstimator.model_terms, into the table's mass and nle.
        self._est_terms = ((est._model, est._data, q), (est._model, est._data, q, dq))
        self._aba = plant._aba
        self._flags = plant._flags
        plant._flags[2] = False  # no patient torque, here and in the composed ticks
        self._table = table
        self._arrays = arrays  # the table's memory, alive as long as the table
        # Whether the estimator runs at the control period (it starts in the
        # first composed ticks and stays so) and the supervisor is in its
        # normal state (it never returns to it); the kernel adds the e-stop time.
        self._running = False
        self._normal = True
        ctrl = self._ctrl
        self._cmd = arrays[_CMD]
        # The QP's own table and its cuff model's Pinocchio terms (PD, CT: unused stand-ins).
        self._qp = isinstance(ctrl, QPController)
        if self._qp:
            self._qp_args = (ctrl.table, ctrl._powers)
            model = ctrl.cuff_model
            self._cuff_terms = (model._model, model._data, model._q_all, model._v_all)
        else:
            self._qp_args = (np.zeros((1, 4), dtype=np.int64), np.zeros(1, dtype=np.int64))
        #: Ticks whose plant step ran fused (the others went on composed).
        self.ticks = 0

    @classmethod
    def of(cls, runner: Runner) -> FusedTick | None:
        """The fused tick of ``runner``, or None if its configuration needs the composed one."""
        setup = runner.setup
        ctrl, plant, est, sup = setup.controller, setup.plant, runner.estimator, runner.supervisor
        if not (
            type(ctrl) in (PDController, ComputedTorqueController, QPController)
            and runner._substeps == 1
            and runner.patient_model is None
            and plant.motors is not None
        ):
            return None
        if sup is None:
            force, current, sup_work = np.zeros((4, 2)), np.zeros(4), np.zeros(1)  # unused
        else:
            force = runner.sensors.cuff_force_est if sup.use_estimate else plant.cuff_force
            current, sup_work = runner._mean_current, sup._work
        # A transposed force view (the plant's) is stored as its contiguous transpose.
        transposed = not force.flags.c_contiguous
        u_ff = getattr(ctrl, "_u_ff", ctrl._no_ff.reshape(1, 4))
        estop_s = np.inf if sup is None else sup._estop
        qp = isinstance(ctrl, QPController)
        params = np.array(
            [
                est.dt,
                plant.dt,
                sup is not None,
                transposed,
                runner._dt,
                estop_s,
                qp,
                ctrl.plan.period_ticks or 0,
                isinstance(ctrl, ComputedTorqueController),
            ]
        )
        sensor_model = runner.sensor_model
        arrays = dict(
            params=params,
            q_true=runner._q_e,
            dq_true=runner._v_e,
            tau_true=plant.sensor_torque,
            noise=sensor_model._noise,
            sensor=sensor_model._work,
            q_all=ctrl.cuff_model._q_all if qp else np.zeros(8),
            v_all=ctrl.cuff_model._v_all if qp else np.zeros(8),
            mass=est._data.M.T,  # column-major, symmetric (crba fills both halves)
            nle=est._data.nle,
            q=runner.sensors.q,
            dq=runner.sensors.dq,
            tau=runner.sensors.tau,
            est=est._work,
            wide=runner.wide,
            state=runner._measured[0],
            readings=runner._measured[1],
            estimates=runner._measured[2],
            u=ctrl._u,
            gains=ctrl._gains,
            q_des=ctrl.plan.q,
            dq_des=ctrl.plan.dq,
            u_ff=u_ff,
            force_est=runner.sensors.cuff_force_est,
            cmd=ctrl._out if qp else ctrl._u,
            last_row=ctrl._last_row,
            force=force.T if transposed else force,
            current=current,
            sup=sup_work,
            s8=plant._s8,
            s4=plant._s4,
            losses=plant._losses,
            patient_torque=plant.patient_torque,
            cuff_m=plant._pre_more[0],
            cuff_p=plant._pre_more[1],
            cuff_out=plant._pre_more[2],
            motor_p=plant._pre_more[3],
            motor_s=plant._pre_more[4],
            outputs=plant.outputs,
            acc=plant._data.ddq,
        )
        ordered = [arrays[name] for name in _ROWS]
        return cls(runner, address_table(ordered), ordered)

    def tick(self, k: int, row: int) -> bool:
        """Run tick k into buffer row ``row``; False (nothing done) if it must be composed.

        The estimator must have started at the control period (after the
        first composed ticks).
        """
        est = self._est
        if not self._running:
            self._running = est.running_at(est.dt)
            if not self._running:
                return False
        if _sense(self._table, k) == 2:  # the noise block is used up
            self._sensor_model.draw()
        crba_args, nle_args = self._est_terms
        pin.crba(*crba_args)
        pin.nonLinearEffects(*nle_args)
        ctrl = self._ctrl
        if self._qp:  # CuffHorizonModel.terms, the state paired by _sense: into the QP table
            m, d, q_all, v_all = self._cuff_terms
            pin.crba(m, d, q_all)
            pin.nonLinearEffects(m, d, q_all, v_all)
        code = _front(self._table, *self._qp_args, k, row, self._normal, self._flags)
        plant = self._plant
        if code < 0:  # the QP goes on in Python (proxsuite, a fallback): composed from here
            u = ctrl.resume(code, self._sensors.dq)
            self.runner._log_qp(row)
            self.runner._apply(k, row, self._sensors, u)
            self._normal = self._sup is None or self._sup.state_code == 0
            return True
        if code == _SUPERVISOR:  # the supervisor acts: composed from here
            self.runner._apply(k, row, self._sensors, self._cmd)
            self._normal = self._sup.state_code == 0
            return True
        # From here as the end of Plant.step.
        if code == _ARMATURE:
            plant._model.armature = plant._arm
        pin.aba(*self._aba)  # into the table's acc
        plant.t += plant.dt
        speed2 = _back(self._table, row, self._flags)
        self.ticks += 1
        if not speed2 < MAX_JOINT_SPEED_RAD_S**2:
            plant._diverged()
        return True


@kernel
def _sense(t, k):
    """The sensors' read of tick k (:func:`~exo_ctrl.sensing.sensors._read_kernel`, its return).

    For the QP also the readings paired for its cuff model's Pinocchio terms
    (:meth:`~exo_ctrl.control.qp.prediction.CuffHorizonModel.terms`).
    """
    taken = _read_kernel(
        k, vector_at(t, _Q_TRUE), vector_at(t, _DQ_TRUE), vector_at(t, _TAU_TRUE),
        tensor_at(t, _NOISE), vector_at(t, _SENSOR),
    )  # fmt: skip
    if vector_at(t, _PARAMS)[6] != 0.0:
        _pair(vector_at(t, _Q), vector_at(t, _DQ), vector_at(t, _Q_ALL), vector_at(t, _V_ALL))
    return taken


@kernel
def _front(t, qp_table, powers, k, row, normal, flags):
    """Observer, log of the measured state, PD voltage, QP, monitor, plant half-step (module doc).

    ``t`` is the address table (rows :data:`_ROWS`), ``flags`` the plant's;
    ``qp_table`` and ``powers`` the QP's (:func:`~exo_ctrl.control.qp.controller._qp_step`);
    ``normal``: the supervisor is in its normal state (the e-stop time is
    checked here, as :meth:`~exo_ctrl.safety.supervisor.SafetySupervisor.normal_at`).
    Returns the QP's negative code (the plant untouched) when the QP must go
    on in Python; 1 (the plant untouched) when the supervisor must act — not
    in its normal state, or a violation; else 2 if the plant's armature
    changed, else 0.
    """
    params = vector_at(t, _PARAMS)
    q, dq, tau = vector_at(t, _Q), vector_at(t, _DQ), vector_at(t, _TAU)
    wide, u = matrix_at(t, _WIDE), vector_at(t, _U)
    _observer_kernel(
        matrix_at(t, _MASS), vector_at(t, _NLE), q, dq, tau, params[0], vector_at(t, _EST)
    )
    _log_measured(
        wide, row, vector_at(t, _STATE), vector_at(t, _READINGS), vector_at(t, _ESTIMATES)
    )
    period = int(params[7])
    plan_row = k % period if period else k  # PDController.plan_row
    vector_at(t, _LAST_ROW)[0] = plan_row
    u_ff = matrix_at(t, _U_FF)[plan_row if params[8] != 0.0 else 0]
    gains, q_des, dq_des = matrix_at(t, _GAINS), matrix_at(t, _Q_DES), matrix_at(t, _DQ_DES)
    pd_volts(u, gains, q_des, dq_des, plan_row, q, dq, u_ff)
    if params[6] != 0.0:
        active = _qp_step(qp_table, powers, q, dq, u, matrix_at(t, _FORCE_EST), True)
        if active < 0:
            return active
        info = vector_at(qp_table, _QP_INFO)  # as Runner._log_qp
        wide[row, 81] = info[0]
        wide[row, 82] = info[4]
    cmd = vector_at(t, _CMD)
    if params[2] != 0.0:
        normal = normal and k * params[4] < params[5]
        current, sup = vector_at(t, _CURRENT), vector_at(t, _SUP)
        force = matrix_at(t, _FORCE)
        if params[3] != 0.0:
            worst = _monitor_kernel(force.T, q, dq, tau, current, cmd, normal, sup)
        else:
            worst = _monitor_kernel(force, q, dq, tau, current, cmd, normal, sup)
        if not (normal and worst <= 0.0):
            return _SUPERVISOR
        wide[row, 52] = 0.0  # the supervisor's state code: normal
    changed = _drift_and_forces(
        params[1], matrix_at(t, _S8), matrix_at(t, _S4), matrix_at(t, _LOSSES), flags, cmd,
        vector_at(t, _PATIENT_TORQUE), matrix_at(t, _CUFF_M), vector_at(t, _CUFF_P),
        matrix_at(t, _CUFF_OUT), vector_at(t, _MOTOR_P), matrix_at(t, _MOTOR_S),
    )  # fmt: skip
    return _ARMATURE if changed else _DONE


@kernel
def _back(t, row, flags):
    """The plant's second half-step and the log of what was applied; returns |v⁺|²."""
    outputs = vector_at(t, _OUTPUTS)
    speed2 = _kick_and_drift(
        vector_at(t, _PARAMS)[1], matrix_at(t, _S8), matrix_at(t, _S4), vector_at(t, _ACC),
        flags, matrix_at(t, _MOTOR_S), matrix_at(t, _CUFF_OUT), outputs,
    )  # fmt: skip
    _log_applied(matrix_at(t, _WIDE), row, vector_at(t, _CMD), outputs)
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
