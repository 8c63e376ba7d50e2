"""The interaction modes' names and parameters."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ... import _validate as v
from ...exceptions import InvalidParameter
from ...model import JOINT_NAMES

__all__ = ["FORCE_GAINS", "FORCE_LEADS", "MODES", "ModeParams"]

#: The interaction modes (``SimConfig.mode``, ``--mode``); ``tracking`` is
#: today's position control by the configured controller; ``path``: the
#: tunnel around the foot path with free timing (:mod:`~exo_ctrl.control.modes.path`).
MODES = ("tracking", "guidance", "transparent", "aan", "path")

#: The default force-feedback gains K_f per (mode, live estimator), per joint
#: (left hip, left knee, right hip, right knee) [-], when ``ModeParams.force_gain``
#: is None.  Chosen on the healthy active patient (1.0 s, 0.30 m against the
#: plan's 1.2 s, 0.35 m) with the default sensors, patient seeds 0–5, 12 s runs
#: (tests/sim/test_modes_run.py; the measurements: ModeParams' docstring).
FORCE_GAINS: dict[tuple[str, str], tuple[float, ...]] = {
    ("transparent", "kalman"): (14.0, 10.0, 14.0, 10.0),
    ("transparent", "momentum"): (10.0, 10.0, 10.0, 10.0),
    ("guidance", "kalman"): (10.0, 10.0, 10.0, 10.0),
    ("guidance", "momentum"): (10.0, 10.0, 10.0, 10.0),
}

#: The default lead T_L per joint [s] on the estimated interaction torque per
#: (mode, live estimator), when ``ModeParams.force_lead_s`` is None (others: 0,
#: none): the lag of the Kalman filter's hip estimate with the default sensors
#: at transparent's σ_d (16 ms measured; ModeParams' docstring).
FORCE_LEADS: dict[tuple[str, str], tuple[float, ...]] = {
    ("transparent", "kalman"): (0.015, 0.015, 0.015, 0.015),
}


@dataclass(frozen=True)
class ModeParams:
    """Parameters of the interaction modes (:mod:`exo_ctrl.control.modes.controller`).

    Attributes:
        guidance: G ∈ [0, 1], the share of the tracking controller's
            impedance in ``guidance`` (1: tracking, 0: transparent).
        force_gain: K_f ≥ 0 per joint, the force feedback on the estimated
            interaction torque in ``transparent`` (and the free share of
            ``guidance``): the exoskeleton's inertia is felt divided by
            1 + K_f [-].  None (default): :data:`FORCE_GAINS` for the mode
            and the live estimator (:meth:`force_gain_for`, below).
        estimator_torque_rate_Nm_per_sqrt_s: σ_d, the intensity of the
            random walk of the patient's unknown joint torques that the
            Kalman filter (:class:`~exo_ctrl.estimation.kalman.KalmanNoise`,
            its own 10) assumes while ``transparent`` runs [N·m/√s] (the
            momentum observer has no such term).  Default 30 (below).
        force_lead_s: T_L ≥ 0 per joint, the lead on the estimated
            interaction torque in ``transparent``, K_f (τ̂ + T_L r) with r the
            rate of τ̂ (its difference over Δt through a first-order low-pass
            of ``force_lead_filter_hz``) [s]; it makes up for the estimate's
            lag behind the true torque.  None (default): :data:`FORCE_LEADS`
            (15 ms with the Kalman filter, none with the momentum observer).
        force_lead_filter_hz: cut-off of the lead's rate filter [Hz].
            Default 10 (as good as 15–50 Hz on the interaction force, and its
            high-frequency gain 1 + T_L ω_f, 1.9 at 15 ms, is half of 30 Hz's:
            less of the encoder's noise and of a frozen reading's loop).
        force_lead_ramp_s: the lead rises linearly from 0 over this time
            after the mode starts [s] (default 0.1): the filter's start (its
            covariance converging from the initial uncertainty) is not
            motion to anticipate — with ideal sensors the unramped lead drove
            the estimated shank force to 150 N at t = 3 ms.
        aan_forgetting: f ∈ [0, 1), the forgetting factor [-] of the
            assist-as-needed support, F_{k+1} = f F_k + g e_k (Emken et al.
            2007); the support fades by f per cycle, time constant
            −1 / ln f cycles.  Default 0.8 (4.5 cycles; choice).
        aan_gain: g ≥ 0 per joint, the support added per radian of the
            cycle's mean error in a phase bin [N·m/rad].  Default 60 (choice,
            see below).
        aan_bins: phase bins per gait cycle of the support table (default 100).
        aan_kp: the soft tracking PD's k_p under the support [V/rad]
            (default 1: 45 N·m/rad through the default drive, 1/300 of
            tracking's).
        aan_kd: the soft PD's k_d [V·s/rad] (default 1: 45 N·m·s/rad, the
            damping that keeps the soft leg from ringing at the gait's
            frequency once the back-EMF is compensated).
        force_filter_hz: f_f, cut-off of the first-order low-pass on the
            estimated interaction torque before K_f in ``guidance`` with
            0 < G < 1 [Hz] (the controller's module docstring: with it the
            Kalman filter and the momentum observer give the same guidance
            forces).  Default 100 / (2π) ≈ 15.9 Hz, the momentum
            observer's bandwidth, with which K_f was tuned.
        speed_filter_hz: cut-off of the first-order filter on the encoder's
            difference that gives the speed for the drive's back-EMF [Hz].
            Default 150 (1 ms lag): the sensors' 30 Hz speed (5 ms lag) left
            an error of (i_G/k_E)(k_t/R) × lag × q̈ ≈ 1.1 kg·m² q̈, an inertia
            of its own; 150 Hz keeps the noise at about 0.016 rad/s (choice).

    **Transparent: K_f, the filter's σ_d and the lead** (issue 18: RMS true
    cuff force below 10 % of tracking's with the same healthy active
    patient; figures: that patient, 1.0 s and 0.30 m against the plan's
    1.2 s and 0.35 m, patient seeds 0–2 or 0–5, 12 s without the
    supervisor, 2.2–6 s / 6–12 s).  What is left of the interaction force
    is the device's uncompensated dynamics divided by 1 + K_f plus the
    estimate's error passed almost whole, K_f/(1 + K_f) e; per joint (hip,
    knee, N·m RMS, the previous K_f = 10 and σ_d = 10, 12.8 %): the links'
    inertia M q̈ 23, 5; the rotors' i_G² J_r q̈ 4, 8; the drive's lag behind
    its steady model (the speed filter, the held voltage and L/R: 0.35 kg·m²
    felt) 6, 9; and K_f e 43, 9 — the estimate's error, mostly its lag: the
    hip estimate lagged the true torque by 18 ms.  The filter's σ_d of 10
    was chosen on passive and spastic patients, whose torques change
    slowly; a patient in charge changes theirs at the gait's rate, and a
    larger σ_d follows them sooner (16 ms at 30, 2 ms at 100).  Three
    changes, each from the sensors' readings and the device's models:

    - σ_d while transparent runs, 10 → 30 N·m/√s (with the others at their
      defaults: 10: 9.5–10.2 %, 20: 8.2–8.7 %, 30: 7.6–8.2 %, 50: 7.1–7.8 %,
      100: 7.0–7.6 %).  Not 100: with a frozen encoder the filter explains
      the torque sensor's reading by cuff forces, a loop of gain ≈ K_f that
      a fast filter turns into a limit cycle between the current limits,
      where the supervisor's drive model residual is not evaluated (seed
      0's frozen hip encoder went undetected by it at 100 without the lead;
      at 30 it is caught after 35 ms, at 10 after 103 ms; tools/faults.py
      --mode transparent).  The still-encoder check (exo_ctrl/safety/still.py)
      now names that limit cycle after 36 ms too.
    - The lead T_L = 15 ms, the hip estimate's lag at σ_d = 30 (none:
      9.0–9.6 %; 10 ms: 8.0–8.6 %; 20 ms: 7.3–7.9 %).  It is a property of
      the sensors: with noise-free angles the estimate has no such lag and
      the lead overshoots (11.6 %, against 7.7 % without); 16- to 20-bit
      encoders: 8.5–6.6 %.
    - K_f hip 14, knee 10 (10 at the hips: 8.2–8.8 %).  K_f is bounded
      by a slow growth at 3–4 Hz (the active patient's 60 ms reflex with the
      estimate's lag: absent at a 30 ms delay or fed the true force): from
      2.2–6 s to 8–12 s the force grew 1.55× at a knee gain of 14, 2.6× at
      16, and on one seed of three at 12; the hips took 24 (1.07×, seed 0).
      These gains and figures were measured on a patient model whose
      reflex damping acted 60 ms late; with it acting at once (the model
      since: :mod:`exo_ctrl.plant.patient_active`) the healthy patient is
      carried at 4.6 N (6.9 %; tests/sim/test_modes_run.py) and the bound
      on K_f has not been measured again.

    Together 7.7–8.2 % over seeds 0–5 and 2.2–6 s, 7.6–7.9 % over 6–12 s
    (weak 0.3 and spastic patients: 4.1–4.2 N RMS, stable).  With the
    momentum observer (100 rad/s lag) K_f stays 10 and T_L 0, the values
    the bounds of tests/sim/test_faults_injection.py were derived with,
    though it grows slowly there: 20 % over 2.2–6 s, 27 % over 6–12 s (K_f
    8: 18–19 % in both; a lead of 10 ms: 15–16 %, 15–17 %).  Tried and
    not taken (each lowers the inertia felt through a lag, which the loop
    turns into negative damping): feedforward of the exoskeleton's inertia
    on an acceleration (the filter's velocity differenced through 10–40 Hz;
    at σ_d = 10, against 12.8 %: a quarter of M 14–15 %, all of it
    unstable); an integral loop on the joint torque sensor (removing the
    rotors' inertia; 0.1–0.3 per tick: unstable at K_f = 10); the
    back-EMF's speed from the filter or predicted 1 ms ahead (the same
    optimum at a lower K_f); a low-pass on τ̂_int (worse at 30–120 Hz).

    **The choice of g.**  With the support in the loop the error answers it,
    e_k ≈ e⁰ − c F_k (c: the leg's compliance, 1 / (soft PD + patient)
    stiffness), so the support obeys F_{k+1} = (f − g c) F_k + g e⁰: it fades
    at f per cycle only while g c ≪ 1 − f, and it cuts the weak patient's
    error by (1 − f) / (1 − f + g c_weak).  Larger g helps more and fades
    faster than f; g = 60 N·m/rad cuts the weak (strength 0.3) patient's
    knee error by about 60 % and fades within 10 % of f's time constant
    once the patient is strong (tests/sim/test_modes_run.py).

    Raises:
        InvalidParameter: a value outside its range.

    """

    guidance: float = 1.0
    force_gain: tuple[float, ...] | float | None = None
    estimator_torque_rate_Nm_per_sqrt_s: float = 30.0
    force_lead_s: tuple[float, ...] | float | None = None
    force_lead_filter_hz: float = 10.0
    force_lead_ramp_s: float = 0.1
    aan_forgetting: float = 0.8
    aan_gain: tuple[float, ...] | float = 60.0
    aan_bins: int = 100
    aan_kp: float = 1.0
    aan_kd: float = 1.0
    speed_filter_hz: float = 150.0
    force_filter_hz: float = 100.0 / (2.0 * math.pi)

    def __post_init__(self) -> None:
        g = v.finite("guidance", self.guidance)
        if not 0.0 <= g <= 1.0:
            raise InvalidParameter("guidance", self.guidance, "in [0, 1] (1: tracking, 0: free)")
        object.__setattr__(self, "guidance", g)
        if self.force_gain is not None:
            kf = v.per_item("force_gain", self.force_gain, "", JOINT_NAMES, check=v.non_negative)
            object.__setattr__(self, "force_gain", kf)
        rate = v.non_negative(
            "estimator_torque_rate", self.estimator_torque_rate_Nm_per_sqrt_s, "N·m/√s"
        )
        object.__setattr__(self, "estimator_torque_rate_Nm_per_sqrt_s", rate)
        if self.force_lead_s is not None:
            lead = v.per_item(
                "force_lead", self.force_lead_s, "s", JOINT_NAMES, check=v.non_negative
            )
            object.__setattr__(self, "force_lead_s", lead)
        object.__setattr__(
            self,
            "force_lead_filter_hz",
            v.positive("force_lead_filter", self.force_lead_filter_hz, "Hz"),
        )
        ramp = v.non_negative("force_lead_ramp", self.force_lead_ramp_s, "s")
        object.__setattr__(self, "force_lead_ramp_s", ramp)
        f = v.finite("aan_forgetting", self.aan_forgetting)
        if not 0.0 <= f < 1.0:
            raise InvalidParameter("aan_forgetting", self.aan_forgetting, "in [0, 1)")
        object.__setattr__(self, "aan_forgetting", f)
        gain = v.per_item("aan_gain", self.aan_gain, "N·m/rad", JOINT_NAMES, check=v.non_negative)
        object.__setattr__(self, "aan_gain", gain)
        bins = self.aan_bins
        if isinstance(bins, bool) or not isinstance(bins, int) or not 1 <= bins <= 10_000:
            raise InvalidParameter("aan_bins", bins, "an integer in [1, 10000]")
        object.__setattr__(self, "aan_kp", v.non_negative("aan_kp", self.aan_kp, "V/rad"))
        object.__setattr__(self, "aan_kd", v.non_negative("aan_kd", self.aan_kd, "V·s/rad"))
        object.__setattr__(
            self, "speed_filter_hz", v.positive("speed_filter", self.speed_filter_hz, "Hz")
        )
        object.__setattr__(
            self, "force_filter_hz", v.positive("force_filter_hz", self.force_filter_hz, "Hz")
        )

    def force_gain_for(self, mode: str, estimator: str = "kalman") -> tuple[float, ...]:
        """K_f per joint of ``mode`` with the live ``estimator`` [-].

        ``force_gain`` if set, else :data:`FORCE_GAINS`; 0 for a mode
        without force feedback (``aan``, and ``tracking`` and ``path``,
        which do not use it).
        """
        if self.force_gain is not None:
            return self.force_gain  # type: ignore[return-value]
        return FORCE_GAINS.get((mode, estimator), (0.0, 0.0, 0.0, 0.0))

    def torque_rate_for(self, mode: str) -> float | None:
        """The Kalman filter's σ_d ``mode`` runs with [N·m/√s], or None (the filter's own).

        ``estimator_torque_rate_Nm_per_sqrt_s`` for ``transparent`` and for
        ``path`` (whose free part is transparent's); None for the others.
        """
        if mode in ("transparent", "path"):
            return self.estimator_torque_rate_Nm_per_sqrt_s
        return None

    def force_lead_for(self, mode: str, estimator: str = "kalman") -> tuple[float, ...]:
        """T_L of ``mode`` with the live ``estimator`` [s] (only ``transparent`` applies it).

        ``force_lead_s`` if set, else :data:`FORCE_LEADS` (0: none).
        """
        if self.force_lead_s is not None:
            return self.force_lead_s  # type: ignore[return-value]
        return FORCE_LEADS.get((mode, estimator), (0.0, 0.0, 0.0, 0.0))
