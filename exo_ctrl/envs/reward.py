r"""The environment's reward: a weighted sum of tracking error, interaction force and energy.

Over the control ticks k of one environment step (each Δt long, its
voltages held over [t_k, t_k+1)):

.. math::

    E_q = \sum_k \sum_j (q^*_{k,j} - q_{k,j})^2\,Δt \quad [\mathrm{rad^2\,s}],

    E_f = \sum_k \sum_c \lVert f_{k,c} \rVert^2\,Δt \quad [\mathrm{N^2\,s}],

    E_e = \sum_k \sum_j \max(W_{k,j},\ 0) \quad [\mathrm{J}],

    r = -(w_q E_q + w_f E_f + w_e E_e),

with ``q*`` the plan and ``q`` the exoskeleton's true joint angles (the
log's ``q_des``, ``q``), ``f_c`` the true force on cuff c (``cuff_force``,
x and z), and W the electrical energy into drive j over tick k from the
plant's energy books (:mod:`exo_ctrl.plant.energy`): U Ī Δt with U the
voltage and Ī the mean current over the tick (the log's ``voltage``,
``current``), except on a tick where the driver's current limit holds the
current, where the driver's own lower voltage is booked (the log's
``voltage`` is then the commanded one, after the supply's clip, and
U Ī Δt overstates W).  Its positive part is the energy drawn from the supply:
what a drive returns while braking is not credited, as with a driver that
burns it in a brake resistor.  The truth is used, not the device's readings:
the reward judges what happened to the patient.

**Default weights** (:class:`RewardWeights`) make each term about 1 per
second of the paper's run with the built-in PD: its tracking error is about
1e-3 rad² summed over the joints, its cuff forces about 1e4 N² summed over
the cuffs, its drives draw about 100 W.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from .._jit import kernel

__all__ = ["REWARD_TERMS", "RewardWeights", "drawn_energy_J", "log_terms"]

#: The names of the reward's terms (E_q, E_f, E_e: module docstring), with their units.
REWARD_TERMS = ("tracking_rad2_s", "interaction_N2_s", "energy_J")


@dataclass(frozen=True)
class RewardWeights:
    """The weights of the reward's terms (module docstring).

    Attributes:
        tracking: w_q [1/(rad²·s)].
        interaction: w_f [1/(N²·s)].
        energy: w_e [1/J].

    Raises:
        InvalidParameter: a weight that is not a finite number >= 0.

    """

    tracking: float = 1e3
    interaction: float = 1e-4
    energy: float = 1e-2

    def __post_init__(self) -> None:
        units = {"tracking": "1/(rad²·s)", "interaction": "1/(N²·s)", "energy": "1/J"}
        for name, unit in units.items():
            value = v.non_negative(f"reward weight {name} [{unit}]", getattr(self, name))
            object.__setattr__(self, name, value)

    @property
    def vector(self) -> np.ndarray:
        """(w_q, w_f, w_e), in :data:`REWARD_TERMS` order."""
        return np.array([self.tracking, self.interaction, self.energy])


@kernel
def log_terms(log, first, end, dt, out):  # pragma: no cover - compiled
    """Add E_q and E_f of the log's rows ``first:end`` to ``out[0]``, ``out[1]`` (module docstring).

    ``log``: the run's log chunk (:func:`~exo_ctrl.sim.schema.log_dtype`:
    ``q_des``, ``q`` [rad], ``cuff_force`` [N]); ``dt``: Δt [s].
    """
    track = 0.0
    force = 0.0
    for i in range(first, end):
        r = log[i]
        for j in range(4):
            e = r.q_des[j] - r.q[j]
            track += e * e
            fx = r.cuff_force[j, 0]
            fz = r.cuff_force[j, 1]
            force += fx * fx + fz * fz
    out[0] += track * dt
    out[1] += force * dt


@kernel
def drawn_energy_J(motors):  # pragma: no cover - compiled
    """The energy the drives have drawn from the supply since the run's start [J].

    Σ_j (net electrical + regenerated) of the drives' record ``motors``
    (:mod:`exo_ctrl.plant.energy`): the sum over the plant's steps of max(W, 0).
    """
    m = motors[0]
    total = 0.0
    for j in range(m.e_electrical.shape[0]):
        total += m.e_electrical[j] + m.e_regenerated[j]
    return total
