"""What a run's summary says of its models: what the device held, what the plant simulated."""

from __future__ import annotations

from typing import Any

from ..estimation.errors import STARTUP_S
from ..estimation.plugin import estimator_name
from .belief import PAPER_PATIENT
from .config import SimConfig

__all__ = ["components_from_s", "device_belief", "true_cuffs"]


def components_from_s(config: SimConfig) -> float:
    """Where a run's per-component estimate figures start [s]: the end of the gait's ramp-in.

    The walking at speed (:mod:`exo_ctrl.estimation.errors`); a calibration run
    has no ramp, and a ramp-in as long as the run leaves the start-up
    (:data:`~exo_ctrl.estimation.errors.STARTUP_S`) only.
    """
    if config.exercise != "gait" or config.ramp_in >= config.n_ticks * config.dt:
        return STARTUP_S
    return max(config.ramp_in, STARTUP_S)


def device_belief(config: SimConfig) -> dict[str, Any]:
    """What the device held in a run (:mod:`exo_ctrl.sim.belief`), for its summary.

    Keys: ``patient`` (``"truth"``: perfect knowledge, the ideal comparison;
    ``"nominal"``; or the URDF path), ``patient_height_m``,
    ``patient_mass_kg``, ``patient_sex`` (the nominal model's, None for the
    others), ``exo`` (the URDF the device holds, None: the true one's file),
    ``drive`` (``"datasheet"``: the installed drive's nominal values, or
    ``"given"``), ``cuffs`` (``"published"``, the default: the run's
    published cuffs, ``SimConfig.cuffs``; or ``"given"``), ``belt`` (the
    treadmill's datasheet: ``"datasheet"`` or ``"given"``), ``soles`` (the
    soles' contact law: ``"datasheet"`` or ``"given"``), ``estimator``,
    ``plan`` (``"synchronised"`` with the measured belt, or
    ``"precomputed"``) and ``safety_cuff_force`` (``"estimate"``, or
    ``"widened estimate"``: with ``safety_widen``; ``"truth"``: the plant's forces, a sensor
    per cuff).
    """
    b = config.belief
    nominal = b.patient == "nominal"
    return {
        "patient": b.patient,
        "patient_height_m": (b.patient_height_m or PAPER_PATIENT["height_m"]) if nominal else None,
        "patient_mass_kg": (b.patient_mass_kg or PAPER_PATIENT["mass_kg"]) if nominal else None,
        "patient_sex": b.patient_sex if nominal else None,
        "exo": b.exo,
        "drive": "datasheet" if b.motor is None else "given",
        "cuffs": "given" if b.cuffs is not None else "published",
        "belt": "datasheet" if b.belt is None else "given",
        "soles": "datasheet" if b.soles is None else "given",
        "estimator": estimator_name(config.estimator),
        "plan": "synchronised" if config.synced else "precomputed",
        "safety_cuff_force": (
            ("widened estimate" if config.safety_widen else "estimate")
            if config.safety_use_estimate
            else "truth"
        ),
    }


def true_cuffs(config: SimConfig) -> dict[str, float]:
    """The patient's true cuffs the plant simulated (:mod:`exo_ctrl.plant.cuff_scatter`).

    Keys: ``normal_stiffness_N_per_m``, ``shear_stiffness_N_per_m`` (k_n, k_u),
    ``normal_factor``, ``shear_factor`` (f_n, f_u: over the published
    ``SimConfig.cuffs``), ``spread_rel`` and ``seed`` (the draw).
    """
    cuffs, scatter = config.true_cuffs, config.cuff_scatter
    f_n, f_u = scatter.factors()
    return {
        "normal_stiffness_N_per_m": float(cuffs.stiffness_N_per_m),
        "shear_stiffness_N_per_m": float(cuffs.shear_stiffness_N_per_m or 0.0),
        "normal_factor": f_n,
        "shear_factor": f_u,
        "spread_rel": scatter.spread_rel,
        "seed": scatter.seed,
    }
