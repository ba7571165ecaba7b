"""A synchronous vector GridSim-v0 with vector rewards: ``gym.make_vec("GridSim-v0", n)``.

gymnasium's ``SyncVectorEnv`` keeps one float reward per environment and cannot hold the
fitness vector ``[l1, l2, l3]``; :class:`MOSyncVectorEnv` stacks them as ``(num_envs, 3)``
(as MO-Gymnasium's vector environment of the same name does). ``AsyncVectorEnv`` stacks
them already.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np


class MOSyncVectorEnv(gym.vector.SyncVectorEnv):
    """``SyncVectorEnv`` whose rewards have the shape of the environments' ``reward_space``."""

    def __init__(self, env_fns, **kwargs: Any) -> None:
        super().__init__(env_fns, **kwargs)
        space = getattr(self.envs[0].unwrapped, "reward_space", None)
        shape = space.shape if space is not None else ()
        self._rewards = np.zeros((self.num_envs, *shape), dtype=np.float64)
        self.reward_space = space


def make_vector_env(num_envs: int = 1, **kwargs: Any) -> MOSyncVectorEnv:
    """The vector entry point of GridSim-v0 (``gym.make_vec``'s default mode)."""
    from gridsim.envs.gridsim_env import GridSimEnv

    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    kwargs.pop("max_episode_steps", None)  # the scenario's duration ends episodes
    return MOSyncVectorEnv([lambda: GridSimEnv(**kwargs) for _ in range(num_envs)])
