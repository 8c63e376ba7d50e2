"""A configuration's tick as compiled compositions of its stages' kernels (design.md §8).

numba cannot call Pinocchio, so a tick's kernels compose only between its
library calls.  For the PD or CT controller with the Kalman filter or the
momentum observer (the configurations :meth:`FusedTick.of` lists: the
default scenario among them) the tick of :class:`~exo_ctrl.sim.tick.Runner`
is, here:

1. the filter's four Pinocchio calls (CRBA and nonLinearEffects of both
   bodies at its last posterior; the observer's two, on this tick's
   readings, come after the read: :func:`front`, then :func:`rest`);
2. :func:`middle`, one compiled call: the sensors' read; with the belt its
   encoder, the synchronised plan's row, the foot plates and the patient's
   shoes; the filter's step, the measured log row, the PD law, the belt
   monitor and the supervisor's check, the plant's drift and forces (CT on
   the synchronised plan: :func:`front` up to the plan's row, its
   feedforward's two RNEA calls, :func:`rest`);
3. the plant's mid-step (:meth:`~exo_ctrl.plant.Plant.mid_step`: ABA; the
   pelvis's guide, a foot's CRBA and friction impulses);
4. :func:`end`, one compiled call: the plant's kick and the applied log row.

The stages' kernels are called with the arguments, in the order, the
stage-by-stage tick calls them, but for two pieces that touch nothing the
others use: the filter's library calls, on its own state, come before the
sensors' read instead of after it, and the supervisor's cuff-load monitor,
on the readings and its own state, after the plant's drift instead of
before it.  A composed call stops at the first kernel that does
not answer OK, at a check that does not pass (the supervisor's stop) or at a
drive that reaches its current limit, and returns which: the tick then goes
on stage by stage from there, as the stage's own method does.  So the fused
tick is the stage-by-stage tick on every branch, bit for bit
(``tests/sim/test_fused.py``).  The filter's first tick, which starts it,
runs stage by stage.  What it gains: docs/performance.md, "The fused tick".
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from .._jit import check, kernel, preload
from ..control.computed_torque import ComputedTorqueController
from ..control.pd import PDController, pd_command
from ..estimation import CuffForceEstimator, CuffForceKalman
from ..estimation.kalman_step import kalman_step
from ..estimation.observer import observer_step
from ..plan.online import online_step, write_plan
from ..plant.step import drift_and_forces, kick_and_drift
from ..safety import SafetySupervisor
from ..safety.belt_monitor import belt_monitor
from ..safety.tick_check import check_readings
from ..sensing.belt_encoder import belt_tick
from ..sensing.device import read_device
from ..sensing.foot_load import read_foot_load, read_shoe_load
from .log_rows import write_applied, write_measured

__all__ = ["FusedTick", "end", "front", "middle", "rest"]

#: :func:`middle`'s stop codes: the stage that stopped it, times 16, plus its kernel's status.
READ, PLAN, ESTIMATE, COMMAND, CHECK, STOP, DRIFT = 16, 32, 48, 64, 80, 96, 112


class FusedTick:
    """The fused tick of a runner whose configuration it covers (module docstring).

    Build it with :meth:`of` from a :class:`~exo_ctrl.sim.tick.Runner`, which
    says None for a configuration it does not cover; :meth:`tick` then runs
    tick ``k`` into row ``row`` as :meth:`Runner.tick <exo_ctrl.sim.tick.Runner.tick>`
    does, on the runner's stages and log.  It is the runner's own tick,
    composed: it holds the runner's pieces (its stages' records and arrays,
    its log and buffers) as the runner looked them up, and calls back into
    its stage-by-stage tick where a composed call stops.
    """

    def __init__(self, runner: Any) -> None:
        self.runner = runner
        _, self._truth, _, _, _, _ = runner._stages
        self._device = runner._device_sensors
        self._est: CuffForceKalman | CuffForceEstimator = runner.estimator
        #: The observer's library calls are on this tick's readings, after the read.
        self._observer = type(self._est) is CuffForceEstimator
        self._plant = plant = runner.setup.plant
        self._sup = sup = runner.supervisor
        self._ctrl: PDController = runner.setup.controller  # type: ignore[assignment]
        self._library, before, after = self._est.step_arguments()
        self._readings = readings = runner.sensors
        self._foot = runner.foot_load if runner._est_in is not None else None
        self._tau_est = readings.tau if self._foot is None else self._foot.tau_known
        drift, kick = plant.step_arguments()
        self._u = self._ctrl.record["u_cmd"][0]
        self._online = runner._online
        belt: tuple[Any, ...] = (None,) * 7
        feet: tuple[Any, ...] = (None, None)
        if self._foot is not None:
            belt = (
                runner._belt,
                runner._belt_speed,
                runner.belt_encoder.record,
                runner.belt_encoder.speed,
                runner.belt_drive_force,
                None if self._online is None else self._online.record,
                runner._plate_load,
            )
            shoes = plant.record["patient_feet"] if runner._shoes is not None else None
            feet = (self._foot.record, shoes)
        checking: tuple[Any, ...] = (None, np.zeros((4, 2)), np.zeros(4), False, None, None)
        if sup is not None:
            watch = sup.belt.args if sup.belt is not None else None
            force, current = runner._sup_force, runner._current
            checking = (sup.record, force, current, sup.checks, sup.plausibility_record, watch)
        self._front = (
            *self._truth,
            *self._device.read_arguments(),
            *belt,
            runner.log,
            readings.q,
        )
        self._rest = (
            *feet,
            plant.contact.record,
            *before,
            readings.q,
            self._tau_est,
            *after,
            runner.log,
            *runner._measured,
            *self._ctrl.command_arguments(),
            readings.dq,
            readings.tau,
            *checking,
            self._u,
            *drift,
        )
        self._end = (*kick, runner.log)
        self._refresh = runner._refresh
        #: One compiled call before the plant's mid-step: no Python between front and rest.
        self._one_call = self._refresh is None and not self._observer
        self._applied = runner._applied
        self._dt = runner._dt

    @classmethod
    def of(cls, runner: Any) -> FusedTick | None:
        """The fused tick of ``runner``, or None where its configuration is not covered.

        Covered: the PD or CT controller, the Kalman filter or the momentum observer, the
        supervisor or none (reading the estimate unwidened), no faults, one plant step a tick
        without a patient-torque model;
        the belt on or off, the plan synchronised or not (CT's row on the synchronised plan
        takes two RNEA calls between :func:`front` and :func:`rest`), the pelvis fixed or
        supported, the patient's feet on the belt or not.
        """
        setup = runner.setup
        covered = (
            runner.faults is None
            and type(runner.estimator) in (CuffForceKalman, CuffForceEstimator)
            and type(setup.controller) in (PDController, ComputedTorqueController)
            and (runner.supervisor is None or type(runner.supervisor) is SafetySupervisor)
            and runner._stages[5] is not None  # one plant step, no patient-torque model
            and runner._widen is None  # the supervisor reads the estimate as it is
        )
        return cls(runner) if covered else None

    def _library_results(self) -> tuple:
        """The estimator's Pinocchio calls: M and n of both bodies (filter) or M, n (observer)."""
        if self._observer:
            model, data = self._library
            q, dq = self._readings.q, self._readings.dq
            return pin.crba(model, data, q), pin.nonLinearEffects(model, data, q, dq), None, None
        me, de, qe, ve, mp, dp, qp, vp = self._library
        return (
            pin.crba(me, de, qe),
            pin.nonLinearEffects(me, de, qe, ve),
            pin.crba(mp, dp, qp),
            pin.nonLinearEffects(mp, dp, qp, vp),
        )

    def preload(self) -> None:
        """Compile (or load) :func:`middle` and :func:`end` for this run, running neither.

        For the first run's compile helper (:mod:`exo_ctrl.sim.warmup`), after the
        stages' own kernels, which both call.
        """
        library = self._library_results()
        if self._one_call:
            preload(middle, 0, 0.0, 0, *library, *self._front, *self._rest)
        else:
            preload(front, 0, 0, *self._front)
            preload(rest, 0, 0.0, 0, *library, *self._rest)
        acc = np.zeros(self._plant.q.shape[0])
        preload(end, self._plant.record, acc, *self._end, 0, *self._applied)

    def tick(self, k: int, row: int) -> None:
        """Run control tick ``k`` into row ``row`` of the runner's log."""
        runner = self.runner
        if not self._est.started:  # the filter's start: the tick stage by stage
            runner.act(k, row, runner.measure(k, row))
            return
        t = k * self._dt
        if self._one_call:
            code = middle(k, t, row, *self._library_results(), *self._front, *self._rest)
        else:  # CT's feedforward of the synchronised plan's row, or the observer's library
            code = front(k, row, *self._front)
            if not code:
                if self._refresh is not None:
                    self._refresh()
                code = rest(k, t, row, *self._library_results(), *self._rest)
        self._device.refill()
        foot = self._foot
        if foot is not None and foot.record["depleted"][0]:
            foot.draw()
        if code:
            self._resume(code, k, t, row)
            return
        if self._sup is not None:
            runner.after_check(k, self._readings)
        plant = self._plant
        status = end(plant.record, plant.mid_step(), *self._end, row, *self._applied)
        if status:
            plant.kicked(status - 1)
            write_applied(runner.log, row, *self._applied)

    # ------------------------------------------------------------------ the stage path

    def _resume(self, code: int, k: int, t: float, row: int) -> None:
        """Go on stage by stage after :func:`middle` stopped with ``code``."""
        stage, status = code & ~15, code & 15
        runner, readings = self.runner, self._readings
        q, dq, tau = readings.q, readings.dq, readings.tau
        if stage == READ:
            q_true, dq_true, tau_true = self._truth
            check(status, "Sensors.read", q_true=q_true, dq_true=dq_true, tau_true=tau_true)
        elif stage == PLAN:  # the generator's own step raises with the reason
            speed, load = float(runner.belt_encoder.speed[0]), runner._plate_load
            self._online.step(k, speed, q, load)  # type: ignore[union-attr]
        elif stage == ESTIMATE:
            self._est.answer(status, q, self._tau_est)
            write_measured(runner.log, row, *runner._measured)
            runner.act(k, row, readings)
        elif stage == COMMAND:
            self._ctrl.refuse(status, k, q, dq)
        elif stage == CHECK:
            SafetySupervisor.refuse(status, runner._sup_force, q, dq, tau, runner._current, self._u)
        elif stage == STOP:
            u = self._sup.respond(t, readings, runner._sup_force, self._u)  # type: ignore[union-attr]
            runner.after_check(k, readings)
            self._plant.step(u)
            write_applied(runner.log, row, *self._applied)
        else:  # DRIFT: the plant refused its input
            torque = self._plant.patient_torque
            check(status, "Plant.step", voltage_V=self._u, patient_torque_Nm=torque)


