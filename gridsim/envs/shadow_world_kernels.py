"""Compiled ticks of the reference's shadow world (:mod:`gridsim.envs.shadow_world`): the
human driver, the ego's step, the seamless road's tracking, the fleet's tick and the recorded
sample, tick after tick in one call, built from the very kernels and float functions the
Python tick calls (same operations, same order: same bits).

A batch stops where Python has work (see :func:`ticks`): it never draws random numbers (the
profile draws it may use come drawn), never grows or trims the road and never asks pymunk.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from gridsim.jit import kernel
from gridsim.road.polyline_kernels import track
from gridsim.traffic.fleet_kernels import FleetState
from gridsim.traffic.fleet_kernels import tick as fleet_tick
from gridsim.traffic.profile_kernels import chain_at, continue_profiles
from gridsim.vehicle.kinematics_kernels import step_one
from gridsim.world.collision_kernels import APART, may_touch
from gridsim.world.scripted_driver_kernels import follower_inputs

#: Why a batch stopped: all ticks done; before a tick Python must run; after the fleet's
#: tick of a tick whose traffic needs Python (new profiles, a respawn); after a tick whose
#: near miss only pymunk can rule out.
DONE, BEFORE, TRAFFIC, CHECK = 0, 1, 2, 3

_NO_CROSS = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))


class Batch(NamedTuple):
    """What :func:`ticks` returns."""

    status: int  # DONE, BEFORE, TRAFFIC or CHECK
    next: int  # the next sample to tick
    time: float  # the clock after the last tick started [s]
    ego: tuple  # the ego state (x, y, psi, v, delta)
    hint: int  # the route segment the driver tracks
    road_s: float  # the road's arc length [m] of the ego
    road_hint: int  # and its segment
    accel: float  # the acceleration applied in the last tick [m/s^2]
    rate: float  # the steering rate applied in the last tick [rad/s]
    ended: np.ndarray  # the participants whose profile ran out
    used: int  # the profile draws used


@kernel
def ticks(k, end, clock, ego, params, driver, chain, road, traffic, renew, near, yielding, out):
    """Tick the shadow world for samples ``k`` to ``end - 1`` until one needs Python.

    ``clock``: ``(time [s], dt [s])``; ``ego``: its state ``(x, y, psi, v, delta)``;
    ``params``: ``(step_one limits, follower_inputs params)``; ``driver``:
    ``(route tracking_data, segment tracked, follower settings)``; ``chain``: the profile
    chain's ``(times, speeds, offsets, ready)``; ``road``: :meth:`SeamlessRoad.tracking`;
    ``traffic``: :meth:`SeamlessTraffic.tick_data`; ``renew``:
    :meth:`SeamlessTraffic.continuation` (the profiles of participants whose profile runs
    out, as long as its draws last); ``near``: the near-miss box ``(length,
    width, radius)`` [m] and whether to test it; ``yielding``: per tick, whether the driver
    gives way then (Python's :func:`conflict_free_accel`); ``out``: the sample arrays ``(xy,
    psi, v)``, written from ``k`` on if not empty.

    Stops before a tick that gives way, needs more of the chain, has non-finite inputs or
    would grow or trim the road (:data:`BEFORE`: nothing of it done); after the fleet's tick
    when a participant is idle or the draws ran out (:data:`TRAFFIC`: the refill, the clock
    and the sample are Python's); after a recorded tick whose near miss the compiled test
    cannot rule out (:data:`CHECK`). Returns a :class:`Batch`.
    """
    t, dt = clock
    x, y, psi, v, delta = ego
    step_limits, driver_params = params
    route, hint, settings = driver
    times, speeds, offsets, ready = chain
    line, ref_s, road_hint, keep_ahead, keep_behind, cut_max = road
    points, seg, seg_len, seg_len_pow2, s_cum, _ = line
    state, paths, profiles, fleet_settings, decay, window, count, _, _ = traffic
    box_length, box_width, radius, check = near
    xy_out, psi_out, v_out = out
    record = len(v_out) > 0
    f = FleetState(*state)
    fleet = (f.x, f.y, f.active, f.length, f.width, f.v)
    ego_length, ego_width, center_offset = driver_params[0], driver_params[1], driver_params[2]
    draws, firsts, bounds, renewed = renew
    status, ended, used = DONE, _NO_CROSS[0], 0
    road_s, applied, rate = np.nan, np.nan, np.nan
    while k < end:
        tick = int(t / dt + 0.5)
        if (tick < len(yielding) and yielding[tick]) or ready < min(int(t / dt) + 3, len(times)):
            status = BEFORE
            break
        speed, offset = chain_at(t, times, speeds, offsets, ready)
        accel, steer, _, _, new_hint = follower_inputs(
            route, fleet, (x, y, psi, v, delta), driver_params, hint, speed, offset, settings
        )
        if not (math.isfinite(accel) and math.isfinite(steer)):
            status = BEFORE
            break
        x1, y1, psi1, v1, d1, a1, r1 = step_one(x, y, psi, v, delta, accel, steer, step_limits, dt)
        s1, _, j1 = track(points, seg, seg_len, seg_len_pow2, s_cum, x1, y1, road_hint)
        if ref_s[-1] < s1 + keep_ahead or np.searchsorted(ref_s, s1 - keep_behind) > cut_max:
            status = BEFORE  # the road grows or is trimmed: Python's update
            break
        x, y, psi, v, delta, hint, road_s, road_hint = x1, y1, psi1, v1, d1, new_hint, s1, j1
        applied, rate = a1, r1
        c, s = math.cos(psi), math.sin(psi)
        cx, cy = x + center_offset * c, y + center_offset * s
        pose = (True, cx, cy, v, ego_length, ego_width, c, s)
        ended = fleet_tick(state, pose, _NO_CROSS, paths, profiles, *fleet_settings, dt, decay,
                           window)  # fmt: skip
        idle = False
        for i in range(count):
            idle = idle or not f.active[i]
        if idle or len(ended) > len(draws) - used:
            status = TRAFFIC
            break
        if len(ended):
            continue_profiles(ended, draws[used:], firsts, bounds, renewed)
            used += len(ended)
        t += dt
        if record:
            xy_out[k, 0], xy_out[k, 1], psi_out[k], v_out[k] = x, y, psi, v
        k += 1
        if check and may_touch(state, (cx, cy, psi, box_length, box_width), radius, APART):
            status = CHECK
            break
    ego = (x, y, psi, v, delta)
    return Batch(status, k, t, ego, hint, road_s, road_hint, applied, rate, ended, used)
