"""Your own planner in GridSim-v0, filmed: a policy is any ``(env, obs, info) -> action``;
this one plans the 5 set-points along the ego's heading at the speed it keeps, a constant-
velocity planner, and the video shows its plan beside the human's.

    python examples/07_custom_policy.py [--quick] [--video constant_velocity.mp4]
"""

import argparse

import gymnasium as gym
import numpy as np

import gridsim  # noqa: F401  (registers GridSim-v0)
from gridsim.video import record_episode


class ConstantVelocity:
    """Set-points where the ego would be holding its speed and heading (grid frame)."""

    action_type = "trajectory"

    def __call__(self, env, obs, info):
        # the observation's ego vector: speed [m/s], ..., cos and sin of the heading in the
        # grid frame, whose origin is the ego's rear axle
        speed, cos_h, sin_h = obs["ego"][0], obs["ego"][4], obs["ego"][5]
        times = env.unwrapped.cfg.env.setpoint_times  # [s] after this decision
        ahead = speed * times  # [m] along the heading
        return np.stack([ahead * cos_h, ahead * sin_h], axis=1).astype(np.float32)


ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--quick", action="store_true", help="a short episode (for CI)")
ap.add_argument(
    "--video",
    default="constant_velocity.mp4",
    help="where to write the video (.mp4 or .gif; default: %(default)s)",
)
args = ap.parse_args()

env = gym.make("GridSim-v0", scenario="seamless", render_mode="rgb_array")
episode, video = record_episode(env, ConstantVelocity(), args.video,
                                steps=20 if args.quick else 600, seed=0)  # fmt: skip
summary = episode.summary()
print(f"{summary['steps']} decisions, ended by {summary['ended_by']}, l1 "
      f"{summary['fitness_sums']['l1']:.1f} m^2 from the human; video {video} "
      f"({video.stat().st_size // 1024} kB)")  # fmt: skip
