r"""Checks of an offline estimate: the model against the recording, the data against the model.

An estimate is only as good as the model the observer runs on and the
readings it runs along.  :mod:`.estimate` calls these checks; each returns
one-line warnings (or raises) that name the file, the cuff and the figures.

- :func:`recorded_exo` loads the exoskeleton of a recording: its own (the
  ``exo_source`` stored in ``raw/meta``), or the one the user gives, which is
  refused when it differs from the recorded one (:func:`model_difference`)
  unless the user allows it.
- :func:`startup_ticks`: the observer's start-up, five time constants
  5 / K_O, in ticks; a run not longer gets no error figures.
- :func:`worse_than_none`: with the true forces known, an estimate whose RMS
  error exceeds the RMS of the true normal force is worse than the zero
  estimate (whose error is the force itself): the observer's model does not
  explain the readings.  A correct model stays far below (3.5–4.4 % of the
  peak with the default sensors, README).
- :func:`beyond_cuff_stretch`: without the truth, a bound from the cuffs'
  physics.  A cuff is a spring of stiffness k; a normal force f stretches it
  by f / k, which cannot exceed the leg's length (thigh + shank) without the
  leg leaving the cuff.  An estimate above k·(l_thigh + l_shank) is
  impossible, whatever the motion.
"""

from __future__ import annotations

import os

import numpy as np

from ..estimation import EstimateErrors
from ..estimation.errors import REL_FLOOR_N
from ..exceptions import ExoCtrlError, InvalidParameter, RecordingError
from ..model import CUFF_NAMES, JOINT_NAMES, BodyModel, default_urdf_path, load_exo

__all__ = [
    "STARTUP_TIME_CONSTANTS",
    "beyond_cuff_stretch",
    "model_difference",
    "recorded_exo",
    "startup_ticks",
    "worse_than_none",
]

#: Observer start-up left out of the error figures: five time constants 5 / K_O [s].
STARTUP_TIME_CONSTANTS = 5.0
#: Tolerances of :func:`model_difference` (relative, absolute in SI units).
_RTOL, _ATOL = 1e-9, 1e-12


def startup_ticks(gain_per_s: float, dt: float) -> int:
    """Ticks of the observer's start-up, round(5 / (K_O Δt)) (as the live run skips them)."""
    return round(STARTUP_TIME_CONSTANTS / gain_per_s / dt)


def _joint_parameters(body: BodyModel) -> list[tuple[str, str, np.ndarray]]:
    """(label, unit, value) of every dynamic and geometric parameter the observer uses."""
    m = body.model
    out: list[tuple[str, str, np.ndarray]] = []
    for name, jid, iq in zip(JOINT_NAMES, body.joint_ids, body.q_index, strict=True):
        inertia, placement = m.inertias[jid], m.jointPlacements[jid]
        out += [
            (f"{name} link mass", "kg", np.array([inertia.mass])),
            (f"{name} link centre of mass", "m", np.array(inertia.lever)),
            (f"{name} link inertia", "kg·m²", np.array(inertia.inertia)),
            (f"{name} joint position", "m", np.array(placement.translation)),
            (f"{name} joint axis frame", "", np.array(placement.rotation)),
            (f"{name} damping", "N·m·s/rad", np.array([m.damping[iq]])),
            (f"{name} friction", "N·m", np.array([m.friction[iq]])),
        ]
    for name, fid in zip(CUFF_NAMES, body.cuff_frame_ids, strict=True):
        out.append((f"{name} cuff position", "m", np.array(m.frames[fid].placement.translation)))
    return out


def model_difference(used: BodyModel, recorded: BodyModel) -> str:
    """The first parameter in which two exoskeleton models differ, in words ("" if none).

    Compared: per driven joint the link's mass, centre of mass and inertia,
    the joint's placement, damping and friction; per cuff its position on
    the link (relative 1e-9).
    """
    for (label, unit, a), (_, _, b) in zip(
        _joint_parameters(used), _joint_parameters(recorded), strict=True
    ):
        if not np.allclose(a, b, rtol=_RTOL, atol=_ATOL):
            if a.size == 1:
                return f"{label} {a[0]:.4g} {unit} against {b[0]:.4g} {unit} recorded"
            gap = float(np.max(np.abs(a - b)))
            return f"{label} differs from the recorded one by up to {gap:.4g} {unit}".rstrip()
    return ""


