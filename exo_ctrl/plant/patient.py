r"""Patient joint torques: the ``M_h`` of paper §V (zero in the paper's §VI).

The paper's patient equations carry joint torques ``M_h1``, ``M_h2`` "of
resistance in the patient's joints, including the phenomenon of spasticity"
but its simulations set them to zero.  This module supplies them.  A
:class:`PatientTorque` is called once per control tick with the patient's
joint angles and speeds and writes the four joint torques (JOINT_NAMES order,
positive = flexion) into a caller-owned buffer; the plant applies them to the
patient's joints (``Plant.step(u, patient_torque)``).

**Spastic patient.**  Spasticity is "a motor disorder characterised by a
velocity-dependent increase in tonic stretch reflexes (muscle tone) with
exaggerated tendon jerks" (Lance 1980).  Per joint the torque is

.. math::

    τ = -k_h (q - q_{rest}) - b\,\dot q
        - \min\bigl(k_f (\dot q - \dot q_{th})_+,\ τ_{max}\bigr)
        + \min\bigl(k_e (-\dot q - \dot q_{th})_+,\ τ_{max}\bigr),

- hypertonia: a stiffness ``k_h`` about a rest posture ``q_rest`` and a small
  extra viscosity ``b`` (increased passive resistance of spastic joints:
  Lin & Rymer 1991 needed raised stiffness and damping and a shifted rest
  length to fit spastic pendulum tests; Joghtaei et al. 2015 measured higher
  knee stiffness but unchanged viscosity in paraplegic SCI, hence ``b`` small);
- stretch reflex: zero below a speed threshold ``q̇_th``, then growing
  linearly with speed (``(x)_+ = max(x, 0)``), as the knee pendulum-test
  models that treat the reflex as lengthening-velocity feedback with a
  threshold and a gain (Kim, Eom & Hase 2011), and as isokinetic studies
  of spastic knees find the resisting torque rising linearly with stretch
  speed, more steeply than in controls (Firoozbakhsh et al. 1993; Perell et
  al. 1996 and Franzoi et al. 1999 at 30–120 °/s);
  capped at ``τ_max`` (a muscle's reflex force is bounded).

**Direction of the reflex.**  A stretch reflex acts in the muscle being
stretched.  Flexing a joint stretches its extensors, extending it stretches
its flexors, and the two groups need not be equally spastic.  So the reflex
has one gain per direction: ``k_f`` resists flexion (spastic extensors),
``k_e`` resists extension (spastic flexors).  Equal gains give the
symmetric law ``-k_r (|q̇| - q̇_th)_+ sign(q̇)``; a zero gain removes the
reflex in that direction.  The defaults follow the common post-stroke
pattern of a spastic rectus femoris / quadriceps (resists knee flexion — the
stiff-knee gait) and hip flexors (resist hip extension), with milder
antagonists.

**Not modelled.**  The reflex latency (30–50 ms): the reflex torque follows
the speed without delay; the reflex's dependence on the joint angle
(threshold angle); clonus; voluntary torque.  Nothing is stateful, so one
instance can serve any number of runs.

References:
    Lance JW (1980). Symposium synopsis. In: Feldman RG, Young RR, Koella WP
    (eds), *Spasticity: Disordered Motor Control*, Year Book, pp. 485–494.
    Lin DC, Rymer WZ (1991). A quantitative analysis of pendular motion of the
    lower leg in spastic human subjects. IEEE TBME 38(9):906–918.
    Firoozbakhsh KK, Kunkel CF, Scremin AME, Moneim MS (1993). Isokinetic
    dynamometric technique for spasticity assessment. Am J Phys Med Rehabil
    72:379–385.
    Perell K, Scremin A, Scremin O, Kunkel C (1996). Quantifying muscle tone
    in spinal cord injury patients using isokinetic dynamometric techniques.
    Paraplegia 34:46–53.
    Franzoi AC, Castro C, Cardone C (1999). Isokinetic assessment of
    spasticity in subjects with traumatic spinal cord injury (ASIA A).
    Spinal Cord 37:416–420.
    Riener R, Edrich T (1999). Identification of passive elastic joint moments
    in the lower extremities. J Biomech 32:539–544.
    Kim CS, Eom GM, Hase K (2011). Modeling and identification of mechanical
    and reflex properties related to spasticity in stroke patients using
    multiple pendulum tests. J Biomech Sci Eng 6(3):135–147.
    Joghtaei M et al. (2015). Assessment of passive knee stiffness and
    viscosity in individuals with spinal cord injury using pendulum test.
    J Spinal Cord Med 38(2):170–177.

"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Protocol

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES

__all__ = [
    "PATIENT_TORQUES",
    "PatientTorque",
    "SpasticParams",
    "SpasticPatient",
    "make_patient_torque",
]

#: Kinds accepted by :func:`make_patient_torque` (and the CLI's ``--patient-torque``).
PATIENT_TORQUES = ("none", "spastic")


class PatientTorque(Protocol):
    """Joint torques the patient applies to their own joints."""

    def __call__(self, t: float, q: np.ndarray, dq: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Write the patient's joint torques into ``out`` and return it.

        Args:
            t: time [s].
            q: patient joint angles, (4,) [rad], JOINT_NAMES order.
            dq: patient joint speeds, (4,) [rad/s].
            out: buffer for the torques, (4,) [N·m] (positive = flexion).

        Returns:
            ``out``.

        """
        ...


