"""A world tick with the ego following a path by pure pursuit, compiled
(:meth:`~gridsim.world.world.World.tick_following`): the controller
(:func:`~gridsim.vehicle.control.follow_path`, or a stop when there is no path), the ego's
step, the road's tracking (a seamless road; a static one needs none) and the fleet's tick
(with the leader candidates on other paths where paths leave lane corridors: city routes,
recorded tracks) in one call, built from the very kernels and float functions the Python
tick calls (same operations, same order: same bits), as the reference's shadow world does
(:mod:`gridsim.envs.shadow_world_kernels`).

It stops where Python has work: before the tick when the road must grow or be trimmed, when
more participants are out of corridors than the all-pairs search takes (Python builds a k-d
tree) or an input is not finite (nothing done: Python ticks with the inputs computed), and
after the fleet's tick when a participant's profile ran out, one is idle or the traffic
refills every tick (the refill draws random numbers, or places recorded tracks). The contact
tests stay in Python.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from gridsim.jit import jitable, kernel
from gridsim.road.polyline_kernels import ahead_of, track
from gridsim.traffic.fleet_kernels import (
    ALL_PAIRS_MAX,
    FleetState,
    all_pairs_candidates,
    no_candidates,
)
from gridsim.traffic.fleet_kernels import tick as fleet_tick
from gridsim.vehicle.control import pursuit_one
from gridsim.vehicle.kinematics_kernels import step_one
from gridsim.world.collision_kernels import APART, may_touch, near_segments

#: What the ego does (``follow``'s first item): stop, follow the path, hold the inputs.
STOP, PURSUIT, HOLD = 0, 1, 2
#: Why the call stopped: the tick is done; before it (Python ticks with the inputs computed);
#: after the fleet's tick (Python refills the traffic); before it, with a state or an input
#: that is not finite (Python computes the inputs and ticks).
DONE, BEFORE, TRAFFIC, NOT_FINITE = 0, 1, 2, 3


class Follow(NamedTuple):
    """What the ego does in :func:`follow_tick` (its ``follow`` argument)."""

    mode: int  # STOP, PURSUIT or HOLD
    path: tuple  # (points, segments, segment lengths, arc lengths, headings) of the path
    speed: float  # the target speed [m/s]
    min_lookahead: float  # pure pursuit's look-ahead [m] at standstill
    lookahead_time: float  # and its growth with speed [s]
    pursuit_limits: tuple  # pursuit_one's limits
    b_max: float  # the braking limit [m/s^2] of a stop
    held: tuple  # (acceleration, steering rate) held (HOLD)


class FollowTick(NamedTuple):
    """What :func:`follow_tick` returns (with status :data:`BEFORE` only ``accel`` and
    ``steer`` are meaningful, with :data:`NOT_FINITE` nothing)."""

    status: int  # DONE, BEFORE, TRAFFIC or NOT_FINITE
    accel: float  # the commanded acceleration [m/s^2]
    steer: float  # the commanded steering rate [rad/s]
    ego: tuple  # the new ego state (x, y, psi, v, delta)
    applied: float  # the acceleration applied (within the vehicle's limits) [m/s^2]
    steer_rate: float  # the steering rate applied [rad/s]
    road_s: float  # the road's arc length [m] of the ego
    road_hint: int  # and its segment
    ended: np.ndarray  # the participants whose profile ran out
    center: tuple  # the ego's footprint centre (x, y) [m]
    quiet: bool  # the contact test can find nothing (no edge near, no vehicle not apart)


@jitable
def _not_done(status, accel, steer, ego):
    """The :class:`FollowTick` of a tick not done (:data:`BEFORE`, :data:`NOT_FINITE`): the
    commanded inputs and the ego as it was (its empty ``ended`` a new array: a global one is
    read-only, of another type)."""
    return FollowTick(status, accel, steer, ego, np.nan, np.nan, np.nan, -1,
                      np.zeros(0, np.int64), (np.nan, np.nan), False)  # fmt: skip


@kernel
def follow_tick(ego, step_limits, dt, follow, road, traffic, box, broad):
    """One tick of the ego following a path (or holding its inputs). ``ego``: its state
    ``(x, y, psi, v, delta)``; ``step_limits``: as
    :func:`~gridsim.vehicle.kinematics_kernels.step_one` takes them; ``follow``: a
    :class:`Follow` (the mode :data:`PURSUIT` follows the path by pure pursuit, :data:`STOP`
    brakes to a stop holding the wheel, :data:`HOLD` holds the inputs); ``road``: a
    :class:`~gridsim.road.base.RoadTracking`, or None on a static road (nothing to track);
    ``traffic``: a :class:`~gridsim.traffic.sources.TrafficTick`; ``box``: the ego's
    ``(length, width, center_offset)``; ``broad``: a :class:`~gridsim.world.collision.BroadPhase`.

    Returns a :class:`FollowTick`; ``quiet``: as the reference's shadow world rules near misses
    out (:func:`~gridsim.world.collision_kernels.may_touch`)."""
    x, y, psi, v, delta = ego
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(psi) and math.isfinite(v)
            and math.isfinite(delta)):  # fmt: skip
        return _not_done(NOT_FINITE, np.nan, np.nan, ego)
    mode, path, speed, min_lookahead, lookahead_time, pursuit_limits, b_max, held = follow
    if mode == HOLD:  # inputs held for the decision period (control and discrete actions)
        accel, steer = held
    elif mode == PURSUIT:
        ahead = min_lookahead + lookahead_time * max(v, 0.0)
        points, seg, seg_len, s_cum, heading = path
        tx, ty, _ = ahead_of(points, seg, seg_len, s_cum, heading, x, y, ahead, 0.0)
        accel, steer = pursuit_one(x, y, psi, v, delta, tx, ty, speed, pursuit_limits)
    else:  # nothing ahead to drive to: brake to a stop, hold the wheel
        accel, steer = -min(b_max, v / dt), 0.0
    if not (math.isfinite(accel) and math.isfinite(steer)):
        return _not_done(NOT_FINITE, accel, steer, ego)
    state, paths, profiles, fleet_settings, decay, window, count, corridors, refill = traffic
    cross = no_candidates()
    if len(corridors):  # paths outside lane corridors: leader candidates on other paths
        idx = np.flatnonzero(FleetState(*state).active)
        if len(idx) > ALL_PAIRS_MAX:
            return _not_done(BEFORE, accel, steer, ego)
        cross = all_pairs_candidates(state, idx, corridors, paths, fleet_settings[0], True)
    x1, y1, psi1, v1, d1, a1, r1 = step_one(x, y, psi, v, delta, accel, steer, step_limits, dt)
    s1, j1 = np.nan, -1
    if road is not None:  # a road that grows and trims: the ego's place on it
        line, ref_s, road_hint, keep_ahead, keep_behind, cut_max = road
        points, seg, seg_len, seg_len_pow2, s_road, _ = line
        s1, _, j1 = track(points, seg, seg_len, seg_len_pow2, s_road, x1, y1, road_hint)
        if ref_s[-1] < s1 + keep_ahead or np.searchsorted(ref_s, s1 - keep_behind) > cut_max:
            return _not_done(BEFORE, accel, steer, ego)
    ego1 = (x1, y1, psi1, v1, d1)
    length, width, center_offset = box
    c, s = math.cos(psi1), math.sin(psi1)
    cx, cy = x1 + center_offset * c, y1 + center_offset * s
    pose = (True, cx, cy, v1, length, width, c, s)
    ended = fleet_tick(state, pose, cross, paths, profiles, *fleet_settings, dt, decay,
                       window)  # fmt: skip
    f = FleetState(*state)
    idle = False
    for i in range(count):
        idle = idle or not f.active[i]
    status = TRAFFIC if refill or idle or len(ended) else DONE
    edges, ego_length, ego_width, ego_radius, core_reach = broad
    quiet = (  # (a refill that renews profiles moves no one; a respawn may)
        not idle
        and not may_touch(state, (cx, cy, psi1, ego_length, ego_width), ego_radius, APART)
        and len(near_segments(edges, cx, cy, core_reach)) == 0
    )
    return FollowTick(status, accel, steer, ego1, a1, r1, s1, j1, ended, (cx, cy), quiet)
