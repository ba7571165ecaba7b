"""Worlds built from scenarios: determinism, all built-ins, the drive command."""

import contextlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gridsim.cli import main
from gridsim.scenario.build import build_sensor, build_world
from gridsim.scenario.family import family_of
from gridsim.scenario.loader import builtin_scenarios, load_scenario
from gridsim.sensors import FREE, OCCUPIED, UNKNOWN
from gridsim.world.scripted_drivers import LaneFollower


def rollout(name, seed, ticks=80):
    sc = load_scenario(name)
    world = build_world(sc, seed)
    sensor = build_sensor(sc)
    driver = LaneFollower(speed=8.0)
    egos, fleets, grids = [], [], []
    for _ in range(ticks):
        world.tick(*driver(world))
        f = world.traffic.fleet
        egos.append(world.ego.copy())
        fleets.append(np.concatenate([f.x, f.y, f.psi, f.v, f.active]))
        grids.append(sensor.observe(world))
    return np.array(egos), np.array(fleets), np.array(grids)


@pytest.mark.parametrize("name", sorted(builtin_scenarios()))
def test_every_builtin_scenario_runs_and_is_deterministic(name):
    a = rollout(name, seed=11)
    b = rollout(name, seed=11)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    grids = a[2]
    assert set(np.unique(grids)) <= {FREE, OCCUPIED, UNKNOWN}
    assert (grids == FREE).mean() > 0.02 and (grids == OCCUPIED).mean() > 0.001


def test_different_seeds_give_different_worlds():
    a = rollout("seamless", 1, 20)
    b = rollout("seamless", 2, 20)
    assert not np.array_equal(a[1], b[1])


@pytest.mark.slow
def test_same_seed_same_result_in_a_fresh_process():
    code = (
        f"import numpy as np, sys; sys.path.insert(0, {str(Path(__file__).parent)!r});"
        "from test_world import rollout;"
        "e, f, g = rollout('inner_city', 5, 30);"
        "print(float(e.sum()), float(f.sum()), int(g.astype(np.int64).sum()))"
    )
    out = [
        subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True
        ).stdout
        for _ in range(2)
    ]
    e, f, g = rollout("inner_city", 5, 30)
    assert (
        out[0] == out[1] == f"{float(e.sum())} {float(f.sum())} {int(g.astype(np.int64).sum())}\n"
    )


def test_traffic_count_is_kept_on_the_endless_road():
    sc = load_scenario("seamless")
    world = build_world(sc, seed=0)
    driver = LaneFollower(speed=12.0)
    counts = []
    for _ in range(1500):  # ~1.5 km
        world.tick(*driver(world))
        counts.append(world.traffic.fleet.active.sum())
    assert np.mean(counts[200:]) >= 0.9 * sc.config.traffic.participants
    assert world.road.memory_points < 1000