@kernel
def front(
    k, row,
    q_true, dq_true, tau_true, joints, current_true, currents, cuff_truth, cuff_sensors, cuff_out,
    belt, belt_speed, encoder, encoder_speed, drive_force, generator, plate_load,
    log, q,
):  # fmt: skip
    """The sensors' read; with the belt its set speed, encoder and drive, the plan's row.

    As :meth:`Runner.measure <exo_ctrl.sim.tick.Runner.measure>` up to the
    synchronised plan's row (``belt`` None: no belt, its arguments unused;
    ``generator`` None: the precomputed plan).  Returns 0, or :data:`READ` or
    :data:`PLAN` plus the status of the kernel that refused.
    """
    s = read_device(
        k, q_true, dq_true, tau_true, joints, current_true, currents, cuff_truth, cuff_sensors,
        cuff_out,
    )  # fmt: skip
    if s != 0:
        return READ + s
    if belt is not None:  # Runner._belt_tick
        belt_tick(encoder, k, belt, belt_speed, drive_force)
        if generator is not None:
            s = online_step(generator, k, encoder_speed[0], q, plate_load)
            if s != 0:
                return PLAN + s
            write_plan(log, row, generator)
    return 0


@kernel
def rest(
    k, t, row, m_e, h_e, m_p, h_p,
    foot, shoes, contact,
    est, cuffs, q, tau_est, split, meas, kalman, h_obs,
    log, plant, readings, estimate, cuff_readings,
    ctrl, q_des, dq_des, u_ff, dq, tau,
    sup, force, current, checks, plausibility, watch,
    u, tau_p, given, s_pelvis, s_contact, s_compliant, s_split, s_feet,
):  # fmt: skip
    """The foot plates, the estimator's step, the measured row, the PD law, the check, the drift.

    The rest of the tick after :func:`front` up to the plant's mid-step, in
    :class:`~exo_ctrl.sim.tick.Runner`'s order (``foot`` None: no belt; ``shoes`` None: the
    patient's feet off it; ``kalman`` True: the Kalman filter; else ``h_obs``: the momentum
    observer's step [s], ``m_e``, ``h_e`` its M(q), n(q, q̇); ``sup`` None: no supervisor;
    ``watch`` None: no belt monitor).  Returns 0 when every kernel answered OK and the check
    passed, else the stage that stopped it (:data:`ESTIMATE` … :data:`DRIFT`) plus its
    status.
    """
    if foot is not None:  # the foot plates (and the patient's shoes, read first)
        if shoes is not None:
            read_shoe_load(foot, shoes)
        read_foot_load(foot, contact, q, tau)
    s = 0  # each estimator's branch pruned where its switch is None (exo_ctrl/_jit.py)
    if kalman is not None:
        s = kalman_step(est, cuffs, m_e, h_e, m_p, h_p, q, tau_est, split, meas)
    if h_obs is not None:
        s = observer_step(est, m_e, h_e, q, dq, tau_est, h_obs)
    if s != 0:
        return ESTIMATE + s
    write_measured(log, row, plant, readings, estimate, cuff_readings)
    s = pd_command(ctrl, q_des, dq_des, u_ff, k, q, dq)
    if s != 0:
        return COMMAND + s
    if sup is not None:
        if watch is not None:
            belt_monitor(watch[0], watch[1], watch[2], watch[3], sup)
        s = check_readings(force, q, dq, tau, current, u, 0.0, t, checks, plausibility, sup)
        if s != 0:
            return CHECK + s
        if not sup[0].passed:
            return STOP
    s = drift_and_forces(plant, u, tau_p, given, s_pelvis, s_contact, s_compliant, s_split, s_feet)
    if s != 0:
        return DRIFT + s
    return 0


