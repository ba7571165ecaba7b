"""Built-in scripted policies for ``gridsim run`` and tests: ``(env, obs, info) -> action``.

Each declares the action type it needs (:attr:`action_type`).
"""

from __future__ import annotations

import numpy as np


class Idle:
    """Hands off: no acceleration, no steering (keeps its speed and its wheel angle)."""

    action_type = "control"

    def __call__(self, env, obs, info):
        return np.zeros(2, np.float32)


class Reference:
    """Feeds the reference set-points (the human future) back as the trajectory action."""

    action_type = "trajectory"

    def __call__(self, env, obs, info):
        return info["reference_setpoints"]


class LaneFollow:
    """Keeps its lane or route at 90 % of the ego's top speed, braking for traffic (IDM)."""

    action_type = "control"

    def __call__(self, env, obs, info):
        from gridsim.world.scripted_drivers import LaneFollower  # compiled: loaded on first use

        world = env.unwrapped.world
        follower = LaneFollower(speed=0.9 * world.ego_params.v_max)
        return np.array(follower(world), np.float32)


class Random:
    """Uniformly random controls from the action space (seeded by the environment): the
    acceleration is drawn from ``[-b_max, a_max]``, so it brakes on average (-2 m/s^2 with the
    default limits) and the car soon stands; ``lane-follow`` drives on."""

    action_type = "control"

    def __call__(self, env, obs, info):
        return env.action_space.sample()


#: The policies by name (``gridsim run --policy NAME``); importing this module is cheap.
POLICIES = {"idle": Idle, "reference": Reference, "lane-follow": LaneFollow, "random": Random}