def test_drive_command_writes_outputs(tmp_path, capsys):
    out = tmp_path / "drive ü"  # (printed as written, not as "\\u00fc")
    assert (
        main(["drive", "--scenario", "inner_city", "--seconds", "3", "--out", str(out), "--quiet"])
        == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ticks"] == 30 and summary["distance_m"] > 5
    data = np.load(out / "grids.npz")
    assert data["grids"].shape == (30, 128, 128) and data["grids"].dtype == np.uint8
    assert data["times"].tolist() == [round(0.1 * (k + 1), 9) for k in range(30)]  # as info's
    assert (out / "topdown.png").stat().st_size > 1000
    printed = capsys.readouterr().out
    assert json.loads(printed)["scenario"] == "inner_city" and "drive ü" in printed
    assert summary["outputs"] == sorted(p.name for p in out.iterdir())  # itself included
    assert summary["out"] == str(out.absolute())  # (it named the temporary folder, renamed)


def test_drive_and_run_with_a_seed_drive_the_same_episode(tmp_path, capsys, monkeypatch):
    """``drive --seed S`` builds the world of ``reset(seed=S)`` (and of ``run --seed S``):
    it built the world of S itself, another episode than the one watched with ``run``."""
    import gymnasium as gym

    from gridsim.scenario import build

    built = []

    def build_world(scenario, seed):
        world = make(scenario, seed)
        built.append(world.ego.copy())
        return world

    make = build.build_world
    monkeypatch.setattr(build, "build_world", build_world)
    assert main(["drive", "--scenario", "inner_city", "--seconds", "0.1", "--seed", "3",
                 "--out", str(tmp_path / "d"), "--quiet"]) == 0  # fmt: skip
    monkeypatch.undo()
    drove = json.loads(capsys.readouterr().out)
    assert main(["run", "--scenario", "inner_city", "--steps", "1", "--seed", "3", "--quiet"]) == 0
    ran = json.loads(capsys.readouterr().out)
    env = gym.make("GridSim-v0", scenario="inner_city")
    _, info = env.reset(seed=3)
    assert drove["episode_seed"] == ran["episode_seed"] == info["episode_seed"] != 3
    assert np.array_equal(built[0], env.unwrapped.world.ego)  # the same start


def test_drive_stops_where_a_recorded_ego_track_ends(tmp_path, capsys):
    """On a recorded scene ``drive`` stops where its ego track's recording ends, saying so
    (20 s drove on past the recording: 142 of 200 ticks off the map, no traffic left)."""
    out = tmp_path / "drive"
    assert main(["drive", "--scenario", "us101_4_1", "--seed", "1", "--out", str(out),
                 "--quiet"]) == 0  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    err = capsys.readouterr().err
    assert summary["simulated_s"] == pytest.approx(summary["ego_track_s"], abs=0.05)
    assert summary["simulated_s"] < 20
    assert f"drove {summary['simulated_s']:g} s, not 20: the recording of ego track " in err
    assert summary["ticks_off_road"] == 0 and summary["cut_at_track_end"]
    # a time that is no whole number of ticks is no cut (it said so, and on a generated
    # scene failed looking for the track)
    assert main(["drive", "--seconds", "1.04", "--out", str(tmp_path / "g"), "--quiet"]) == 0
    assert "drove" not in capsys.readouterr().err
    assert main(["drive", "--scenario", "us101_4_1", "--seed", "1", "--seconds", "1.04",
                 "--out", str(tmp_path / "r"), "--quiet"]) == 0  # fmt: skip
    assert "drove" not in capsys.readouterr().err


def test_drive_rejects_bad_arguments(tmp_path, capsys):
    for bad in ("-1", "nan", "1e12"):
        assert main(["drive", "--seconds", bad, "--out", str(tmp_path / "x"), "--quiet"]) == 2
        assert "--seconds must be in (0, 3600]" in capsys.readouterr().err
    assert main(["drive", "--scenario", "nowhere", "--out", str(tmp_path / "x"), "--quiet"]) == 2
    assert "unknown scenario 'nowhere'" in capsys.readouterr().err
    (tmp_path / "afile").write_text("")
    assert main(["drive", "--out", str(tmp_path / "afile" / "x"), "--quiet"]) == 2
    assert f"{tmp_path / 'afile'} is a file, not a folder" in capsys.readouterr().err


@pytest.mark.parametrize("scenario", ["seamless", "inner_city", "us101_3_3"])
def test_worlds_copied_from_the_pristine_one_tick_like_a_fresh_build(scenario):
    """build_world hands out copies of a world kept per (scenario, seed): they must behave
    exactly like a world built from scratch, however often one is handed out."""
    sc = load_scenario(scenario)
    fresh = family_of(sc).build(sc, 11)
    copies = [build_world(sc, 11), build_world(sc, 11)]
    if scenario == "us101_3_3":  # a recording's tracks, paths and profiles: shared too
        a, b = (w.traffic for w in copies)
        assert a.tracks is b.tracks and a.fleet.paths is b.fleet.paths
        assert a.fleet.profiles is b.fleet.profiles and a.fleet is not b.fleet
    drivers = [LaneFollower(speed=9.0) for _ in range(3)]
    for _ in range(150):  # (15 s: past the ego track's span on recorded scenes)
        for w, drive in zip([fresh, *copies], drivers, strict=True):
            w.tick(*drive(w))
        for w in copies:
            assert np.array_equal(w.ego, fresh.ego)
            assert np.array_equal(w.traffic.fleet.x, fresh.traffic.fleet.x)
            assert w.last == fresh.last
    assert copies[0].road is copies[1].road or scenario == "seamless"  # static maps shared


def test_the_kept_worlds_stay_within_their_memory(monkeypatch):
    """The worlds kept for warm resets take at most PRISTINE_BYTES together (a world of a
    recorded scene of thousands of vehicles takes tens of MB), and at least one is kept."""
    from gridsim.scenario import build

    sc = load_scenario("inner_city")
    monkeypatch.setattr(build, "_PRISTINE", type(build._PRISTINE)())
    size = build.world_bytes(build_world(sc, 0))
    assert size > 1e6
    monkeypatch.setattr(build, "PRISTINE_BYTES", int(2.5 * size))
    for seed in range(1, 6):
        build_world(sc, seed)
        kept = [s for _, s in build._PRISTINE.values()]
        assert len(kept) <= 3 and sum(kept) <= build.PRISTINE_BYTES
    monkeypatch.setattr(build, "PRISTINE_BYTES", 1)
    build_world(sc, 9)
    assert len(build._PRISTINE) == 1


def test_a_checked_tick_after_unchecked_ones_tests_the_road_itself():
    # unchecked ticks report "on the road"; the next checked tick must not trust that
    sc = load_scenario("seamless")
    world = build_world(sc, 0)
    world.ego[3] = 0.0  # standing: a tick moves it less than the shortcut's half width
    for _ in range(3):
        world.ego[1] += 40.0  # far off the road while nothing is checked
        assert not world.tick(0.0, 0.0, check=False).off_road
    world.ego[1] += 0.01
    assert world.tick(0.0, 0.0).off_road


def test_driving_slowly_out_of_a_recorded_maps_open_end_is_off_road():
    """Where a recorded map's lanes are cut off there is no edge to touch: the shortcut that
    trusts "no edge touched, so still on the road" must not hold there (the lane follower of
    `gridsim drive` rolled onto the grass past US-101's end at 1.3 m/s, 'ticks_off_road: 0')."""
    world = build_world(load_scenario("us101_4_1"), 0)
    speed = float(world.ego_track.speed.mean())  # as `gridsim drive` drives
    follower, counted, outside = LaneFollower(speed=speed), [], []
    for _ in range(200):
        result = world.tick(*follower(world))
        counted.append(result.off_road)
        outside.append(not world.road.is_drivable(world.ego_center()[None])[0])
    assert world.ego[3] < 0.5 * world.ego_params.width / world.dt  # slow: the shortcut's case
    assert sum(outside) > 10 and counted == outside  # every tick off the map is off-road
    assert not world.road.enclosed and build_world(load_scenario("seamless"), 0).road.enclosed


def _world_state(world):
    f, road, traffic = world.traffic.fleet, world.road, world.traffic
    rng = getattr(traffic, "rng", None)  # synthetic traffic's random stream
    return (
        world.ego.copy(),
        world.time,
        [a.copy() for a in f.state],
        road.version,
        getattr(road, "_ego_s", None),
        getattr(road, "_hint", None),
        world.last,
        rng.bit_generator.state if rng is not None else None,
        getattr(traffic, "time", None),
        getattr(traffic, "_done", np.zeros(0)).copy(),
        f.paths.kernel_data()[1].copy(),
    )  # (recorded clock and tracks; city routes)


def _assert_same_world(a, b):
    """Worlds ``a`` and ``b`` in the same state (:func:`_world_state`), bit for bit."""
    for x, y in zip(_world_state(a), _world_state(b), strict=True):
        if isinstance(x, list):
            assert all(np.array_equal(p, q) for p, q in zip(x, y, strict=True))
        elif isinstance(x, np.ndarray):
            assert np.array_equal(x, y)
        else:
            assert x == y


@contextlib.contextmanager
def _follow_tick_statuses():
    """The set of statuses ``world_kernels.follow_tick`` returns while the block runs."""
    from gridsim.world import world_kernels

    statuses, original = set(), world_kernels.follow_tick

    def spy(*args):
        out = original(*args)
        statuses.add(out[0])
        return out

    world_kernels.follow_tick = spy
    try:
        yield statuses
    finally:
        world_kernels.follow_tick = original


def _compiled_tick(env, action):
    """One tick of ``env``'s world following ``action`` (through its action type's
    controller), compiled (``World.tick_following``) and in Python on a copy: the same
    result and the same world, bit for bit. Returns the result and the controller."""
    import copy

    from gridsim.frames import grid_rotation
    from gridsim.vehicle.kinematics import PSI

    env = env.unwrapped
    world = env.world
    rotation = grid_rotation(env._orientation, world.ego[PSI])
    control, _ = env.action_kind.controller(world, action, rotation)
    twin = copy.deepcopy(world)
    result = twin.tick(*control(twin))
    assert world.tick_following(control) == result
    _assert_same_world(world, twin)
    return result, control


@pytest.mark.parametrize("seed, participants", [(0, None), (3, None), (26, 45)])
def test_compiled_path_following_tick_equals_the_python_tick(seed, participants):
    """``World.tick_following`` (the trajectory action's controller, the ego's step, the road's
    tracking, the fleet's tick and the contact test's broad phases in one compiled call)
    leaves a world in the same state, bit for bit, as ``world.tick(*control(world))``, with
    the same contacts: over episodes with noisy set-points, stops (no path), road growth,
    profile renewals, vehicles alongside and collisions."""

    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.world import world_kernels
    from gridsim.world.collision_kernels import within_reach

    env = GridSimEnv(**({"traffic": {"participants": participants}} if participants else {}))
    _, info = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    stops, alongside, contacts = 0, 0, 0
    with _follow_tick_statuses() as statuses:
        for i in range(400):
            action = info["reference_setpoints"].astype(np.float64)
            if i % 40 < 4:
                action = action + rng.normal(0, 4, action.shape)
            if participants and i % 60 < 12:  # swerve into the next lane, speed up
                action = action * np.array([2.0, 1.0]) + np.array([0.0, 3.5])
            if i % 97 == 0:
                action = -np.abs(action)  # behind the ego: a stop
            result, control = _compiled_tick(env, action)
            stops += control.path is None
            contacts += result.contact.any
            world = env.unwrapped.world
            f, (_, _, radius) = world.traffic.fleet, world.collision.ego_box
            cx, cy = world.ego_center()
            alongside += len(within_reach(f.active, f.x, f.y, f.length, f.width, cx, cy, radius))
            _, _, terminated, truncated, info = env.step(info["reference_setpoints"])
            if terminated or truncated:
                _, info = env.reset(seed=seed + i + 1)
    assert stops and statuses >= {world_kernels.DONE, world_kernels.TRAFFIC, world_kernels.BEFORE}
    assert alongside > 0 and (contacts > 0 or not participants)


@pytest.mark.parametrize("scenario", ["inner_city", "us101_4_1", "lankershim_1_1"])
def test_compiled_tick_on_static_roads_equals_the_python_tick(scenario):
    """On a static road (a city network, a recorded map) ``World.tick_following`` (the
    controller, the ego's step, the fleet's tick with its leader candidates on other paths in
    one compiled call; the refill in Python every tick: city respawns, recorded tracks placed
    and retired) leaves a world in the same state, bit for bit, as the Python tick, with the
    same contacts: over episodes with noisy set-points, stops, and collisions."""

    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.world import world_kernels

    env = GridSimEnv(scenario)
    _, info = env.reset(seed=3)  # (a seed with contacts on each scenario)
    rng = np.random.default_rng(3)
    stops = contacts = 0
    with _follow_tick_statuses() as statuses:
        for i in range(300):
            action = info["reference_setpoints"].astype(np.float64)
            if i % 40 < 6:
                action = action + rng.normal(0, 4, action.shape)
            if i % 70 > 55:  # the plan turned 60 degrees: into traffic or off the road
                turn = np.array([[0.5, -0.866], [0.866, 0.5]])
                action = action @ turn.T
            if i % 53 == 0:
                action = -np.abs(action)  # behind the ego: a stop
            result, control = _compiled_tick(env, action)
            stops += control.path is None
            contacts += result.contact.any or result.off_road
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                _, info = env.reset(seed=i + 2)
    assert stops and world_kernels.TRAFFIC in statuses and contacts > 0


def _crafted_scene(tmp_path, case):
    """Crafted recorded scenes for the compiled tick's edge cases (see the test below)."""
    from dataclasses import replace

    from scenes import track, write_scene

    def car(name, x0, y, start=0.0, n=41):
        return replace(track(name, np.linspace(x0, x0 + 0.5 * (n - 1), n), np.full(n, y)),
                       t=start + 0.1 * np.arange(n))  # 5 m/s  # fmt: skip

    ego = car("ego", 60.0, 1.75, n=61)
    if case == "a car appears on the ego":  # 2.05 s in, where the ego is then (the test
        # below compares every other tick: this one is compared)
        others = [car("late", 70.25, 1.75, start=2.05, n=21)]
    elif case == "more than 48 cars":  # the candidates on other paths: Python's k-d tree
        others = [car(f"c{k}", 20.0 + 3.0 * k, -1.75 if k % 2 else 1.75 - 3.5 * (k % 3 == 0))
                  for k in range(60)]  # fmt: skip
        others = [o for o in others if abs(o.x[0] - 60.0) > 6.0 or o.y[0] < 0]
    else:  # a clock from 100 s
        others = [car("ahead", 75.0, 1.75), car("beside", 55.0, -1.75)]
        ego = replace(ego, t=ego.t + 100.0)
        others = [replace(o, t=o.t + 100.0) for o in others]
    return write_scene(tmp_path, [ego, *others])


@pytest.mark.parametrize("case", ["a car appears on the ego", "more than 48 cars",
                                  "a clock from 100 s"])  # fmt: skip
def test_compiled_tick_edge_cases_equal_the_python_tick(tmp_path, case, monkeypatch):
    """The compiled tick on a recorded scene where the refill places a car on the ego (its
    contact must be tested even when the broad phase saw nothing near: here no road edge is
    handed to it), with more active cars than the compiled leader search takes (it hands the
    tick to Python), and on a clock that does not start at 0: the same world as the Python
    tick, bit for bit."""

    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.world import world_kernels
    from gridsim.world.collision import BroadPhase, CollisionChecker

    if case == "a car appears on the ego":
        broad = CollisionChecker.broad_phase_data
        monkeypatch.setattr(CollisionChecker, "broad_phase_data", lambda self: BroadPhase(
            np.zeros((0, 4)), *broad(self)[1:]))  # fmt: skip
    env = GridSimEnv(str(_crafted_scene(tmp_path, case)))
    _, info = env.reset(seed=0)
    at_start = int(env.unwrapped.world.traffic.fleet.active.sum())
    contacts = 0
    with _follow_tick_statuses() as statuses:
        for _ in range(40):
            result, _ = _compiled_tick(env, info["reference_setpoints"])
            contacts += result.collided
            if result.collided:
                break
            _, _, terminated, truncated, info = env.step(info["reference_setpoints"])
            if terminated or truncated:
                break
    if case == "a car appears on the ego":
        assert contacts > 0
    elif case == "more than 48 cars":
        assert world_kernels.BEFORE in statuses
    else:
        assert at_start == 2  # the traffic of the ego's first time stamp, 100 s


@pytest.mark.parametrize("action_type", ["control", "discrete"])
def test_compiled_held_inputs_tick_equals_the_python_tick(action_type):
    """The control and discrete actions' compiled ticks (inputs held) leave a world in the
    same state, bit for bit, as ``world.tick(*control(world))``."""

    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.world import world_kernels

    env = GridSimEnv(action_type=action_type)
    env.reset(seed=5)
    env.action_space.seed(5)
    with _follow_tick_statuses() as statuses:
        for i in range(300):
            action = env.action_space.sample()
            if action_type == "control" and i % 3:
                action = np.array([0.5, 0.0], np.float32)  # mostly straight on
            _compiled_tick(env, action)
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset(seed=100 + i)
    assert world_kernels.DONE in statuses