@kernel
def middle(
    k, t, row, m_e, h_e, m_p, h_p,
    q_true, dq_true, tau_true, joints, current_true, currents, cuff_truth, cuff_sensors, cuff_out,
    belt, belt_speed, encoder, encoder_speed, drive_force, generator, plate_load,
    log_front, q_front,
    foot, shoes, contact,
    est, cuffs, q, tau_est, split, meas, kalman, h_obs,
    log, plant, readings, estimate, cuff_readings,
    ctrl, q_des, dq_des, u_ff, dq, tau,
    sup, force, current, checks, plausibility, watch,
    u, tau_p, given, s_pelvis, s_contact, s_compliant, s_split, s_feet,
):  # fmt: skip
    """:func:`front` then :func:`rest`, one call (a tick with nothing between them)."""
    s = front(
        k, row, q_true, dq_true, tau_true, joints, current_true, currents, cuff_truth,
        cuff_sensors, cuff_out, belt, belt_speed, encoder, encoder_speed, drive_force, generator,
        plate_load, log_front, q_front,
    )  # fmt: skip
    if s != 0:
        return s
    return rest(
        k, t, row, m_e, h_e, m_p, h_p, foot, shoes, contact, est, cuffs, q, tau_est, split, meas,
        kalman, h_obs, log, plant, readings, estimate, cuff_readings,
        ctrl, q_des, dq_des, u_ff, dq, tau,
        sup, force, current, checks, plausibility, watch,
        u, tau_p, given, s_pelvis, s_contact, s_compliant, s_split, s_feet,
    )  # fmt: skip


@kernel
def end(
    plant,
    acc,
    s_pelvis,
    s_contact,
    s_compliant,
    s_feet,
    log,
    row,
    ctrl,
    sup,
    plant_again,
    encoder,
    phase,
    foot,
):
    """The plant's kick, then the applied row: 0, or 1 + the kick's status where the row waits.

    The row waits for the plant's own answer where the kick did not answer OK
    or a drive reached its current limit (the step kicks again).
    """
    s = kick_and_drift(plant, acc, s_pelvis, s_contact, s_compliant, s_feet)
    if s != 0 or plant[0].resolve:
        return s + 1
    write_applied(log, row, ctrl, sup, plant_again, encoder, phase, foot)
    return 0