def recorded_exo(
    path: os.PathLike[str] | str,
    recorded_source: str,
    exo: str | os.PathLike[str] | None,
    allow_other_exo: bool,
) -> tuple[BodyModel, list[str]]:
    """The exoskeleton to estimate a recording with, and warnings.

    Args:
        path: the recording (for messages).
        recorded_source: the ``exo_source`` the recording stores.
        exo: the URDF the user gives, or None for the recorded one.
        allow_other_exo: accept an ``exo`` that differs from the recorded model.

    Raises:
        InvalidParameter: ``exo`` differs from the recorded model and
            ``allow_other_exo`` is False.
        RecordingError: ``exo`` is None and the recorded model cannot be loaded.

    """
    try:
        recorded = load_exo(recorded_source or None)
    except ExoCtrlError as exc:
        if exo is None:
            raise RecordingError(
                f"cannot read {path}: the exoskeleton URDF it names, {recorded_source}, cannot "
                f"be loaded ({exc}); give the model with --exo"
            ) from None
        warning = (
            f"{path}: exo {str(exo)!r} cannot be checked against the recorded exoskeleton "
            f"{recorded_source} ({exc})"
        )
        return load_exo(exo), [warning]
    if exo is None:
        default = os.path.realpath(default_urdf_path("exo"))
        if recorded_source and os.path.realpath(recorded_source) != default:
            said = f"read with the exoskeleton URDF it names, {recorded_source} (--exo: another)"
            return recorded, [f"{path}: {said}"]
        return recorded, []
    used = load_exo(exo)
    difference = model_difference(used, recorded)
    if not difference:
        return used, []
    if not allow_other_exo:
        raise InvalidParameter(
            "exo",
            str(exo),
            f"the exoskeleton {path} was recorded with ({recorded_source}) unless a "
            "different model is allowed (--allow-other-exo)",
            difference,
        )
    return used, [f"{path}: estimating with exo {str(exo)!r}, not the recorded one: {difference}"]


def worse_than_none(path: os.PathLike[str] | str, errors: EstimateErrors) -> list[str]:
    """Warnings for cuffs whose RMS error exceeds the true force's RMS.

    Error and truth are per cuff normal components [N], compared after the
    observer's start-up; the zero estimate has an RMS error equal to the
    truth's RMS, so an estimate above it explains nothing of the readings.
    A cuff whose true RMS is below
    :data:`~exo_ctrl.estimation.errors.REL_FLOOR_N` is not judged (the bound
    would be the sensor noise).
    """
    if errors.rms_true_N is None:
        return []
    out = []
    for cuff, err, true in zip(CUFF_NAMES, errors.rms_error_N, errors.rms_true_N, strict=True):
        if true >= REL_FLOOR_N and err > true:
            out.append(
                f"{path}: the {cuff} estimate is worse than none: its RMS error {err:.4g} N "
                f"exceeds the recorded force's RMS {true:.4g} N; the observer's model does "
                "not explain the readings (another exoskeleton, or faulty sensors)"
            )
    return out


def beyond_cuff_stretch(
    path: os.PathLike[str] | str,
    peak_normal_N: np.ndarray,
    stiffness_N_per_m: float,
    body: BodyModel,
) -> list[str]:
    """Warnings for cuffs whose estimated peak exceeds k·(l_thigh + l_shank) of their leg.

    Args:
        path: the file estimated from (for messages).
        peak_normal_N: peak |estimated normal force| per cuff [N], (4,).
        stiffness_N_per_m: cuff stiffness k [N/m].
        body: the exoskeleton the estimate used (its leg lengths).

    """
    out = []
    for cuff, peak in zip(CUFF_NAMES, peak_normal_N, strict=True):
        leg = body.legs[cuff.split("_", 1)[0]]
        length = leg.thigh_length + leg.shank_length
        if peak > stiffness_N_per_m * length:
            out.append(
                f"{path}: the {cuff} estimate peaks at {peak:.4g} N, which would stretch its "
                f"{stiffness_N_per_m:.4g} N/m cuff by {peak / stiffness_N_per_m:.4g} m, more "
                f"than the leg's {length:.4g} m; the observer's model does not match the data"
            )
    return out
