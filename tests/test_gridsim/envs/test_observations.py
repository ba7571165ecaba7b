"""Observation types (``observation_type=``): the built-in ``grids`` and ``kinematics``, a
type registered from outside the package, and the error for an unknown one."""

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

import gridsim  # noqa: F401  (registers GridSim-v0)
from gridsim.envs import ENV_ID
from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.envs.observations import (
    OBSERVATION_TYPES,
    KinematicsObservation,
    ObservationType,
)

SHORT = {"simulation": {"duration": 4.0}}


@pytest.mark.parametrize("scenario", ["seamless", "inner_city", "us101_4_1"])
def test_kinematics_passes_check_env_and_holds_the_nearest_vehicles(scenario):
    env = gym.make(ENV_ID, scenario=scenario, observation_type="kinematics", **SHORT)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
    assert not [w for w in caught if "reward" not in str(w.message)
                and "symmetric and normalized" not in str(w.message)]  # fmt: skip
    grids = GridSimEnv(scenario, **SHORT)  # the same episode with the default observation
    obs, info = env.reset(seed=3)
    ref, _ = grids.reset(seed=3)
    for _ in range(5):
        assert set(obs) == {"ego", "destination", "vehicles"}
        np.testing.assert_array_equal(obs["ego"], ref["ego"])
        np.testing.assert_array_equal(obs["destination"], ref["destination"])
        rows = obs["vehicles"]
        assert rows.shape == (KinematicsObservation.VEHICLES, 7) and rows.dtype == np.float32
        present = rows[:, 0] == 1
        n = int(present.sum())
        assert present[:n].all() and not rows[n:].any()  # vehicles first, then zero rows
        dist = np.hypot(rows[:n, 1], rows[:n, 2])
        assert (np.diff(dist) >= 0).all()  # nearest first
        # the same vehicles, recomputed from the world: centres in the grid frame
        w = env.unwrapped.world
        f = w.traffic.fleet
        act = np.flatnonzero(f.active)
        centres = env.unwrapped.to_grid(np.column_stack([f.x[act], f.y[act]]))
        all_dist = np.sort(np.hypot(centres[:, 0], centres[:, 1]))
        in_range = all_dist[all_dist <= env.unwrapped.cfg.sensor.max_range]
        np.testing.assert_allclose(dist, in_range[:n], rtol=1e-5, atol=1e-4)
        assert n == min(len(in_range), KinematicsObservation.VEHICLES)
        np.testing.assert_allclose(rows[:n, 5] ** 2 + rows[:n, 6] ** 2, 1.0, rtol=1e-5)
        action = info["reference_setpoints"]
        obs, reward, term, trunc, info = env.step(action)
        ref, ref_reward, *_, ref_info = grids.step(action)
        # no grid rendered, the same episode: rewards and poses bit for bit
        np.testing.assert_array_equal(reward, ref_reward)
        np.testing.assert_array_equal(info["pose"], ref_info["pose"])
        if term or trunc:
            break


def test_kinematics_velocities_are_relative_to_the_ego():
    env = GridSimEnv("seamless", observation_type="kinematics", **SHORT)
    obs, _ = env.reset(seed=0)
    w = env.world
    f = w.traffic.fleet
    act = np.flatnonzero(f.active)
    centres = env.to_grid(np.column_stack([f.x[act], f.y[act]]))
    nearest = act[np.argmin(np.hypot(centres[:, 0], centres[:, 1]))]
    row = obs["vehicles"][0]
    # north_up grid: the grid frame's axes are the world's
    vx = f.v[nearest] * math.cos(f.psi[nearest]) - w.ego[3] * math.cos(w.ego[2])
    vy = f.v[nearest] * math.sin(f.psi[nearest]) - w.ego[3] * math.sin(w.ego[2])
    np.testing.assert_allclose(row[3:5], [vx, vy], rtol=1e-5, atol=1e-5)


class SpeedOnly(ObservationType):
    """A toy type: the ego's speed alone."""

    def _make_space(self):
        return spaces.Box(0.0, 100.0, (1,), np.float32)

    def observe(self, env):
        return env.ego_features()[:1].copy()


@pytest.fixture
def speed_only():
    OBSERVATION_TYPES["speed_only"] = SpeedOnly
    yield
    del OBSERVATION_TYPES["speed_only"]


def test_a_registered_observation_type_drives_end_to_end(speed_only):
    env = gym.make(ENV_ID, observation_type="speed_only", **SHORT)
    assert env.observation_space == spaces.Box(0.0, 100.0, (1,), np.float32)
    obs, info = env.reset(seed=1)
    speeds = [obs[0]]
    for _ in range(10):
        obs, reward, term, trunc, info = env.step(info["reference_setpoints"])
        assert env.observation_space.contains(obs)
        speeds.append(obs[0])
    np.testing.assert_allclose(speeds[-1], info["pose"][3], rtol=1e-6)
    assert len(set(speeds)) > 1  # it moves


def test_the_newest_grid_is_the_last_of_the_grids_and_passes_check_env():
    """``observation_type="grid"``: the same episode as ``"grids"``, whose history is the
    first grid repeated after a reset, then one newest grid more per step."""
    env = GridSimEnv(observation_type="grid", **SHORT)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    assert not [w for w in caught if "reward" not in str(w.message)
                and "symmetric and normalized" not in str(w.message)]  # fmt: skip
    grids = GridSimEnv(**SHORT)
    obs, info = env.reset(seed=5)
    ref, _ = grids.reset(seed=5)
    history = [obs["grid"]] * env.cfg.env.history
    for _ in range(12):
        assert set(obs) == {"grid", "ego", "destination"} and obs in env.observation_space
        np.testing.assert_array_equal(np.stack(history), ref["grids"])
        for key in ("ego", "destination"):
            np.testing.assert_array_equal(obs[key], ref[key])
        action = info["reference_setpoints"]
        obs, *_, info = env.step(action)
        ref, *_ = grids.step(action)
        history = history[1:] + [obs["grid"]]


def test_an_unknown_observation_type_is_refused_with_the_choices():
    with pytest.raises(ValueError, match=r"observation_type must be one of \['grid', 'grids', "
                       r"'kinematics'\], got 'lidar'"):  # fmt: skip
        GridSimEnv(observation_type="lidar")


def test_kinematics_renders_no_grid_unless_frames_are_rendered():
    env = GridSimEnv(observation_type="kinematics", **SHORT)
    env.reset(seed=0)
    with pytest.raises(RuntimeError, match="'kinematics' renders no grids"):
        env.grid_history()
    shown = GridSimEnv(observation_type="kinematics", render_mode="rgb_array", **SHORT)
    shown.reset(seed=0)
    shown.step(shown.action_space.sample())
    assert shown.grid_history().any() and shown.render().ndim == 3  # the sensor inset's grid


def test_building_blocks_need_a_reset():
    env = GridSimEnv(**SHORT)
    for block in (env.grid_history, env.ego_features, env.destination):
        with pytest.raises(RuntimeError, match=r"call reset\(\) before"):
            block()
