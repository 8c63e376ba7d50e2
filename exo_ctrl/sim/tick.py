"""The control tick: sensors → estimator → controller → supervisor → plant → log.

One control tick k at t_k = k Δt: the sensors read the plant, the estimator
updates the cuff-force estimate, the controller turns the plan's row k and
the readings into drive voltages, the safety supervisor passes or replaces
them, and the plant advances by Δt (in ``plant_substeps`` equal steps) with
the voltages held.  Each stage is called through its public per-tick
method, a compiled kernel or a Pinocchio call with little Python around it;
the rare branches (the supervisor stopping, a QP tick that calls proxsuite)
are ordinary branches inside those methods.  Where the configuration allows,
the same stages' kernels run composed into two compiled calls between the
library calls (:mod:`exo_ctrl.sim.fused`; bit for bit the same tick).

The tick writes row ``row`` of a structured log array whose fields are the
declared signals (:mod:`exo_ctrl.sim.schema`), by name, from the stages'
records, in two compiled calls (:mod:`exo_ctrl.sim.log_rows`):
:func:`write_measured` (the state at t_k and what the device measured and
estimated) before the command, and :func:`write_applied` (the command, what
acted over [t_k, t_k+1), the belt, the feet and the pelvis) after the plant
step.

**Cost.**  A compiled call costs its dispatch, about 0.3 µs plus 0.05 µs per
array argument and 0.17 µs per record argument on these machines, and a
Python attribute lookup some 0.03 µs: the tick looks its stages' methods and
the log kernels' arguments up once, in the constructor, and kernels that
always run back to back are one call.
"""

from __future__ import annotations

import numpy as np

from .._jit import record
from ..control.modes.path import PathController
from ..estimation import CuffForceEstimator, CuffForceKalman, EstimatorDevice, PluginEstimator
from ..plan.online import online_step, write_plan
from ..plant import CuffParams, CuffSet, PatientTorque
from ..safety import SafetySupervisor
from ..safety.cuff_load import CuffLoadMonitor, cuff_load_schedule
from ..safety.unseen import AlongWidening
from ..sensing import (
    BeltEncoder,
    CuffSensors,
    CurrentSensor,
    DeviceSensors,
    FootLoad,
    SensorReadings,
    Sensors,
)
from ..sensing.belt_encoder import belt_tick
from .faults import FaultInjector
from .fused import FusedTick
from .log_rows import write_applied, write_measured
from .schema import log_dtype
from .setup import Setup, patient_torque_for, start_on_plan
from .supervision import build_supervisor, departure_for
from .tone_load import unseen_along_N

__all__ = [
    "UNTIMED_TICKS",
    "Runner",
    "write_applied",
    "write_measured",
]

#: Ticks at the start of a run left out of its wall time: they load (or,
#: after an install, compile) the compiled kernels.
UNTIMED_TICKS = 3

#: The record of an absent supervisor: state 0 (normal) throughout.
_NO_SUPERVISOR = [("state", np.float64)]

#: The phase record of a controller other than ``path``: row -1 throughout.
_NO_PHASE = [("row", np.int64)]


