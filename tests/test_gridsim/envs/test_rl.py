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


def test_sb3_make_vec_env_trains_on_the_registered_scalar_variant(tmp_path):
    """make_vec_env wraps its Monitor around the env before any wrapper_class: the scalar
    variant gives it a scalar reward, the weights as a keyword; the vector stays in info."""
    import torch
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import configure

    from gridsim.envs import SCALAR_ENV_ID

    torch.set_num_threads(1)
    weights = (-0.02, -1.0, 0.2)
    kwargs = {"weights": weights, "action_type": "control", "simulation": {"duration": 3.0},
              "sensor": {"rows": 64, "cols": 64}}  # fmt: skip
    venv = make_vec_env(SCALAR_ENV_ID, n_envs=2, seed=0, env_kwargs=kwargs)
    venv.reset()
    _, rewards, _, infos = venv.step(np.zeros((2, 2), np.float32))
    assert rewards.shape == (2,)
    np.testing.assert_allclose(rewards, [np.dot(weights, i["fitness"]) for i in infos], rtol=1e-5)
    model = sb3.PPO("MultiInputPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0,
                    device="cpu", verbose=0)  # fmt: skip
    model.set_logger(configure(str(tmp_path), []))
    model.learn(total_timesteps=64)
    with pytest.raises(ValueError, match="weights must be 3 finite numbers"):
        gym.make(SCALAR_ENV_ID, weights=(1.0, 2.0))


def test_a_vector_env_without_autoreset_goes_on_after_resetting_what_ended():
    """``autoreset_mode=DISABLED``: the user resets the environments that ended, with a reset
    mask, as the docs say; the rewards stay vectors."""
    venv = gym.make_vec("GridSim-v0", num_envs=2, simulation={"duration": 1.0},
                        autoreset_mode=gym.vector.AutoresetMode.DISABLED)  # fmt: skip
    _, info = venv.reset(seed=0)
    ends = 0
    for _ in range(25):
        actions = np.stack([info["reference_setpoints"][i] for i in range(2)])
        _, rewards, terminated, truncated, info = venv.step(actions)
        assert rewards.shape == (2, 3)
        if (done := terminated | truncated).any():
            ends += int(done.sum())
            _, info = venv.reset(options={"reset_mask": done})
    assert ends >= 4
