"""Action types (``action_type=``): a type registered from outside the package drives the
env end to end, and an unknown name is refused naming the registered ones."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

import gridsim  # noqa: F401  (registers GridSim-v0)
from gridsim.envs import ENV_ID
from gridsim.envs.actions import ACTION_TYPES, ActionType, HeldInputs, rollout_controls


class BrakeAction(ActionType):
    """A toy action: the share of the braking limit to apply, wheel held straight."""

    def _make_space(self) -> spaces.Box:
        return spaces.Box(0.0, 1.0, shape=(1,), dtype=np.float32)

    def controller(self, world, action, rotation):
        accel = -float(np.clip(action[0], 0.0, 1.0)) * self.params.b_max
        plan = rollout_controls(world.ego, accel, 0.0, self.params, self.period, self.horizon)
        return HeldInputs(accel, 0.0), plan


def test_a_registered_action_type_drives_the_env(monkeypatch):
    monkeypatch.setitem(ACTION_TYPES, "brake", BrakeAction)
    env = gym.make(ENV_ID, scenario="seamless", action_type="brake",
                   simulation={"duration": 6.0})  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the env checker's notes on the reward's shape
        check_env(env.unwrapped, skip_render_check=True)
    kind = env.unwrapped.action_kind
    assert isinstance(kind, BrakeAction) and env.action_space == kind.space
    assert kind.decision_period == env.unwrapped.cfg.env.decision_period
    env.reset(seed=1)
    speeds = [env.unwrapped.world.ego[3]]
    for _ in range(40):
        *_, terminated, truncated, info = env.step(np.array([0.5], np.float32))
        speeds.append(env.unwrapped.world.ego[3])
        if terminated or truncated:
            break
    dv = np.diff(speeds)
    # half the braking limit over each decision, until it stands
    b = 0.5 * kind.params.b_max * kind.decision_period
    moving = np.array(speeds[1:]) > 0
    np.testing.assert_allclose(dv[moving], -b, atol=1e-9)
    assert speeds[-1] == kind.params.v_min == 0.0  # stood still, then held


def test_an_unknown_action_type_names_the_registered_ones():
    with pytest.raises(ValueError, match=r"action_type must be one of \['control', 'discrete', "
                       r"'trajectory'\], got 'brake'"):  # fmt: skip
        gym.make(ENV_ID, scenario="seamless", action_type="brake")
