"""Accuracy metrics, commands, and the constant-velocity, DWA and End2End baselines."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from gridsim.frames import grid_to_pixel
from gridsim.sensors.occupancy import FREE, OCCUPIED, UNKNOWN
from gridsim.traffic.library import TrajectoryLibrary
from gridsim.vehicle.kinematics import BicycleParams, box_corners
from neurotrajectory.compare.baselines.constant_velocity import (
    ConstantVelocity,
    constant_velocity_setpoints,
)
from neurotrajectory.compare.baselines.dwa import (
    ADMISSIBLE,
    DWA,
    MOST_CLEARANCE,
    NO_BRAKING_CHECK,
    DWAConfig,
)
from neurotrajectory.compare.baselines.end2end import End2End, TrainSettings
from neurotrajectory.compare.metrics import accuracy, ego_frame_errors
from neurotrajectory.compare.predictors import Setting
from neurotrajectory.data.commands import (
    N_STEER,
    STEER_BINS_EACH_SIDE,
    command_setpoints,
    implied_commands,
)
from neurotrajectory.data.windows import Windows

TIMES = 0.5 * np.arange(1, 6)


def make_windows(grids, ego, destination=None, target=None, vehicle=(2.7, 4.5, 1.8)):
    n = len(ego)
    zero = np.zeros(n, np.int64)
    return Windows(
        grids=np.asarray(grids, np.uint8),
        ego=np.asarray(ego, np.float32),
        destination=np.zeros((n, 2), np.float32) if destination is None else destination,
        target=np.zeros((n, 5, 2), np.float32) if target is None else target,
        steer=zero,
        longitudinal=zero,
        accel=np.zeros(n, np.float32),
        vehicle=np.tile(np.array(vehicle, np.float32), (n, 1)),
        track=np.array([f"t{i}" for i in range(n)]),
        time=np.zeros(n, np.float32),
    )


# -- metrics ----------------------------------------------------------------------------------
def test_errors_are_taken_in_the_ego_frame():
    # Ego heading north (+y in the grid frame): a prediction 1 m too far north is 1 m ahead
    # (e_x = +1); 2 m too far west is 2 m to the left (e_y = +2).
    target = np.zeros((1, 2, 2))
    predicted = np.array([[[0.0, 1.0], [-2.0, 0.0]]])
    ex, ey = ego_frame_errors(predicted, target, np.array([np.pi / 2]))
    np.testing.assert_allclose(ex, [[1.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(ey, [[0.0, 2.0]], atol=1e-12)


def test_accuracy_matches_hand_computed_values():
    target = np.zeros((2, 2, 2))
    # heading 0: e_x = dx, e_y = dy. Window 0 errors (3, 4) and (0, 0); window 1 (1, 0), (0, -2).
    predicted = np.array([[[3.0, 4.0], [0.0, 0.0]], [[1.0, 0.0], [0.0, -2.0]]])
    a = accuracy(predicted, target, np.zeros(2))
    assert a.count == 2
    assert a.mean_ex == pytest.approx((3 + 0 + 1 + 0) / 4)
    assert a.max_ex == 3.0
    assert a.mean_ey == pytest.approx((4 + 0 + 0 + 2) / 4)
    assert a.max_ey == 4.0
    assert a.rmse == pytest.approx(np.sqrt((25 + 0 + 1 + 4) / 4))
    assert a.ade == pytest.approx((5 + 0 + 1 + 2) / 4)
    assert a.fde == pytest.approx((0 + 2) / 2)
    np.testing.assert_allclose(a.rmse_per_setpoint, [np.sqrt(13), np.sqrt(2)])
    np.testing.assert_allclose(a.std_per_setpoint, [2.0, 1.0])
    np.testing.assert_allclose(a.window_rmse, [np.sqrt(12.5), np.sqrt(2.5)])


def test_accuracy_rejects_bad_input():
    with pytest.raises(ValueError, match=r"\(N, T, 2\)"):
        accuracy(np.zeros((2, 5, 2)), np.zeros((2, 4, 2)), np.zeros(2))
    with pytest.raises(ValueError, match="NaN"):
        accuracy(np.full((1, 5, 2), np.nan), np.zeros((1, 5, 2)), np.zeros(1))
    with pytest.raises(ValueError, match="no windows"):
        accuracy(np.zeros((0, 5, 2)), np.zeros((0, 5, 2)), np.zeros(0))


def test_constant_velocity_reproduces_the_ngsim_reference_figures():
    """shared notes: constant velocity from the recorded state over all complete windows of
    5 set-points 0.1 s apart gives per-set-point RMSE 0.048 / 0.107 / 0.183 / 0.277 / 0.385 m,
    overall 0.233 m."""
    preds, targets = [], []
    for track in TrajectoryLibrary.builtin().tracks:
        n = len(track.t) - 5
        if n <= 0:
            continue
        xy = np.stack([track.x, track.y], axis=1)
        idx = np.arange(n)[:, None] + np.arange(1, 6)[None, :]
        targets.append(xy[idx] - xy[:n, None])
        preds.append(constant_velocity_setpoints(track.speed[:n], track.heading[:n], TIMES / 5))
    a = accuracy(np.concatenate(preds), np.concatenate(targets), np.zeros(sum(map(len, preds))))
    assert a.count == 2628
    np.testing.assert_allclose(a.rmse_per_setpoint, [0.048, 0.107, 0.183, 0.277, 0.385],
                               atol=0.003)  # fmt: skip
    assert a.rmse == pytest.approx(0.233, abs=0.002)


def test_constant_velocity_predictor_uses_speed_and_heading():
    w = make_windows(np.zeros((1, 1, 8, 8)), [[10.0, 0, 0, 0, 0.0, 1.0]])
    setting = Setting(TIMES, 0.5, "north_up", BicycleParams())
    out = ConstantVelocity(setting).predict(w)
    np.testing.assert_allclose(out[0], np.stack([np.zeros(5), 10 * TIMES], 1), atol=1e-5)


# -- commands ---------------------------------------------------------------------------------
def test_command_trajectories_imply_their_own_commands():
    rng = np.random.default_rng(0)
    n = 200
    steer = rng.integers(0, N_STEER, n)
    lon = rng.integers(0, 3, n)
    speed = rng.uniform(4, 20, n)  # fast enough not to stop within the horizon
    heading = rng.uniform(-np.pi, np.pi, n)
    accel = np.array([-1.5, 0.0, 1.2])
    pts = command_setpoints(steer, lon, speed, heading, TIMES, accel)
    s2, l2, a2 = implied_commands(pts, speed, heading, TIMES)
    np.testing.assert_array_equal(s2, steer)
    np.testing.assert_array_equal(l2, lon)
    np.testing.assert_allclose(a2, accel[lon], atol=1e-9)


def test_braking_commands_stop_and_never_reverse():
    pts = command_setpoints(np.array([STEER_BINS_EACH_SIDE]), np.array([0]), np.array([2.0]),
                            np.array([0.0]), TIMES, np.array([-4.0, 0, 1]))  # fmt: skip
    np.testing.assert_allclose(pts[0, :, 0], [0.5, 0.5, 0.5, 0.5, 0.5])  # stops after 0.5 m


# -- DWA ----------------------------------------------------------------------------------------
CELL = 0.5
SIZE = 128


def _setting():
    params = BicycleParams(v_max=15.0, a_max=2.0, b_max=6.0, delta_max=0.6, v_delta_max=0.8)
    return Setting(TIMES, CELL, "north_up", params)


def _rect(grid, x0, x1, y0, y1, value=OCCUPIED):
    """Fill the grid-frame rectangle [x0, x1] x [y0, y1] [m] (north-up)."""
    (u0, v0), (u1, v1) = grid_to_pixel(np.array([[x0, y1], [x1, y0]]), SIZE, SIZE, CELL,
                                       "north_up")  # fmt: skip
    grid[int(np.floor(v0)) : int(np.ceil(v1)) + 1, int(np.floor(u0)) : int(np.ceil(u1)) + 1] = value


def _footprint_hits(grid, states, vehicle=(2.7, 4.5, 1.8)):
    """Occupied (or unknown) cells under the footprint at any of ``states`` (independent check:
    rasterised rectangles, not the planner's disks)."""
    wheelbase, length, width = vehicle
    hits = 0
    for x, y, psi, *_ in states:
        cx, cy = x + 0.5 * wheelbase * np.cos(psi), y + 0.5 * wheelbase * np.sin(psi)
        corners = box_corners(np.array([cx]), np.array([cy]), np.array([psi]), length, width)[0]
        uv = grid_to_pixel(corners, SIZE, SIZE, CELL, "north_up")
        mask = np.zeros_like(grid)
        cv2.fillConvexPoly(mask, np.rint(uv).astype(np.int32), 1)
        hits += int(np.sum((mask == 1) & (grid != FREE)))
    return hits


def test_dwa_never_returns_a_colliding_trajectory_on_crafted_grids():
    setting = _setting()
    dwa = DWA(setting)
    rng = np.random.default_rng(3)
    checked = 0
    for trial in range(40):
        grid = np.full((SIZE, SIZE), FREE, np.uint8)
        grid[:2], grid[-2:], grid[:, :2], grid[:, -2:] = OCCUPIED, OCCUPIED, OCCUPIED, OCCUPIED
        for _ in range(rng.integers(1, 6)):  # obstacles ahead, none on the ego
            x0, y0 = rng.uniform(6, 25), rng.uniform(-12, 12)
            _rect(grid, x0, x0 + rng.uniform(1, 5), y0, y0 + rng.uniform(1, 4))
        if trial % 4 == 0:  # walls of a corridor
            _rect(grid, -30, 30, 3.5, 4.5)
            _rect(grid, -30, 30, -4.5, -3.5)
        speed = rng.uniform(2, 12)
        goal = np.array([[speed * 2.5, rng.uniform(-6, 6)]], np.float32)
        w = make_windows(grid[None, None], [[speed, 0, 0, 0, 1.0, 0.0]], destination=goal)
        plan = dwa.plan(w, 0)
        if plan.level > NO_BRAKING_CHECK:  # the near future is checked down to this level
            continue
        checked += 1
        k = int(round(dwa.config.collision_horizon / dwa.config.dt))
        assert _footprint_hits(grid, plan.states[: k + 1]) == 0, f"trial {trial}"
    assert checked >= 30


def test_dwa_with_a_full_collision_horizon_avoids_a_stopped_car_and_heads_for_the_goal():
    grid = np.full((SIZE, SIZE), FREE, np.uint8)
    _rect(grid, 12.0, 15.0, -1.5, 1.5)  # a car stopped 12 m ahead
    goal = np.array([[20.0, 0.0]], np.float32)
    w = make_windows(grid[None, None], [[8.0, 0, 0, 0, 1.0, 0.0]], destination=goal)
    static_world = DWAConfig(collision_horizon=2.5)
    plan = DWA(_setting(), static_world).plan(w, 0)
    assert plan.feasible
    assert _footprint_hits(grid, plan.states) == 0  # over the whole horizon
    assert plan.setpoints[-1, 0] < 12.0 - 2.85 or abs(plan.setpoints[-1, 1]) > 2.0
    # the default (0.5 s) only guarantees the near future: it keeps going, and brakes later
    near = DWA(_setting()).plan(w, 0)
    k = int(round(DWAConfig().collision_horizon / DWAConfig().dt))
    assert _footprint_hits(grid, near.states[: k + 1]) == 0
    free = make_windows(np.full((1, 1, SIZE, SIZE), FREE), w.ego, destination=goal)
    free_run = DWA(_setting()).plan(free, 0)
    assert np.hypot(*(free_run.setpoints[-1] - goal[0])) < 2.0


def test_dwa_flags_a_boxed_in_ego_and_unknown_cells_can_block():
    grid = np.full((SIZE, SIZE), FREE, np.uint8)
    _rect(grid, 5.5, 7.0, -8, 8)  # a wall just ahead
    _rect(grid, -6, 5, 1.6, 3)
    _rect(grid, -6, 5, -3, -1.6)
    w = make_windows(grid[None, None], [[10.0, 0, 0, 0, 1.0, 0.0]])
    assert not DWA(_setting()).plan(w, 0).feasible
    unknown = np.full((SIZE, SIZE), FREE, np.uint8)
    _rect(unknown, 5.5, 7.0, -8, 8, UNKNOWN)
    w = make_windows(unknown[None, None], [[10.0, 0, 0, 0, 1.0, 0.0]])
    assert not DWA(_setting()).plan(w, 0).feasible
    assert DWA(_setting(), DWAConfig(unknown="penalise")).plan(w, 0).feasible


def _queue(speed: float, gap: float):
    """An ego at ``speed`` [m/s] heading +x in a lane between two walls, a car ``gap`` [m]
    ahead of its rear axle, and the destination where it would be holding speed (as if the
    car ahead moved at the ego's speed)."""
    grid = np.full((SIZE, SIZE), FREE, np.uint8)
    _rect(grid, -30, 30, 2.2, 3.0)
    _rect(grid, -30, 30, -3.0, -2.2)
    _rect(grid, gap, gap + 4.5, -0.9, 0.9)
    goal = np.array([[speed * TIMES[-1], 0.0]], np.float32)
    return make_windows(grid[None, None], [[speed, 0, 0, 0, 1.0, 0.0]], destination=goal)


@pytest.mark.parametrize(
    ("config", "gap"),
    # the defaults (0.3 s checked, 0.3 s headway), and the horizons before tuning (0.5 s)
    [(DWAConfig(), 10.0), (DWAConfig(collision_horizon=0.5, headway=0.5), 12.0)],
)
def test_dwa_does_not_brake_hard_when_only_the_braking_check_fails(config, gap):
    # every rollout clears the collision horizon, none could then stop within the headway
    w = _queue(12.0, gap)
    plan = DWA(_setting(), config).plan(w, 0)
    assert not plan.feasible and plan.admissible == 0
    assert plan.level == NO_BRAKING_CHECK
    assert plan.states[-1, 3] > 10.0  # keeps most of its 12 m/s
    assert plan.setpoints[-1, 0] > 25.0 and abs(plan.setpoints[-1, 1]) < 1.0
    k = int(round(config.collision_horizon / config.dt))
    assert _footprint_hits(w.grids[0, -1], plan.states[: k + 1]) == 0
    # the fallback before issue 10 took the first rollout of most clearance: the slowest
    # speed in the window (12 m/s - b_max * 0.5 s)
    old = DWA(_setting(), replace(config, fallback="clearance")).plan(w, 0)
    assert old.level == MOST_CLEARANCE
    assert old.states[-1, 3] == pytest.approx(9.0)


def test_dwa_fallback_leaves_admissible_plans_alone():
    dwa, old = DWA(_setting()), DWA(_setting(), DWAConfig(fallback="clearance"))
    for gap in (20.0, 30.0):
        w = _queue(12.0, gap)
        plan = dwa.plan(w, 0)
        assert plan.feasible and plan.level == ADMISSIBLE
        np.testing.assert_array_equal(plan.states, old.plan(w, 0).states)


def test_dwa_rejects_bad_configuration():
    with pytest.raises(ValueError, match="unknown must be"):
        DWAConfig(unknown="ignore")
    with pytest.raises(ValueError, match="fallback must be"):
        DWAConfig(fallback="stop")
    with pytest.raises(ValueError, match="multiples of dt"):
        DWA(Setting(np.array([0.25, 0.55]), CELL, "north_up", BicycleParams()))


# -- End2End ----------------------------------------------------------------------------------
def test_end2end_learns_a_separable_toy_task():
    """A blob on the left of the grid means 'steer left', on the right 'steer right'; in the
    upper half 'accelerate', in the lower half 'decelerate'."""
    rng = np.random.default_rng(0)
    n, size = 240, 64
    side, upper = rng.integers(0, 2, n), rng.integers(0, 2, n)
    grids = np.zeros((n, 2, size, size), np.uint8)
    for i in range(n):
        c = rng.integers(6, 24) if side[i] == 0 else rng.integers(40, 58)
        r = rng.integers(6, 24) if upper[i] == 1 else rng.integers(40, 58)
        grids[i, :, r - 5 : r + 5, c - 5 : c + 5] = OCCUPIED
    ego = np.zeros((n, 6), np.float32)
    ego[:, 0], ego[:, 4] = 5.0, 1.0
    w = make_windows(grids, ego)
    w.steer = np.where(side == 0, STEER_BINS_EACH_SIDE + 4, STEER_BINS_EACH_SIDE - 4)
    w.longitudinal = np.where(upper == 1, 2, 0)
    train, test = w.take(np.arange(180)), w.take(np.arange(180, n))
    model = End2End.train(train, _setting(), TrainSettings(epochs=30, learning_rate=3e-3),
                          preset="tiny")  # fmt: skip
    steer, lon = model.commands(test)
    assert np.mean(steer == test.steer) > 0.9
    assert np.mean(lon == test.longitudinal) > 0.9


def test_end2end_training_is_deterministic_and_round_trips(tmp_path):
    rng = np.random.default_rng(1)
    w = make_windows(rng.integers(0, 256, (16, 2, 32, 32)), rng.uniform(0, 1, (16, 6)))
    w.steer = rng.integers(0, N_STEER, 16)
    settings = TrainSettings(epochs=2)
    a = End2End.train(w, _setting(), settings, preset="tiny")
    b = End2End.train(w, _setting(), settings, preset="tiny")
    np.testing.assert_array_equal(a.predict(w), b.predict(w))
    a.save(tmp_path / "m")
    c = End2End.load(tmp_path / "m", _setting())
    np.testing.assert_array_equal(a.predict(w), c.predict(w))


def test_end2end_commands_drive_the_discrete_action():
    import torch

    from gridsim.envs.gridsim_env import GridSimEnv
    from neurotrajectory.compare.baselines.end2end import CommandPolicy, End2EndNet
    from neurotrajectory.model import PRESETS, NetConfig

    env = GridSimEnv("seamless", action_type="discrete")
    obs, info = env.reset(seed=0)
    cfg = NetConfig(**{**PRESETS["tiny"].to_dict(), "grid_size": 128})
    setting = Setting.from_env(env)

    def policy_for(steer: int, lon: int) -> CommandPolicy:
        net = End2EndNet(cfg)
        with torch.no_grad():
            for head, k in ((net.steer, steer), (net.longitudinal, lon)):
                head.weight.zero_()
                head.bias.zero_()
                head.bias[k] = 10.0
        return CommandPolicy(End2End(net, setting, np.array([-1.0, 0.0, 1.0])))

    straight = STEER_BINS_EACH_SIDE
    assert policy_for(N_STEER - 1, 1)(env, obs, info) == CommandPolicy.LEFT
    assert policy_for(0, 1)(env, obs, info) == CommandPolicy.RIGHT
    for lon, action in ((0, CommandPolicy.DECELERATE), (1, CommandPolicy.KEEP),
                        (2, CommandPolicy.ACCELERATE)):  # fmt: skip
        assert policy_for(straight, lon)(env, obs, info) == action
    assert env.action_space.contains(policy_for(0, 1)(env, obs, info))
