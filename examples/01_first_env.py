"""Your first GridSim-v0 episode: make the environment, follow the human reference, read the
fitness vector [l1, l2, l3] the paper trains on.

    python examples/01_first_env.py [--quick]
"""

import argparse

import gymnasium as gym
import numpy as np

import gridsim  # noqa: F401  (registers GridSim-v0)

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--quick", action="store_true", help="a short episode (for CI)")
args = ap.parse_args()

env = gym.make("GridSim-v0", scenario="seamless")
obs, info = env.reset(seed=0)
print("observation:", {k: v.shape for k, v in obs.items()})  # grids (5, 128, 128), ego, destination
print("action: 5 set-points (x, y) [m] in the grid frame,", env.action_space)

total, taken = np.zeros(3), 0
steps = 30 if args.quick else 600
for _ in range(steps):
    # the human's next 5 set-points: a perfect planner's action (l1 = 0)
    obs, fitness, terminated, truncated, info = env.step(info["reference_setpoints"])
    total += fitness  # each step's fitness sums its ticks' (one tick a step by default)
    taken += 1
    if terminated or truncated:
        break
print(
    f"after {info['time']:.1f} s, the fitness summed over {taken} steps: l1 {total[0]:.2f} m^2 "
    f"(distance to the human), l2 {total[1]:.2f} rad/s (steering rate), l3 {total[2]:.1f} m/s "
    f"(speed; a mean of {total[2] / taken:.1f} m/s a step)"
)
