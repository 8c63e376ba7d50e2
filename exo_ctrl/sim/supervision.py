"""The run's safety supervisor, built from its configuration; current-mode drives' reports.

A drive in the driver's current mode (:mod:`exo_ctrl.plant.current_mode`:
a user's torque controller) sets its own voltage within the plant's step,
so the voltage the supervisor sent it (the current references' feedforward,
:mod:`exo_ctrl.control.current_loop`) is not the voltage across the winding.
The supervisor's drive model (:mod:`exo_ctrl.safety.plausibility`,
:mod:`exo_ctrl.safety.still`) then takes the drivers' report of the voltage
they applied over the last plant step (:class:`ReportingDrives`), as a
servo driver reports it to its master.  A short (U = 0 whatever is sent) is
then reported too, and is not seen by the drive model.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..model import BodyModel
from ..plant.pelvis import moving_mass_kg
from ..safety import SafetySupervisor
from ..safety.belt_monitor import BeltMonitor
from ..safety.departure import DepartureMonitor, departure_limit_rad, harness_arrest_s
from ..safety.monitor import LIMIT_GROUPS
from ..sensing.readings import SensorReadings

__all__ = ["ReportingDrives", "build_supervisor", "departure_for"]


class ReportingDrives(SafetySupervisor):
    """A supervisor whose drive model takes the drives' report of their applied voltage.

    Args:
        applied_voltage_V: the drives' applied voltage over the last plant
            step, (4,) [V], updated by the plant (its ``voltage``).
        *args, **kwargs: :class:`~exo_ctrl.safety.SafetySupervisor`'s.

    """

    def __init__(self, *args: Any, applied_voltage_V: np.ndarray, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._report = applied_voltage_V
        self._sent = self.plausibility_record["u_prev"][0]

    def step(
        self,
        k: int,
        t: float,
        sensors: SensorReadings,
        cuff_force: np.ndarray,
        current_A: np.ndarray,
        u_cmd: np.ndarray,
        command_age_s: float = 0.0,
    ) -> np.ndarray:
        """:meth:`SafetySupervisor.step` with the drive model on the drives' report."""
        np.copyto(self._sent, self._report)
        return super().step(k, t, sensors, cuff_force, current_A, u_cmd, command_age_s)


def departure_for(config: Any, exo: BodyModel) -> DepartureMonitor | None:
    """The QP's departure stop (:mod:`exo_ctrl.safety.departure`), or None.

    With the QP tracking its plan (the tracking mode, no session), its bound
    tightened, the feet over the belt (contact on; the pelvis fixed or
    supported: a leg the QP takes off its plan can strike the belt either way)
    and the gait exercise; δ from the gait's lift and ``exo``'s (the device's)
    leg length; with the pelvis supported, the look-ahead T the harness takes to
    arrest the pelvis (the brake's K and C on the body mass the unloading is set
    from and ``exo``'s links; fixed: 0).
    """
    if not (
        config.controller == "qp"
        and config.mode == "tracking"
        and config.session is None
        and config.qp_tighten_bound
        and config.contact.enabled
        and config.exercise == "gait"
    ):
        return None
    leg = min(legs.reach[1] for legs in exo.legs.values())
    limit = departure_limit_rad(config.gait.lift_height, leg)
    pelvis = config.pelvis
    if not pelvis.supported:  # nothing falls: the present departure alone
        return DepartureMonitor(limit)
    arrest = harness_arrest_s(
        pelvis.stop_stiffness_N_per_m,
        pelvis.stop_damping_N_s_per_m,
        moving_mass_kg(pelvis, exo.model),
    )
    return DepartureMonitor(limit, arrest)


def build_supervisor(
    runner: Any, setup: Any, current_mode: bool, departure: bool = False
) -> SafetySupervisor | None:
    """The supervisor of a run (None: no safety, no e-stop and no departure stop).

    Args:
        runner: the tick's runner (its belt encoder, foot load and belt drive force).
        setup: the run's :class:`~exo_ctrl.sim.setup.Setup`.
        current_mode: the drives follow current references (:class:`ReportingDrives`).
        departure: the run has the QP's departure stop, which needs a supervisor
            (with safety off one that serves stops only, as for an e-stop).

    """
    config = setup.config
    if not (config.safety or config.estop_at_s is not None or departure):
        return None
    # Safety off: a supervisor that serves stops only (the e-stop, the departure stop).
    # Its reactions take their damping, ramp and hold checks from the limits
    # (safety/stop_reaction.py), so it keeps them; its monitors never trip (a
    # non-finite reading still does) and the plausibility monitors do not run.
    extra = {"applied_voltage_V": setup.plant.record["voltage"][0]} if current_mode else {}
    cls = ReportingDrives if current_mode else SafetySupervisor
    sup = cls(
        config.safety_limits,
        setup.device_exo,
        setup.device_patient,
        setup.device_motor,
        config.dt,
        estop_at_s=config.estop_at_s,
        use_estimate="widened cuff force estimate"
        if config.safety_widen
        else config.safety_use_estimate,
        sensors=config.sensors,
        compliant_drives=config.joint_compliance.enabled,
        belt=BeltMonitor(
            runner.belt_encoder,
            runner.foot_load,
            runner.belt_drive_force,
            config.belief.belt_model(config.contact.belt),
        )
        if config.safety and setup.belt_speed is not None
        else None,
        stop_reaction=config.stop_reactions,
        cuff_stiffness=config.belief.cuff_model_of(config.cuffs).stiffness_N_per_m,
        current_sensor=config.current_sensor,
        plausibility_checks=config.safety,
        **extra,
    )
    if not config.safety:
        sup.record["limit"][0][:LIMIT_GROUPS] = np.finfo(float).max
    if config.pelvis.supported and config.contact.patient_feet:
        sup.yield_command.stand()  # the patient stands on the belt at a stop
    return sup
