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

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .. import _validate as v

__all__ = ["REWARD_TERMS", "RewardWeights", "drawn_energy_J", "reward_terms"]

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
            value = v.non_negative(f"reward weight {name} [{unit}]", getattr(self, name))
            object.__setattr__(self, name, value)

    @property
    def vector(self) -> np.ndarray:
        """(w_q, w_f, w_e), in :data:`REWARD_TERMS` order."""
        return np.array([self.tracking, self.interaction, self.energy])


def reward_terms(rows: Mapping[str, np.ndarray], dt_s: float, drawn_J: float) -> np.ndarray:
    """(E_q, E_f, E_e) of the ticks in ``rows`` (module docstring), (3,).

    Args:
        rows: the ticks' logged signals (``q_des``, ``q``: (n, 4) [rad];
            ``cuff_force``: (n, 4, 2) [N]).
        dt_s: the control period Δt [s].
        drawn_J: E_e, the energy the drives drew from the supply over the ticks [J]
            (:func:`drawn_energy_J` after less before).

    """
    track = float(np.sum((rows["q_des"] - rows["q"]) ** 2)) * dt_s
    force = float(np.sum(rows["cuff_force"] ** 2)) * dt_s
    return np.array([track, force, drawn_J])


def drawn_energy_J(motors: np.ndarray | None) -> float:
    """The energy the drives have drawn from the supply since the run's start [J].

    Σ_j (net electrical + regenerated), the sum over the plant's steps of
    max(W, 0) (:mod:`exo_ctrl.plant.energy`); ``motors``: the drives'
    record (None: no drives, 0).
    """
    if motors is None:
        return 0.0
    m = motors[0]
    return float(np.sum(m["e_electrical"]) + np.sum(m["e_regenerated"]))
