"""Ego collisions with pymunk: vehicles and road edges, and off-road in the world."""

import numpy as np
import pytest

from gridsim.scenario.build import build_world
from gridsim.scenario.loader import load_scenario
from gridsim.world.collision import CollisionChecker
from gridsim.world.scripted_drivers import LaneFollower


def traffic(*poses, length=4.0, width=2.0):
    arr = np.array(poses, float).reshape(-1, 3)
    n = len(arr)
    return (arr[:, 0], arr[:, 1], arr[:, 2], np.full(n, length), np.full(n, width))


def test_overlapping_vehicle_is_reported_by_index():
    cc = CollisionChecker(4.0, 2.0)
    cc.set_boundaries(np.zeros((0, 4)), 0, np.zeros(2))
    hit = cc.check(np.zeros(2), 0.0, traffic((3.9, 0.0, 0.0), (30.0, 0.0, 0.0)), np.array([7, 9]))
    assert hit.vehicles == (7,) and hit.boundaries == ()


@pytest.mark.parametrize("gap", [0.05, 0.5])
def test_near_misses_are_not_collisions(gap):
    cc = CollisionChecker(4.0, 2.0)
    cc.set_boundaries(np.zeros((0, 4)), 0, np.zeros(2))
    # Nose to tail, `gap` metres apart.
    assert not cc.check(np.zeros(2), 0.0, traffic((4.0 + gap, 0.0, 0.0)), np.array([0])).any
    # A box turned 45 degrees whose corner stops `gap` short of the ego's side: their
    # bounding boxes overlap, the shapes do not.
    corner = np.hypot(2.0, 1.0)
    far = 1.0 + gap + corner * np.sin(np.pi / 4 + np.arctan2(1.0, 2.0))
    assert not cc.check(np.zeros(2), 0.0, traffic((0.0, far, np.pi / 4)), np.array([0])).any
    assert cc.check(
        np.zeros(2), 0.0, traffic((0.0, far - 2 * gap, np.pi / 4)), np.array([0])
    ).vehicles == (0,)


def test_moving_between_checks_updates_shapes():
    cc = CollisionChecker(4.0, 2.0)
    cc.set_boundaries(np.zeros((0, 4)), 0, np.zeros(2))
    assert cc.check(np.zeros(2), 0.0, traffic((3.0, 0.0, 0.0)), np.array([4])).vehicles == (4,)
    assert not cc.check(np.zeros(2), 0.0, traffic((10.0, 0.0, 0.0)), np.array([4])).any
    assert not cc.check(np.array([50.0, 0.0]), 0.0, traffic((3.0, 0.0, 0.0)), np.array([4])).any


def test_road_edges_are_reported():
    cc = CollisionChecker(4.0, 2.0)
    edges = np.array([[-50.0, 1.5, 50.0, 1.5], [-50.0, -5.0, 50.0, -5.0]])
    cc.set_boundaries(edges, 1, np.zeros(2))
    empty = traffic()
    none = np.array([], int)
    assert cc.check(np.zeros(2), 0.0, empty, none).boundaries == ()
    # The box may reach EDGE_TOLERANCE (0.3 m) over an edge: a wheel on the line.
    assert cc.check(np.array([0.0, 0.7]), 0.0, empty, none).boundaries == ()  # 0.2 m over
    assert cc.check(np.array([0.0, 0.9]), 0.0, empty, none).boundaries == (0,)  # 0.4 m over
    assert cc.check(np.array([0.0, -4.5]), 0.3, empty, none).boundaries == (1,)
    # Vehicles count from the first touch.
    assert cc.check(np.zeros(2), 0.0, traffic((0.0, 2.05, 0.0)), np.array([3])).vehicles == ()
    assert cc.check(np.zeros(2), 0.0, traffic((0.0, 1.95, 0.0)), np.array([3])).vehicles == (3,)


def test_lane_follower_stays_on_road_and_steering_away_goes_off_road():
    sc = load_scenario("seamless")
    world = build_world(sc, seed=4)
    driver = LaneFollower(speed=10.0)
    for _ in range(300):
        r = world.tick(*driver(world))
        assert not r.off_road and not r.contact.boundaries
    world = build_world(sc, seed=4)
    events = []
    for k in range(150):  # turn left, straighten out, and drive away from the road
        r = world.tick(1.0, 0.5 if k < 8 else (-0.5 if k < 16 else 0.0))
        events.append(r.off_road)
    assert any(events)
    first = events.index(True)
    assert all(events[first:])  # once off the road it stays off
    assert not world.road.is_drivable(world.ego_center()[None])[0]


def test_edges_near_the_ego_give_the_contacts_of_all_edges(monkeypatch):
    """pymunk is given and asked about only the road edges near the ego: the contacts are
    the same as with every loaded edge given to it and asked about (random edges, an ego
    moving between checks, touching edges or not)."""
    from gridsim.world import collision_kernels

    rng = np.random.default_rng(8)
    cases = []
    for _ in range(100):
        edges = rng.uniform(-15, 15, (int(rng.integers(0, 12)), 4))
        edges[: len(edges) // 2, 2:] = edges[: len(edges) // 2, :2]  # some of zero length
        cases.append((edges, [(rng.normal(0, 4, 2), float(rng.uniform(-4, 4))) for _ in range(4)]))

    def contacts():
        out, none_near = [], 0
        for edges, poses in cases:
            cc = CollisionChecker(4.5, 1.8)
            cc.set_boundaries(edges, 1, np.zeros(2))
            for center, psi in poses:
                near = collision_kernels.near_segments(cc._edges, *center, cc._core_reach)
                none_near += not len(near)
                out.append(cc.check(center, psi, traffic(), np.array([], int)))
        return out, none_near

    filtered, none_near = contacts()
    monkeypatch.setattr(collision_kernels, "near_segments", lambda e, *_: np.arange(len(e)))
    everything, _ = contacts()
    assert filtered == everything
    assert 0 < none_near < len(filtered) and sum(bool(c.boundaries) for c in everything) > 50