@dataclass(frozen=True)
class SpasticParams:
    """Parameters of :class:`SpasticPatient`, per joint (scalar: the same for all four).

    Every field is a number or four numbers in JOINT_NAMES order (left_hip,
    left_knee, right_hip, right_knee); both legs are equally affected by
    default.  Sources are in the module docstring; the studies report the
    *form* of the law and orders of magnitude (spastic knees resist passive
    movement at 30–120 °/s with torques of the order of 10–30 N·m, growing
    linearly with speed), so the numbers below are choices inside that range,
    tuned so that the default spastic patient visibly loads the cuffs on the
    default gait (peak cuff force > 150 N with the CT controller, against
    ≈ 107 N for the passive patient).

    Attributes:
        stiffness_Nm_per_rad: hypertonia stiffness k_h [N·m/rad].  Default
            hip 15, knee 10: a few times the passive mid-range stiffness of
            healthy joints (Riener & Edrich 1999 give passive moments of a
            few N·m over the gait range); choice.
        rest_posture_rad: rest posture q_rest where the hypertonic torque
            vanishes [rad].  Default hip 0.2, knee 0.3 (11° and 17° of
            flexion: the extended resting posture of an extensor-spastic
            leg); choice.
        damping_Nms_per_rad: extra joint viscosity b [N·m·s/rad], added to
            the URDF's passive damping.  Default 0.3; Joghtaei et al. 2015
            found knee viscosity in SCI not different from controls, so it
            is small; choice.
        reflex_gain_flexion_Nms_per_rad: k_f, reflex torque per rad/s above
            the threshold while the joint flexes (spastic extensors)
            [N·m·s/rad].  Default hip 6, knee 20 (quadriceps / rectus
            femoris spasticity, the stiff-knee pattern); choice.
        reflex_gain_extension_Nms_per_rad: k_e, the same while the joint
            extends (spastic flexors) [N·m·s/rad].  Default hip 20 (hip
            flexors), knee 8 (hamstrings); choice.
        reflex_threshold_rad_s: speed threshold q̇_th [rad/s].  Default 0.5
            (≈ 30 °/s, the slowest isokinetic speed at which the cited
            studies see spastic resistance; healthy joints show none there);
            choice.
        reflex_max_Nm: cap on the reflex torque magnitude τ_max [N·m].
            Default 40; choice (well below the joints' voluntary strength).

    Raises:
        InvalidParameter: a field is not a number or four numbers, or a value
            is not finite, or (all fields but ``rest_posture_rad``) negative.

    """

    stiffness_Nm_per_rad: tuple[float, ...] | float = (15.0, 10.0, 15.0, 10.0)
    rest_posture_rad: tuple[float, ...] | float = (0.2, 0.3, 0.2, 0.3)
    damping_Nms_per_rad: tuple[float, ...] | float = 0.3
    reflex_gain_flexion_Nms_per_rad: tuple[float, ...] | float = (6.0, 20.0, 6.0, 20.0)
    reflex_gain_extension_Nms_per_rad: tuple[float, ...] | float = (20.0, 8.0, 20.0, 8.0)
    reflex_threshold_rad_s: tuple[float, ...] | float = 0.5
    reflex_max_Nm: tuple[float, ...] | float = 40.0

    def __post_init__(self) -> None:
        units = {
            "stiffness_Nm_per_rad": "N·m/rad",
            "rest_posture_rad": "rad",
            "damping_Nms_per_rad": "N·m·s/rad",
            "reflex_gain_flexion_Nms_per_rad": "N·m·s/rad",
            "reflex_gain_extension_Nms_per_rad": "N·m·s/rad",
            "reflex_threshold_rad_s": "rad/s",
            "reflex_max_Nm": "N·m",
        }
        for f in fields(self):
            lo = None if f.name == "rest_posture_rad" else 0.0
            check = v.finite if lo is None else v.non_negative
            value = v.per_item(
                f.name, getattr(self, f.name), units[f.name], JOINT_NAMES, check=check
            )
            object.__setattr__(self, f.name, value)


