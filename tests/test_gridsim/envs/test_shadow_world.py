"""The reference's shadow world ticked in compiled batches gives the samples, revisions and
collisions of the Python ticks, bit for bit; and the compiled pieces it is built from equal the
code they replaced."""

import numpy as np
import pymunk
import pytest

from gridsim.envs import human_reference, shadow_world_kernels
from gridsim.envs.human_reference import HumanReference
from gridsim.scenario.build import build_world
from gridsim.scenario.loader import load_scenario
from gridsim.vehicle.control import pursuit_inputs, pursuit_lookahead
from gridsim.vehicle.footprint_kernels import boxes_apart
from gridsim.vehicle.idm import idm_accel
from gridsim.vehicle.kinematics import V
from gridsim.world.scripted_driver_kernels import route_inputs
from gridsim.world.scripted_drivers import HumanDriver, LaneFollower


def _both(monkeypatch, scenario, seed, duration):
    """The reference of ``seed`` with compiled batches (counting them) and without."""
    calls = []
    ticks = shadow_world_kernels.ticks

    def counted(k, end, *args):
        out = ticks(k, end, *args)
        calls.append(out[1] - k)
        return out

    monkeypatch.setattr(shadow_world_kernels, "ticks", counted)
    refs = []
    for compiled in (True, False):
        monkeypatch.setattr(human_reference, "COMPILED_SHADOW", compiled)
        ref = HumanReference(scenario, seed, duration)
        ref.positions(np.array([duration]))  # all of it
        refs.append(ref)
    return refs, sum(calls)


def _assert_same(a, b):
    for x, y in ((a.xy, b.xy), (a.psi, b.psi), (a.v, b.v)):
        assert x.tobytes() == y.tobytes()
    assert a.revisions == b.revisions and a.collisions == b.collisions


@pytest.mark.parametrize("seed", [0, 7, 1924045405])
def test_compiled_shadow_ticks_equal_the_python_ticks(monkeypatch, seed):
    sc = load_scenario("seamless", {"simulation": {"duration": 30.0}})
    (compiled, python), batched = _both(monkeypatch, sc, seed, 32.5)
    _assert_same(compiled, python)
    assert batched > 0.8 * len(python.t)  # most ticks were compiled


@pytest.mark.parametrize("seed", [0, 3, 6])  # (5's no longer needs a revision)
def test_compiled_shadow_ticks_revise_as_the_python_ticks(monkeypatch, seed):
    """A near-miss box 10 m longer at each end (dense traffic): revisions, replays, giving
    way and unavoidable collisions, all as in Python."""
    monkeypatch.setattr(human_reference, "NEAR_MISS_AHEAD", 10.0)
    sc = load_scenario("seamless", {"traffic": {"participants": 45},
                                    "simulation": {"duration": 20.0}})  # fmt: skip
    (compiled, python), batched = _both(monkeypatch, sc, seed, 22.5)
    _assert_same(compiled, python)
    assert python.revisions and batched > 0


def test_boxes_apart_only_where_pymunk_finds_no_contact():
    space = pymunk.Space()
    bodies = [pymunk.Body(body_type=pymunk.Body.KINEMATIC) for _ in range(2)]
    rng = np.random.default_rng(5)
    apart = touching = 0
    for _ in range(20000):
        boxes = [(*rng.uniform(-3, 3, 2), rng.uniform(-4, 4), *rng.uniform(0.5, 6, 2))
                 for _ in range(2)]  # fmt: skip
        shapes = []
        for body, (x, y, psi, length, width) in zip(bodies, boxes, strict=True):
            hl, hw = 0.5 * length, 0.5 * width
            shapes.append(pymunk.Poly(body, [(-hl, -hw), (hl, -hw), (hl, hw), (-hl, hw)]))
            body.position, body.angle = (x, y), psi
        space.add(*bodies, *shapes)
        contact = bool(space.shape_query(shapes[0]))
        space.remove(*bodies, *shapes)
        if boxes_apart(tuple(boxes[0]), tuple(boxes[1]), shadow_world_kernels.APART):
            assert not contact
            apart += 1
        touching += contact
    assert apart > 5000 and touching > 5000


