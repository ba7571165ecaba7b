"""Third-party RL libraries train on GridSim-v0 through the scalarising wrapper."""

import gymnasium as gym
import numpy as np
import pytest

from gridsim.envs import ENV_ID
from gridsim.envs.wrappers import LinearScalarization

sb3 = pytest.importorskip("stable_baselines3")


def test_sb3_ppo_runs_a_few_hundred_steps(tmp_path):
    import torch
    from stable_baselines3.common.logger import configure

    torch.set_num_threads(1)
    env = LinearScalarization(
        gym.make(
            ENV_ID,
            action_type="control",
            simulation={"duration": 5.0},
            sensor={"rows": 64, "cols": 64},
        )  # fmt: skip
    )
    model = sb3.PPO("MultiInputPolicy", env, n_steps=64, batch_size=32, n_epochs=1, seed=0,
                    device="cpu", verbose=0)  # fmt: skip
    model.set_logger(configure(str(tmp_path), []))  # not a fresh SB3-* folder in /tmp
    model.learn(total_timesteps=256)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(np.asarray(action, np.float32))