class SpasticPatient:
    """A resisting (spastic) patient: hypertonia plus a velocity-dependent stretch reflex.

    The law is in the module docstring.  All work arrays are allocated here;
    a call allocates nothing.

    Args:
        params: the parameters (default: :class:`SpasticParams` defaults).

    """

    def __init__(self, params: SpasticParams | None = None) -> None:
        self.params = params if params is not None else SpasticParams()
        p = self.params
        self._k = np.array(p.stiffness_Nm_per_rad)
        self._q_rest = np.array(p.rest_posture_rad)
        self._b = np.array(p.damping_Nms_per_rad)
        self._k_f = np.array(p.reflex_gain_flexion_Nms_per_rad)
        self._k_e = np.array(p.reflex_gain_extension_Nms_per_rad)
        self._th = np.array(p.reflex_threshold_rad_s)
        self._cap = np.array(p.reflex_max_Nm)
        self._zero = np.zeros(4)
        self._tmp = np.zeros(4)

    def __call__(self, t: float, q: np.ndarray, dq: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Patient joint torques [N·m] into ``out`` (see :class:`PatientTorque`)."""
        tmp = self._tmp
        # Resistance r (positive opposes flexion); τ = -r.
        np.subtract(q, self._q_rest, out=out)
        np.multiply(out, self._k, out=out)
        np.multiply(dq, self._b, out=tmp)
        np.add(out, tmp, out=out)
        # Flexing faster than the threshold: + min(k_f (q̇ - q̇_th)_+, τ_max).
        np.subtract(dq, self._th, out=tmp)
        np.maximum(tmp, self._zero, out=tmp)
        np.multiply(tmp, self._k_f, out=tmp)
        np.minimum(tmp, self._cap, out=tmp)
        np.add(out, tmp, out=out)
        # Extending faster than the threshold: - min(k_e (-q̇ - q̇_th)_+, τ_max).
        np.add(dq, self._th, out=tmp)
        np.minimum(tmp, self._zero, out=tmp)
        np.multiply(tmp, self._k_e, out=tmp)
        np.negative(tmp, out=tmp)
        np.minimum(tmp, self._cap, out=tmp)
        np.subtract(out, tmp, out=out)
        np.negative(out, out=out)
        return out


def make_patient_torque(kind: str = "none", **params: object) -> PatientTorque | None:
    """The patient-torque model named ``kind``.

    Args:
        kind: ``"none"`` (the paper's §VI: no patient torque; returns None) or
            ``"spastic"`` (:class:`SpasticPatient`).
        **params: :class:`SpasticParams` fields for ``"spastic"``.

    Returns:
        The model, or None for ``"none"``.

    Raises:
        InvalidParameter: unknown ``kind``, a parameter that ``kind`` does not
            take, or a bad parameter value.

    """
    if kind == "none":
        if params:
            raise InvalidParameter(
                "patient_torque parameters", sorted(params), "empty for patient_torque 'none'"
            )
        return None
    if kind == "spastic":
        known = {f.name for f in fields(SpasticParams)}
        for name in params:
            if name not in known:
                raise InvalidParameter(
                    "spastic parameter", name, f"one of {', '.join(sorted(known))}"
                )
        return SpasticPatient(SpasticParams(**params))  # type: ignore[arg-type]
    raise InvalidParameter("patient_torque", kind, f"one of {', '.join(PATIENT_TORQUES)}")
