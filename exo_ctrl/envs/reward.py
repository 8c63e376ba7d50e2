r"""The environment's reward: a weighted sum of tracking error, interaction force and energy.

Over the control ticks k of one environment step (each Δt long, its
voltages held over [t_k, t_k+1)), from the run's logged signals
(:mod:`exo_ctrl.sim.schema`):

.. math::

    E_q = \sum_k \sum_j (q^*_{k,j} - q_{k,j})^2\,Δt \quad [\mathrm{rad^2\,s}],

    E_f = \sum_k \sum_c \lVert f_{k,c} \rVert^2\,Δt \quad [\mathrm{N^2\,s}],

    E_e = \sum_k \sum_j \max(U_{k,j}\,\bar I_{k,j},\ 0)\,Δt \quad [\mathrm{J}],

    r = -(w_q E_q + w_f E_f + w_e E_e),

with ``q*`` the plan (``q_des``), ``q`` the exoskeleton's true joint angles
(``q``), ``f_c`` the true force on cuff c (``cuff_force``, x and z), ``U``
the voltage the drives applied (``voltage``) and ``Ī`` their mean current
over the tick (``current``): U Ī Δt is then the electrical energy into the
drive over the tick, exactly, and its positive part the energy drawn from
the supply (what a drive returns while braking is not credited, as a
driver that burns it in a brake resistor).  The truth is used, not the
device's readings: the reward judges what happened to the patient.

**Default weights** (:class:`RewardWeights`) make each term about 1 per
second of the paper's run with the built-in PD: its tracking error is about
1e-3 rad² summed over the joints, its cuff forces about 1e4 N² summed over
the cuffs, its drives draw about 100 W.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .. import _validate as v

__all__ = ["REWARD_TERMS", "RewardWeights", "reward_terms"]

#: The names of the reward's terms, in :func:`reward_terms`' order, with their units.
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
            value = v.non_negative(f"reward weight {name}", getattr(self, name), unit)
            object.__setattr__(self, name, value)

    @property
    def vector(self) -> np.ndarray:
        """(w_q, w_f, w_e), in :data:`REWARD_TERMS` order."""
        return np.array([self.tracking, self.interaction, self.energy])


def reward_terms(rows: Mapping[str, np.ndarray], dt_s: float) -> np.ndarray:
    """(E_q, E_f, E_e) of the ticks in ``rows`` (module docstring), (3,).

    Args:
        rows: the ticks' logged signals (``q_des``, ``q``: (n, 4) [rad];
            ``cuff_force``: (n, 4, 2) [N]; ``voltage`` [V], ``current`` [A]: (n, 4)).
        dt_s: the control period Δt [s].

    """
    track = float(np.sum((rows["q_des"] - rows["q"]) ** 2)) * dt_s
    force = float(np.sum(rows["cuff_force"] ** 2)) * dt_s
    energy = float(np.sum(np.maximum(rows["voltage"] * rows["current"], 0.0))) * dt_s
    return np.array([track, force, energy])