def _python_inputs(follower, world, speed, offset):
    """The code ``follower_inputs`` replaced (LaneFollower.inputs before, giving way aside)."""
    route = world.route
    p, f, ego = world.ego_params, world.traffic.fleet, world.ego
    pose = (float(ego[0]), float(ego[1]), float(ego[2]), p.length, p.width, p.center_offset)
    _, _, _, tx, ty, gap, lead_v = route_inputs(
        route.tracking_data(), (f.x, f.y, f.active, f.length, f.width, f.v), pose,
        follower._hint_on(world, route), pursuit_lookahead(ego[V], follower.gains),
        float(offset), 96, follower.lookahead)  # fmt: skip
    accel, steer_rate = pursuit_inputs(ego, (tx, ty), speed, p, follower.gains)
    if np.isfinite(gap):
        v = ego[V]
        a_idm = idm_accel(float(v), float(speed), gap, float(v - lead_v), *follower.idm.values)
        accel = min(accel, float(a_idm))
    return (min(max(accel, -p.b_max), p.a_max), steer_rate), bool(np.isfinite(gap))


def test_compiled_follower_inputs_equal_the_python_code():
    rng = np.random.default_rng(3)
    sc = load_scenario("seamless", {"traffic": {"participants": 40}})
    for seed in range(3):
        world, follower = build_world(sc, seed), LaneFollower(speed=25.0)
        led = 0
        for _ in range(300):
            speed, offset = float(rng.uniform(0, 35)), float(rng.uniform(-1, 1))
            expected, leader = _python_inputs(follower, world, speed, offset)
            assert follower.inputs(world, speed, offset) == expected
            accel, rate = follower(world)
            world.tick(accel + float(rng.normal(0, 0.5)), rate, check=False)
            led += leader
        assert led > 30  # the IDM behind a leader, too


class _Slower(LaneFollower):
    """A follower with inputs of its own (half the profile's speed)."""

    def inputs(self, world, speed, offset, yield_to=()):
        return super().inputs(world, 0.5 * speed, offset, yield_to)


def test_a_follower_with_its_own_inputs_ticks_in_python(monkeypatch):
    """The compiled batch drives as :class:`LaneFollower` does: a subclass with inputs of its
    own offers no tick data, so its shadow world ticks in Python (its own inputs), and the
    plain follower's is what the kernel takes."""
    calls = []
    ticks = shadow_world_kernels.ticks
    monkeypatch.setattr(shadow_world_kernels, "ticks",
                        lambda *args: calls.append(1) or ticks(*args))  # fmt: skip
    sc = load_scenario("seamless", {"simulation": {"duration": 10.0}})
    world = build_world(sc, 0)
    plain = LaneFollower(speed=10.0)
    route, hint, settings = plain.tick_data(world)
    assert all(a is b for a, b in zip(route, world.route.tracking_data(), strict=True))
    assert hint == plain.tracked(world)
    assert settings == plain.settings
    slower = _Slower(speed=10.0)
    assert slower.tick_data(world) is None
    monkeypatch.setattr(human_reference, "HumanDriver", _slower_driver)
    ref = HumanReference(sc, 0, 5.0)
    ref.positions(np.array([5.0]))
    assert not calls  # every tick in Python
    monkeypatch.undo()
    normal = HumanReference(sc, 0, 5.0)
    normal.positions(np.array([5.0]))
    assert (ref.v[10:] < 0.8 * normal.v[10:]).all()  # it drove as its own inputs say


def _slower_driver(chain, yield_to):
    return HumanDriver(chain, _Slower(speed=chain.profiles.bounds.v_max), yield_to)


class _Wrapped:
    """A follower of another kind (no LaneFollower): it passes on a LaneFollower's inputs."""

    def __init__(self, speed: float) -> None:
        self.inner = LaneFollower(speed=speed)

    def inputs(self, world, speed, offset, yield_to=()):
        return self.inner.inputs(world, speed, offset, yield_to)


def test_a_follower_of_another_kind_ticks_in_python_with_the_same_result(monkeypatch):
    """A follower that offers no tick data (it has no ``tick_data``) ticks in Python; as it
    drives as a LaneFollower, its reference is the compiled one, bit for bit."""
    sc = load_scenario("seamless", {"simulation": {"duration": 10.0}})
    compiled = HumanReference(sc, 3, 8.0)
    compiled.positions(np.array([8.0]))
    monkeypatch.setattr(human_reference, "HumanDriver", lambda chain, yield_to: HumanDriver(
        chain, _Wrapped(chain.profiles.bounds.v_max), yield_to))  # fmt: skip
    wrapped = HumanReference(sc, 3, 8.0)
    wrapped.positions(np.array([8.0]))
    _assert_same(compiled, wrapped)
