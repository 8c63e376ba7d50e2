r"""The foot plates' load cells: the belt's force on each exoskeleton foot, as the device reads it.

With the belt (contact on) the stance foot carries body weight, and every
joint torque sensor of that leg reads the ground's force through the leg.
An estimator that explains the joint torques by the cuffs alone would call
that force a cuff force (with body-weight support: hundreds of newtons).  A
device that stands on a belt therefore measures what its feet carry: a load
cell under each foot plate reads the sagittal force (F_x, F_z) the belt
applies, plus white noise,

    F_m = F + n_F,   n_F ~ N(0, σ_F²) per component,

and the reading's joint-space torque at the encoders' angles, with the
device's own leg geometry (its URDF, not the plant's),

    τ_g = J_x(q_m)ᵀ F_m,x + J_z(q_m)ᵀ F_m,z   if F_m,z ≥ F_c, else 0,

J the foot point's rows ∂p/∂(q_hip, q_knee) (the closed form of
:mod:`exo_ctrl.plant.contact`), is a known external torque: the cuff-force
estimators (:mod:`exo_ctrl.estimation`) are given τ_s + τ_g, the torque
sensors' reading with it, as the torque acting on the legs besides the
cuffs' (logged as ``tau_ground_meas``, so the offline estimate adds the same).

**Contact threshold.**  A plate whose vertical reading is below
F_c = c σ_F (c = ``contact_threshold_sd``, default 5) carries no foot: its
reading is the cells' noise, and the device adds nothing (τ_g = 0; the
reading itself is still logged and watched by the belt monitor).  Without
it the swing foot's noise, σ_F through the foot's lever arm (about 0.5 m
below the knee: 1 N·m per tick, five times the joint torque sensor's
0.2 N·m), entered every estimate as a torque the cuffs had made: on the
default scenario, whose feet skim the belt (peak ground force under 1 N),
it was 1.7 points of the shank cuffs' 5.9–6.1 % normal error after the
ramp-in (4.0–4.2 % with it; ``docs/performance.md``).  Five standard
deviations: noise alone crosses it with a probability of 3·10⁻⁷ a reading
(chosen); a foot loaded below F_c (10 N with the default cells) is missed,
a torque of at most F_c times its lever arm, during touchdown and lift-off only.

**The patient's feet** (``ContactParams.patient_feet``,
:mod:`exo_ctrl.plant.patient_feet`): where the patient's shoes meet the belt
they too carry load and pull on the belt.  The device reads them with load
cells of the same class under each shoe (instrumented shoes measuring the
ground reaction force: Liedtke et al. 2007, Gait & Posture 26:39-47;
Schepers, Koopman & Veltink 2007, IEEE Trans. Biomed. Eng. 54:895-902), the
same noise σ_F from a stream of their own (seed [``seed``, 1]): rows 2-3 of
``force``.  Their force acts on the patient's legs, which reach the device
through the cuffs, so it is no part of τ_g (the cuff estimate would
otherwise lose it); the belt monitor (:mod:`exo_ctrl.safety.belt_monitor`)
counts it among the forces on the belt.  Without the patient's feet those
rows stay zero.

**Defaults** (chosen; the class of a strain-gauge foot plate of 2 kN range
read at 0.1 % of its range): ``noise_std_N`` = 2 N, ``seed`` = 2 (a stream
of its own, apart from the joint sensors' and the current sensors').
:meth:`FootLoadParams.ideal` reads the force exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import kernel, record
from ..model import BodyModel
from ..model.leg_kernels import LEG_FIELDS, fill_legs, foot_point

__all__ = ["FOOT_LOAD_FIELDS", "FootLoad", "FootLoadParams"]

#: Noise samples drawn at a time, per component.
NOISE_BLOCK = 1000


@dataclass(frozen=True)
class FootLoadParams:
    """The two foot plates' load cells (module docstring).

    Attributes:
        noise_std_N: σ_F, white noise on each force component, std [N].
        seed: seed of the noise generator (an integer >= 0).
        contact_threshold_sd: c, the contact threshold F_c = c σ_F on the
            vertical reading below which a plate adds no torque (module
            docstring; default 5, chosen) [-].

    Raises:
        InvalidParameter: a negative noise or threshold, a seed that is not
            an integer >= 0.

    """

    noise_std_N: float = 2.0
    seed: int = 2
    contact_threshold_sd: float = 5.0

    def __post_init__(self) -> None:
        v.non_negative("foot load cell noise_std", self.noise_std_N, "N")
        v.non_negative("foot load cell contact_threshold_sd", self.contact_threshold_sd)
        v.seed("foot load cell seed", self.seed)

    @classmethod
    def ideal(cls) -> FootLoadParams:
        """The exact force: no noise."""
        return cls(noise_std_N=0.0)


#: Fields of the load cells' record: the device's leg geometry per leg
#: (``l1``, ``l2`` [m], ``s_h``, ``s_k``, ``phi1_0``, ``phi2_0`` [rad]);
#: ``force`` the reading (x, z) per foot [N] (rows: exoskeleton left, right,
#: patient left, right; the patient's zero without their feet on the belt),
#: ``tau`` τ_g [N·m] (4), ``tau_known`` τ_s + τ_g [N·m] (4), ``threshold``
#: F_c [N] (the contact threshold, module docstring), ``row``
#: of the noise blocks, ``depleted``, ``noise`` (NOISE_BLOCK, 4) [N] and
#: ``patient_noise`` (NOISE_BLOCK, 4) [N] (drawn with the patient's feet only).
FOOT_LOAD_FIELDS = [
    *LEG_FIELDS,
    ("force", np.float64, (4, 2)),
    ("tau", np.float64, (4,)),
    ("tau_known", np.float64, (4,)),
    ("threshold", np.float64),
    ("row", np.int64),
    ("depleted", np.bool_),
    ("noise", np.float64, (NOISE_BLOCK, 4)),
    ("patient_noise", np.float64, (NOISE_BLOCK, 4)),
]


class FootLoad:
    """The foot plates' load cells, read once per control tick.

    Args:
        params: the load cells.
        exo: the exoskeleton model the device holds (its legs' geometry).
        patient_feet: the plant's record of the patient's feet
            (:mod:`exo_ctrl.plant.patient_feet`) when they meet the belt: the
            shoes' load cells are read too (module docstring); None: not.

    """

    def __init__(
        self, params: FootLoadParams, exo: BodyModel, patient_feet: np.ndarray | None = None
    ) -> None:
        self.params = params
        self.record = record(FOOT_LOAD_FIELDS)
        r = self.record[0]
        fill_legs(r, exo)
        r["threshold"] = params.contact_threshold_sd * params.noise_std_N
        #: The foot plates' reading (x, z) per foot [N], (2, 2), and τ_g [N·m],
        #: (4,): views of the record.
        self.force = r["force"][:2]
        self.tau = r["tau"]
        #: Every reading of a force on the belt (x, z) [N], (4, 2): the plates',
        #: then the patient's shoes' (zero without them).
        self.belt_force = r["force"]
        #: Feet whose force on the belt the device reads: 2, or 4 with the patient's.
        self.feet = 2 if patient_feet is None else 4
        #: τ_s + τ_g of the last read [N·m], (4,): what the estimators are given.
        self.tau_known = r["tau_known"]
        self._noise = r["noise"]
        self._rng = np.random.default_rng(params.seed)
        self._patient = patient_feet
        self._patient_rng = None
        if patient_feet is not None:
            self._patient_rng = np.random.default_rng([params.seed, 1])
        self.draw()

    def read(self, contact: Any, q_meas: np.ndarray, tau_sensor: np.ndarray) -> np.ndarray:
        """Read the plant's foot forces (``contact``: its record); returns :attr:`tau_known`.

        ``q_meas``: the encoders' angles [rad]; ``tau_sensor``: the joint
        torque sensors' reading [N·m], to which τ_g is added.
        """
        if self._patient is not None:  # before read_foot_load moves the row on
            read_shoe_load(self.record, self._patient)
        read_foot_load(self.record, contact, q_meas, tau_sensor)
        if self.record["depleted"][0]:
            self.draw()
        return self.tau_known

    def draw(self) -> None:
        """Draw the next block of noise (a read calls it when the block is used up)."""
        self._rng.standard_normal(out=self._noise)
        np.multiply(self._noise, self.params.noise_std_N, out=self._noise)
        if self._patient_rng is not None:
            noise = self.record["patient_noise"][0]
            self._patient_rng.standard_normal(out=noise)
            np.multiply(noise, self.params.noise_std_N, out=noise)
        self.record["row"][0] = 0
        self.record["depleted"][0] = False


@kernel
def read_foot_load(sensor: np.ndarray, contact: Any, q: np.ndarray, tau_s: np.ndarray) -> None:
    """F_m = F + n_F per foot, τ_g = Jᵀ F_m at the encoder angles ``q``, and τ_s + τ_g.

    τ_g = 0 for a foot whose vertical reading is below ``threshold`` (F_c).

    ``contact``: the plant's contact record (:data:`~exo_ctrl.plant.contact.CONTACT_FIELDS`;
    ``ft``, ``fn`` of the last step).
    """
    s = sensor[0]
    c = contact[0]
    i = s.row
    for leg in range(2):
        fx = c.ft[leg] + s.noise[i, 2 * leg]
        fz = c.fn[leg] + s.noise[i, 2 * leg + 1]
        s.force[leg, 0], s.force[leg, 1] = fx, fz
        if fz < s.threshold:  # no foot on the plate: its reading is noise
            fx = fz = 0.0
        _, _, jx0, jx1, jz0, jz1 = foot_point(s, leg, q[2 * leg], q[2 * leg + 1])
        s.tau[2 * leg] = jx0 * fx + jz0 * fz
        s.tau[2 * leg + 1] = jx1 * fx + jz1 * fz
    for j in range(4):
        s.tau_known[j] = tau_s[j] + s.tau[j]
    s.row = i + 1
    s.depleted = i + 1 == s.noise.shape[0]


@kernel
def read_shoe_load(sensor: np.ndarray, feet: Any) -> None:
    """The patient's shoes: rows 2-3 of ``force``, F + n_F at this tick's noise row.

    ``feet``: the plant's patient feet record (``ft``, ``fn`` of the last step).
    """
    s = sensor[0]
    f = feet[0]
    i = s.row
    for leg in range(2):
        s.force[2 + leg, 0] = f.ft[leg] + s.patient_noise[i, 2 * leg]
        s.force[2 + leg, 1] = f.fn[leg] + s.patient_noise[i, 2 * leg + 1]
