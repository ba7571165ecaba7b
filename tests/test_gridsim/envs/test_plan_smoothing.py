"""Plan smoothing: each followed plan blends the new plan with the previous one, re-timed."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.envs.plan_smoothing import PlanSmoother, retime
from gridsim.envs.wrappers import PlanSmoothing
from neurotrajectory.evolve.fitness import Evaluator
from neurotrajectory.evolve.genome import initial_genome, set_genome
from neurotrajectory.model import PRESETS, NetConfig, NetPolicy, TrajectoryNet

SHORT = {"simulation": {"duration": 3.0}}
#: float32 actions through two frame rotations
FRAME_TOLERANCE = 1e-5


def test_retime_interpolates_in_time_and_extrapolates_along_the_last_segment():
    times = np.array([0.0, 0.5, 1.0])
    points = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 2.0]])
    at = np.array([0.25, 0.75, 1.0, 1.5])
    want = [[2.5, 0.0], [7.5, 1.0], [10.0, 2.0], [15.0, 4.0]]
    np.testing.assert_allclose(retime(times, points, at), want)


def _plan(env, lateral):
    """A plan along the grid's x axis at the ego's speed, ``lateral`` [m] to the left."""
    times = env.cfg.env.setpoint_times
    speed = max(float(env.world.ego[3]), 1.0)
    return np.stack([speed * times, np.full_like(times, lateral)], 1).astype(np.float32)


def test_the_followed_plan_is_the_blend_of_the_new_and_the_previous():
    env = GridSimEnv("seamless", **SHORT)
    env.reset(seed=3)
    keep = 0.7
    smoother = PlanSmoother(keep)
    first = smoother(env, _plan(env, 0.0))  # the first plan of an episode: as given
    np.testing.assert_allclose(first, _plan(env, 0.0), atol=FRAME_TOLERANCE)
    second = smoother(env, _plan(env, 1.0))  # same time: the previous plan is the first
    want = keep * _plan(env, 0.0) + (1 - keep) * _plan(env, 1.0)
    np.testing.assert_allclose(second, want, atol=FRAME_TOLERANCE)
    # after a step, a new plan equal to the previous one re-timed is followed unchanged
    t0, xy0 = env.world.time, env.world.ego[:2].copy()
    previous = env.to_world(second.astype(np.float64))
    env.step(second)
    times = env.world.time + env.cfg.env.setpoint_times
    knots = np.concatenate(([t0], t0 + env.cfg.env.setpoint_times))
    retimed = env.to_grid(retime(knots, np.vstack([xy0, previous]), times)).astype(np.float32)
    np.testing.assert_allclose(smoother(env, retimed), retimed, atol=FRAME_TOLERANCE)
    env.reset(seed=4)  # a new episode forgets the last one's plan
    np.testing.assert_allclose(
        smoother(env, _plan(env, 2.0)), _plan(env, 2.0), atol=FRAME_TOLERANCE
    )


def test_keep_zero_follows_every_plan_as_given_and_actions_are_clipped():
    env = GridSimEnv("seamless", **SHORT)
    env.reset(seed=3)
    smoother = PlanSmoother(0.0)
    for lateral in (0.0, 1.5, -1.0):
        np.testing.assert_allclose(
            smoother(env, _plan(env, lateral)), _plan(env, lateral), atol=FRAME_TOLERANCE
        )
    far = np.full(env.action_space.shape, 1e6, np.float32)
    np.testing.assert_allclose(smoother(env, far), env.action_space.high, rtol=1e-6)


def _drive(env, keep, jitter=0.4):
    """Sum of l2 and whether the episode failed, for a planner that follows the reference
    ``jitter`` [m] to the left, then to the right, alternating every decision."""
    env = PlanSmoothing(env, keep) if keep else env
    obs, info = env.reset(seed=11)
    l2, sign, failed = 0.0, 1.0, False
    while True:
        plan = info["reference_setpoints"] + np.array([0.0, sign * jitter], np.float32)
        obs, r, term, trunc, info = env.step(plan)
        l2, sign = l2 + float(r[1]), -sign
        failed |= info["collision"] or info["off_road"]
        if term or trunc:
            return l2, failed


def test_smoothing_calms_a_jittering_planner():
    jittery, failed = _drive(GridSimEnv("seamless", simulation={"duration": 6.0}), 0.0)
    calm, failed_smoothed = _drive(GridSimEnv("seamless", simulation={"duration": 6.0}), 0.7)
    assert not failed and not failed_smoothed
    assert calm < jittery / 3, (calm, jittery)


def test_smoothed_fitness_in_training_is_the_smoothed_policy_s():
    cfg = PRESETS["tiny"]
    smoothed = Evaluator("seamless", SHORT, replace(cfg, smoothing=0.6), [5])
    plain = Evaluator("seamless", SHORT, cfg, [5])
    genome = initial_genome(smoothed.net, 1)
    rng = np.random.default_rng(0)
    genome += np.float32(0.05) * rng.standard_normal(genome.shape[0], dtype=np.float32)
    fitness, _ = smoothed.evaluate(genome)
    assert not np.allclose(fitness, plain.evaluate(genome)[0])  # it takes effect
    torch.set_num_threads(1)
    net = TrajectoryNet(smoothed.net_cfg)
    set_genome(net, genome)
    policy = NetPolicy(net)  # smoothing from the network's configuration
    env = GridSimEnv("seamless", **SHORT)
    obs, info = env.reset(seed=5)
    total = np.zeros(3)
    while True:
        obs, r, term, trunc, info = env.step(policy(env, obs, info))
        total += r
        if term or trunc:
            break
    assert not term  # no padding of an early ending in the evaluator's fitness
    # the batched forward pass differs from TrajectoryNet's by float rounding only
    np.testing.assert_allclose(fitness, total, rtol=1e-4)


@pytest.mark.parametrize(
    ("keep", "text"),
    [
        (1.0, "must be in [0, 1), got 1.0"),
        (-0.1, "must be in [0, 1), got -0.1"),
        (float("nan"), "must be in [0, 1), got nan"),
        ("0.5", "must be a number in [0, 1), got '0.5'"),
        (True, "must be a number in [0, 1), got True"),
    ],
)
def test_bad_keep_values_are_refused_by_name(keep, text):
    with pytest.raises(ValueError) as info:
        PlanSmoother(keep)
    assert str(info.value).startswith("plan smoothing (the share of the previous plan kept)")
    assert text in str(info.value)
    with pytest.raises(ValueError, match="smoothing"):
        NetConfig(smoothing=keep)


def test_misuse_gets_a_clear_error():
    env = GridSimEnv("seamless", **SHORT)
    with pytest.raises(RuntimeError, match=r"call reset\(\) before to_world\(\)"):
        PlanSmoother(0.5)(env, np.zeros((5, 2), np.float32))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"must have shape \(5, 2\), got \(2,\)"):
        PlanSmoother(0.5)(env, np.zeros(2, np.float32))
    with pytest.raises(ValueError, match="make the environment with action_type='trajectory'"):
        PlanSmoothing(GridSimEnv("seamless", action_type="control", **SHORT), 0.5)
