"""The Gymnasium environment (the optional extra ``gym``): ``exo_ctrl/Treadmill-v0``.

Importing this package registers :class:`TreadmillEnv` with Gymnasium as
:data:`ENV_ID`, so ``gymnasium.make("exo_ctrl/Treadmill-v0", action="torque")``
works after ``import exo_ctrl.envs`` (or, without the import,
``gymnasium.make("exo_ctrl.envs:exo_ctrl/Treadmill-v0")``, which imports it).
Without gymnasium installed the import raises
:class:`~exo_ctrl.exceptions.MissingDependency` with the install hint.
See docs/gym.md.
"""

from ..exceptions import MissingDependency

try:
    import gymnasium
except ImportError:  # the optional extra
    raise MissingDependency(
        'the Gymnasium environment needs gymnasium: pip install "exo-ctrl[gym]"'
    ) from None

from .observation import OBSERVATION_NAMES
from .reward import REWARD_TERMS, RewardWeights
from .treadmill import ACTIONS, TreadmillEnv

__all__ = [
    "ACTIONS",
    "ENV_ID",
    "OBSERVATION_NAMES",
    "REWARD_TERMS",
    "RewardWeights",
    "TreadmillEnv",
]

#: The environment's id in Gymnasium's registry.
ENV_ID = "exo_ctrl/Treadmill-v0"

if ENV_ID not in gymnasium.registry:  # a second import (a reload) registers nothing
    gymnasium.register(id=ENV_ID, entry_point="exo_ctrl.envs.treadmill:TreadmillEnv")
