"""Stable-Baselines3 PPO on GridSimScalar-v0: GridSim-v0 with its fitness vector weighted into
one scalar reward (the keyword ``weights``), as single-objective libraries need.

    pip install stable-baselines3
    python examples/03_sb3_ppo.py [--quick]
"""

import argparse

from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

import gridsim  # noqa: F401  (registers GridSim-v0 and GridSimScalar-v0)

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--quick", action="store_true", help="a few hundred steps (for CI)")
args = ap.parse_args()

env_kwargs = {
    "weights": (-0.01, -0.5, 0.1),  # l1 and l2 are costs, l3 (speed) a reward
    "action_type": "control",  # acceleration and steering rate
    "sensor": {"rows": 64, "cols": 64},  # smaller grids: a smaller policy network
    "simulation": {"duration": 10.0},
}
venv = make_vec_env("GridSimScalar-v0", n_envs=2, seed=0, env_kwargs=env_kwargs)
model = PPO("MultiInputPolicy", venv, n_steps=64 if args.quick else 512, batch_size=64,
            seed=0, device="cpu", verbose=0)  # fmt: skip
model.learn(total_timesteps=256 if args.quick else 50_000)
obs = venv.reset()
action, _ = model.predict(obs, deterministic=True)
print("trained; a deterministic action per environment:", action.round(3).tolist())