class Runner:
    """Runs the ticks of a :class:`~exo_ctrl.sim.setup.Setup` into a chunk of log rows.

    :meth:`tick` is the whole per-tick work of a run (sensors, estimator,
    controller, safety supervisor, patient torque, plant steps, logging);
    ``tools/bench.py`` times exactly it.

    Attributes:
        log: the chunk, a structured array of :func:`~exo_ctrl.sim.schema.log_dtype`
            with ``chunk`` rows.
        buf: signal name → view of its field in :attr:`log`.

    Args:
        setup: the run's pieces.
        start: put the plant on the plan's first row (:func:`~exo_ctrl.sim.setup.start_on_plan`);
            False only for :mod:`exo_ctrl.sim.warmup`'s helper, which compiles and never runs
            (nor loads the cuff-load monitor's kernels ahead).
        fuse: run the tick as compiled compositions of the stages' kernels where the
            configuration allows (:mod:`exo_ctrl.sim.fused`; equal to the stage-by-stage
            tick, bit for bit); False: stage by stage always.

    """

    def __init__(self, setup: Setup, start: bool = True, fuse: bool = True) -> None:
        self.setup = setup
        config = setup.config
        plant = setup.plant
        self.chunk = min(config.chunk_ticks, max(config.n_ticks, 1))
        self.log = np.zeros(self.chunk, dtype=log_dtype())
        self.buf = {name: self.log[name] for name in self.log.dtype.names}
        self.sensor_model = Sensors(config.sensors, config.dt)
        #: The cuffs' force sensors (sensing/cuff_load.py; read only with a sensor set).
        self.cuff_sensors = CuffSensors(config.cuff_sensors, config.dt)
        self.estimator: CuffForceEstimator | CuffForceKalman | PluginEstimator
        if setup.estimator is not None:  # a user's (estimation/plugin.py)
            device = EstimatorDevice(setup.device_exo, setup.device_patient, config.dt)
            self.estimator = PluginEstimator(setup.estimator, device)
        elif config.estimator == "kalman":  # the coupled model's filter (estimation/kalman.py)
            self.estimator = CuffForceKalman(
                setup.device_exo,
                setup.device_patient,
                config.dt,
                cuffs=config.belief.cuff_model_of(config.cuffs),
                sensors=config.sensors,
                cuff_sensors=self.cuff_sensors,
            )
        else:
            self.estimator = CuffForceEstimator(
                setup.device_exo,
                config.dt,
                config.observer_gain_per_s,
                stiffness_ratio=config.cuff_stiffness_ratio,
            )
        tune = getattr(setup.controller, "tune_estimator", None)
        if tune is not None:  # a mode's tuning of the estimator (transparent: the filter's σ_d)
            tune(self.estimator)
        self.sensors = self.sensor_model.readings
        self.sensors.cuff_force_est = self.estimator.force  # filled in place
        self.sensors.cuff_force_std = getattr(self.estimator, "force_std", None)
        #: The foot plates' load cells, and the patient's shoes' with their feet on the
        #: belt (sensing/foot_load.py; read with the belt only).
        shoes = plant.record["patient_feet"] if config.contact.patient_feet else None
        self.foot_load = FootLoad(config.foot_load, setup.device_exo, shoes)
        self._shoes = None if shoes is None else self.foot_load.belt_force[2:]
        #: The belt-speed sensor (read each tick with contact on).
        self.belt_encoder = BeltEncoder(config.belt_encoder, config.dt)
        self._belt = plant.contact.belt
        #: The treadmill drive's report of its force [N], (1,) (copied each tick with contact on).
        self.belt_drive_force = np.zeros(1)
        self._belt_speed = setup.belt_speed  # the set speed per tick (None: contact off)
        if setup.belt_speed is not None:
            self.sensors.belt_speed = self.belt_encoder.speed
        self._substeps = config.plant_substeps
        self._dt = config.dt
        self.patient_model: PatientTorque | None = patient_torque_for(config, setup.patient)
        self._tau_p = np.zeros(4)
        self._q_p, self._v_p = plant.q[4:], plant.v[4:]
        self._q_e, self._v_e = plant.q[:4], plant.v[:4]
        #: The drives' current sensors (the supervisor's current readings), read
        #: with the joints' sensors at the start of the tick (sensing/device.py).
        self.current_sensor = CurrentSensor(config.current_sensor)
        bind = getattr(setup.controller, "bind_driver", None)
        if bind is not None:  # a user's torque controller: the drivers take its current references
            bind(*plant.motors.current_command)
        self._device_sensors = DeviceSensors(
            self.sensor_model,
            self.current_sensor,
            plant.motors.mean_current_A,
            self.cuff_sensors,
            plant.record["cuffs"],
        )
        #: The QP's departure stop (safety/departure.py; None: none), checked before
        #: the supervisor on the plan row the controller tracked.
        self._departure = departure_for(config, setup.device_exo)
        self.supervisor: SafetySupervisor | None = build_supervisor(
            self, setup, bind is not None, self._departure is not None
        )
        sup = self.supervisor
        #: The supervisor's patient-load monitor (safety/cuff_load.py; None: off the whole
        #: run), run on its normal ticks; its warnings go to the supervisor's events.
        self.cuff_load: CuffLoadMonitor | None = None
        schedule = cuff_load_schedule(config.mode, config.modes.guidance, config.session)
        if config.safety and not all(why for _, why in schedule):
            period, tau_ext = config.gait.period, self.estimator.tau_ext
            self.cuff_load = CuffLoadMonitor(
                setup.device_patient, tau_ext, config.dt, period, schedule, shoes=self._shoes
            )
            if start:  # (the helper leaves these kernels to the run's own process)
                self.cuff_load.preload(self.sensors.q, self.sensors.dq)
        if self._departure is not None and start:
            self._departure.preload(self.sensors.q)
        #: On a stop the harness locks the pelvis (plant/pelvis.py) and the treadmill
        #: runs down to rest (BeltParams.stop_decel_mps2): :meth:`_device_stop`.
        self._stop_pending = sup is not None and config.contact.enabled
        self._sup_force = None
        #: The estimate widened by what the device cannot see (safety_widen; None: off).
        self._widen: AlongWidening | None = None
        if sup is not None:
            # The estimate, as on the device; the plant's true forces only
            # when asked for (the ideal comparison: a force sensor per cuff).
            self._sup_force = self.sensors.cuff_force_est if sup.use_estimate else plant.cuff_force
            if config.safety_widen:
                cuffs = CuffSet(setup.device_exo, setup.device_patient, CuffParams())
                self._widen = AlongWidening(cuffs.select, cuffs.along0, unseen_along_N(config))
                self._sup_force = self._widen.out
        #: The run's fault injector (:mod:`exo_ctrl.sim.faults`; None: no faults).
        self.faults: FaultInjector | None = None
        if config.faults:
            self.faults = FaultInjector(
                config.faults,
                config.dt,
                config.n_ticks,
                config.sensors.velocity_filter_hz,
                plant.record["motors"] if plant.motors is not None else None,
                plant.record["cuffs"],
                self._belt if setup.belt_speed is not None else None,
            )
        self._records = (
            plant.record,
            self.sensor_model.record if self.faults is None else self.faults.record,
            self.estimator.record,
            setup.controller.record,
            sup.record if sup is not None else record(_NO_SUPERVISOR),
        )
        #: The online gait generator (synchronised plan; None: precomputed).
        self._online = setup.online
        #: The foot plates' vertical loads [N] (a view: the last reading).
        self._plate_load = self.foot_load.belt_force[:2, 1]
        self._refresh = getattr(setup.controller, "refresh_row", None) if setup.online else None
        #: The path mode's record, whose phase ``row`` the tick logs (``path_phase``);
        #: other controllers: a record whose row is -1.
        ctrl = setup.controller
        self._phase = ctrl.record if isinstance(ctrl, PathController) else record(_NO_PHASE)
        if not isinstance(ctrl, PathController):
            self._phase["row"] = -1
        # The estimator reads the device's readings (faulted or not: the same arrays
        # every tick); with the belt the torque sensors' reading plus the load cells'
        # joint torque.
        src = self.faults.readings if self.faults is not None else self.sensors
        self._est_in: SensorReadings | None = None
        if config.contact.enabled:
            self._est_in = SensorReadings(src.q, src.dq, self.foot_load.tau_known)
            self._contact_rec = plant.record["contact"]
        est_in = self._est_in if self._est_in is not None else src
        if start:
            start_on_plan(setup)
        # The stages' per-tick methods and arguments, looked up once.
        self._stages = (
            self._device_sensors.read,
            (self._q_e, self._v_e, plant.sensor_torque),
            self.estimator.bind(est_in),
            setup.controller.command,
            sup.step if sup is not None else None,
            plant.step if self.patient_model is None and self._substeps == 1 else None,
        )
        #: The log kernels' record arguments (after the log and the row).
        plant_rec, sensor_rec, est_rec, ctrl_rec, sup_rec = self._records
        self._measured = (plant_rec, sensor_rec, est_rec, self.cuff_sensors.readings)
        self._applied = (
            ctrl_rec,
            sup_rec,
            plant_rec,
            self.belt_encoder.record,
            self._phase,
            self.foot_load.record,
        )
        self._current = self.current_sensor.current
        #: The fused tick (:mod:`exo_ctrl.sim.fused`; None: stage by stage).
        self.fused = FusedTick.of(self) if fuse else None

    def tick(self, k: int, row: int) -> None:
        """Run control tick ``k``, logging into row ``row`` of :attr:`log`."""
        if self.fused is not None:
            self.fused.tick(k, row)
        else:
            self.act(k, row, self.measure(k, row))

    def measure(self, k: int, row: int) -> SensorReadings:
        """Tick ``k``'s first half: the sensors read, the estimate made, row ``row`` begun.

        Returns the readings the controller gets (:meth:`act`'s argument).
        """
        read, truth, estimate = self._stages[:3]
        readings = read(k, *truth)
        if self.faults is not None:
            readings = self.faults.readings_at(k, readings)
        if self._belt_speed is not None:  # the plan's landing places on the device's encoders
            self._belt_tick(k, row, readings.q)
        if self._est_in is not None:  # the feet's load, known from the foot plates
            self.foot_load.read(self._contact_rec, readings.q, readings.tau)
        estimate()  # on this tick's readings (or the faulted device's, with the feet's load)
        write_measured(self.log, row, *self._measured)
        return readings

    def act(self, k: int, row: int, readings: SensorReadings) -> None:
        """Tick ``k``'s second half: command, supervisor, plant steps, row ``row`` ended."""
        command, supervise, step = self._stages[3:]
        u = command(k, readings)
        age = 0.0
        faults = self.faults
        if faults is not None:
            u, age = faults.command_at(k, u)
        if self._departure is not None and self.supervisor is not None:
            ctrl = self.setup.controller  # the QP: the plan row it tracked, its bounds
            plan, r = ctrl.plan, ctrl.last_row
            cause = self._departure.check(
                k * self._dt, readings.q, readings.dq, plan.q[r], plan.dq[r]
            )
            if cause is not None:
                # the yield feeds the cuff forces back, its gains set from the bounds
                self.supervisor.request_stop(k * self._dt, cause, "yield", ctrl.cuff_limits_N)
        if supervise is not None:
            if self._widen is not None:
                self._widen(self.sensors.cuff_force_est, readings.q)
            u = supervise(k, k * self._dt, readings, self._sup_force, self._current, u, age)
            self.after_check(k, readings)
        if step is not None:
            step(u)
        else:
            self._substep(u)
        write_applied(self.log, row, *self._applied)

    def after_check(self, k: int, readings: SensorReadings) -> None:
        """Tick ``k`` after the supervisor's answer: a stop's harness and belt, the load monitor.

        On the tick the supervisor stops, the harness locks and the belt runs
        down (:meth:`_device_stop`); on its normal ticks its patient-load monitor
        steps on the readings.
        """
        sup = self.supervisor
        if self._stop_pending and sup.state_code:
            self._device_stop(k)
        load = self.cuff_load
        if load is not None and not sup.state_code:
            load.step(k, k * self._dt, readings.q, readings.dq, sup.events)

    def compile_back(self) -> None:
        """Call the tick's stages once, last first, on a run that was not started: they compile.

        For :mod:`exo_ctrl.sim.warmup`'s helper, which compiles while the run's
        own process does, each from its end.  That process compiles in this
        order: the cuffs' fit, the chunk statistics, the sensors, the
        estimator's start, the measured row, the controller, the supervisor,
        the plant's step, the applied row, and on the second tick the
        estimator's step (the largest, some 3 s); so the helper takes them
        the other way round: the plan's rows, the estimator's step (its first
        call starts it, the second steps), the applied row, the plant's step,
        the supervisor, the controller; then the fused tick's two calls
        (:mod:`exo_ctrl.sim.fused`), which the first run of a feature set leaves
        to later runs (:func:`~exo_ctrl.sim.loop.simulate`).  The values are the unstarted run's
        (zeros): what they compute is thrown away.
        """
        _, _, estimate, command, supervise, step = self._stages
        u = np.zeros(4)
        self.fill_plan(0, 1)
        estimate()
        estimate()
        write_applied(self.log, 0, *self._applied)
        if step is not None:
            step(u)
        else:
            self._substep(u)
        if supervise is not None:
            supervise(0, 0.0, self.sensors, self._sup_force, self._current, u, 0.0)
        command(0, self.sensors)
        if self.fused is not None:
            self.fused.preload()

    def _belt_tick(self, k: int, row: int, q_meas: np.ndarray) -> None:
        """Tick ``k``'s belt set speed and rate, its encoder and drive read; the plan's row."""
        belt_tick(self.belt_encoder.record, k, self._belt, self._belt_speed, self.belt_drive_force)
        if self._online is not None:
            self._plan_tick(k, row, q_meas)

    def _device_stop(self, k: int) -> None:
        """The supervisor stopped at tick ``k``: the harness locks, the belt runs down.

        The belt's set speed from tick k + 1 on falls from its present value at
        the treadmill's stop deceleration a to rest, v(t) = max(v_k − a (t − t_k), 0)
        (its rate −a while it falls); the pelvis on its guide locks at its height.
        """
        self._stop_pending = False
        config = self.setup.config
        if config.pelvis.supported:
            self.setup.plant.lock_pelvis()
        speed = self._belt_speed
        if speed is None or k + 1 >= speed.shape[0]:
            return
        decel = config.contact.belt.stop_decel_mps2
        t = np.arange(1, speed.shape[0] - k) * self._dt
        v = np.maximum(speed[k, 0] - decel * t, 0.0)
        speed[k + 1 :, 0] = v
        speed[k + 1 :, 1] = np.where(v > 0.0, -decel, 0.0)

    def _substep(self, u: np.ndarray) -> None:
        """The plant's steps of a tick with substeps or a patient-torque model."""
        plant = self.setup.plant
        for _ in range(self._substeps):
            tau_p = None
            if self.patient_model is not None:
                tau_p = self.patient_model(plant.t, self._q_p, self._v_p, self._tau_p)
            plant.step(u, tau_p)

    def _plan_tick(self, k: int, row: int, q_meas: np.ndarray) -> None:
        """The synchronised plan's row for tick ``k`` from the belt encoder's reading, logged.

        The encoders ``q_meas`` and the foot plates' last vertical loads place a
        landing approach (:mod:`exo_ctrl.plan.surface`).  CT's feedforward row is
        recomputed from the new targets.
        """
        gen = self._online
        load = self._plate_load
        if online_step(gen.record, k, self.belt_encoder.speed[0], q_meas, load):
            gen.step(k, float(self.belt_encoder.speed[0]), q_meas, load)  # raises with the reason
        write_plan(self.log, row, gen.record)
        if self._refresh is not None:
            self._refresh()

    def fill_plan(self, start: int, rows: int) -> None:
        """Copy the planned rows ``start:start+rows`` into the log.

        A synchronised plan's rows are logged by the tick (:meth:`_plan_tick`).
        """
        if self._online is not None:
            return
        plan = self.setup.plan
        index = plan.rows(start, rows)
        self.buf["q_des"][:rows] = plan.q[index]
        self.buf["dq_des"][:rows] = plan.dq[index]
