"""Several environments at once: gym.make_vec gives the fitness vector of every environment,
rewards of shape (num_envs, 3); asynchronous=True runs one subprocess per environment.

    python examples/02_vector_envs.py [--quick]
"""

import argparse

import gymnasium as gym

import gridsim  # noqa: F401  (registers GridSim-v0)

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--quick", action="store_true", help="fewer steps (for CI)")
args = ap.parse_args()

venv = gym.make_vec("GridSim-v0", num_envs=4, asynchronous=not args.quick,
                    scenario="inner_city", action_type="control")  # fmt: skip
obs, info = venv.reset(seed=0)
for _ in range(5 if args.quick else 200):
    obs, rewards, terminated, truncated, info = venv.step(venv.action_space.sample())
print("rewards", rewards.shape, "per environment [l1, l2, l3]:")
print(rewards)
venv.close()
