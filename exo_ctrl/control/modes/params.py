"""The interaction modes' names and parameters."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ... import _validate as v
from ...exceptions import InvalidParameter
from ...model import JOINT_NAMES

__all__ = ["MODES", "ModeParams"]

#: The interaction modes (``SimConfig.mode``, ``--mode``); ``tracking`` is
#: today's position control by the configured controller; ``path``: the
#: tunnel around the foot path with free timing (:mod:`~exo_ctrl.control.modes.path`).
MODES = ("tracking", "guidance", "transparent", "aan", "path")


@dataclass(frozen=True)
class ModeParams:
    """Parameters of the interaction modes (:mod:`exo_ctrl.control.modes.controller`).

    Attributes:
        guidance: G ∈ [0, 1], the share of the tracking controller's
            impedance in ``guidance`` (1: tracking, 0: transparent).
        force_gain: K_f ≥ 0 per joint, the force feedback on the estimated
            interaction torque in ``transparent`` (and the free share of
            ``guidance``): the exoskeleton's inertia is felt divided by
            1 + K_f [-].
            Default 10 (choice: the least RMS interaction force of 0.5–30
            on the healthy active patient with the default sensors; 20 and
            more excite the cuffs' 10–20 Hz mode through the estimate's lag).
        aan_forgetting: f ∈ [0, 1), the forgetting factor of the
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
            0 < G < 1 [Hz] (the controller's module docstring: its lag
            damps the active patient's reflex mode against the guidance
            spring).  Default 100 / (2π) ≈ 15.9 Hz, the momentum
            observer's bandwidth, with which K_f was tuned.
        speed_filter_hz: cut-off of the first-order filter on the encoder's
            difference that gives the speed for the drive's back-EMF [Hz].
            Default 150 (1 ms lag): the sensors' 30 Hz speed (5 ms lag) left
            an error of (i_G/k_E)(k_t/R) × lag × q̈ ≈ 1.1 kg·m² q̈, an inertia
            of its own; 150 Hz keeps the noise at about 0.016 rad/s (choice).

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
    force_gain: tuple[float, ...] | float = 10.0
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
        kf = v.per_item("force_gain", self.force_gain, "", JOINT_NAMES, check=v.non_negative)
        object.__setattr__(self, "force_gain", kf)
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
