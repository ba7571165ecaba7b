"""Compiled part of the scripted drivers (:mod:`gridsim.world.scripted_drivers`): the ego's
position on its route, its pure-pursuit target, the leader on the route and the inputs that
follow. Same operations, in the same order, as the NumPy code they replaced (same bits)."""

from __future__ import annotations

import math

import numpy as np

from gridsim.jit import kernel
from gridsim.road.polyline_kernels import frenet_one, project, track
from gridsim.vehicle.control import pursuit_one
from gridsim.vehicle.idm import idm_accel_pow


@kernel
def route_leader(fleet, ego, route, hint, window, lookahead) -> tuple[float, float]:
    """Bumper-to-bumper gap [m] along ``route`` to the nearest active vehicle ahead of the
    ego on it, and that vehicle's speed [m/s]; ``(inf, 0)`` if none.

    ``fleet``: ``(x, y, active, length, width, v)`` arrays; ``ego``: ``(x, y, psi, s_rear,
    length, width, center_offset)`` (rear axle [m, world], heading [rad], its arc length on
    the route); ``route``: a polyline's ``(points, seg, seg_len, s_cum)``. Candidates are
    ahead of the ego's rear axle and within ``lookahead`` [m]; they are projected on the
    route segments within ``window`` of segment ``hint`` and must overlap the ego's width
    (plus 0.3 m) there."""
    fx, fy, active, length, width, v = fleet
    x, y, psi, s_rear, ego_length, ego_width, center_offset = ego
    points, seg, seg_len, s_cum = route
    c, sn = math.cos(psi), math.sin(psi)
    idx = np.empty(len(fx), np.int64)
    n = 0
    for i in range(len(fx)):
        dx, dy = fx[i] - x, fy[i] - y
        if active[i] and dx * c + dy * sn > 0 and np.hypot(dx, dy) < lookahead:
            idx[n] = i
            n += 1
    if n == 0:
        return np.inf, 0.0
    xy = np.empty((n, 2))
    for k in range(n):
        xy[k, 0], xy[k, 1] = fx[idx[k]], fy[idx[k]]
    s, d, segment = np.empty(n), np.empty(n), np.empty(n, np.int64)
    hint = min(max(hint, 0), len(seg) - 1)
    lo, hi = max(0, hint - window), min(len(seg), hint + window)
    project(points, seg, seg_len, s_cum, xy, lo, hi, s, d, segment)
    best = -1
    for k in range(n):
        j = idx[k]
        on_route = s[k] > s_rear and abs(d[k]) < 0.5 * (width[j] + ego_width) + 0.3
        if on_route and (best < 0 or s[k] < s[best]):
            best = k
    if best < 0:
        return np.inf, 0.0
    j = idx[best]
    gap = s[best] - (s_rear + center_offset) - 0.5 * (length[j] + ego_length)
    return gap, v[j]


@kernel
def route_inputs(route, fleet, ego, hint, look, offset, window, lookahead):
    """What a :class:`~gridsim.world.scripted_drivers.LaneFollower` needs from its route, in
    one call: the rear axle's arc length and lateral offset [m] and its segment (tracked from
    segment ``hint``), the pure-pursuit target ``(x, y)`` [m, world] ``look`` metres further
    along at lateral ``offset`` [m], and :func:`route_leader`'s gap [m] and leader speed [m/s].

    ``route``: :meth:`~gridsim.road.polyline.Polyline.tracking_data`; ``fleet`` as for
    :func:`route_leader`; ``ego``: ``(x, y, psi, length, width, center_offset)``."""
    points, seg, seg_len, seg_len_pow2, s_cum, heading = route
    x, y, psi, length, width, center_offset = ego
    s, d, j = track(points, seg, seg_len, seg_len_pow2, s_cum, x, y, hint)
    tx, ty, _ = frenet_one(points, seg, seg_len, s_cum, heading, s + look, offset)
    pose = (x, y, psi, s, length, width, center_offset)
    gap, lead_v = route_leader(fleet, pose, (points, seg, seg_len, s_cum), j, window, lookahead)
    return s, d, j, tx, ty, gap, lead_v


@kernel
def follower_inputs(route, fleet, ego, params, hint, speed, offset, settings):
    """A lane follower's inputs without giving way, in one call: acceleration [m/s^2] and
    steering rate [rad/s] keeping lateral ``offset`` [m] from ``route`` at up to ``speed``
    [m/s] (pure pursuit, and the IDM behind :func:`route_leader`'s leader), then the rear
    axle's arc length and lateral offset [m] and its segment (:func:`route_inputs`).

    ``ego``: the state ``(x, y, psi, v, delta)``; ``params``: ``(length, width,
    center_offset, wheelbase, delta_max, b_max, a_max, v_delta_max)``; ``settings``:
    ``((min_lookahead, lookahead_time, steer_time, speed_gain), idm values, window,
    lookahead)``. The IDM's powers are libm's ``pow``, as Python computes them on floats."""
    x, y, psi, v, delta = ego
    length, width, center_offset, wheelbase, delta_max, b_max, a_max, v_delta_max = params
    gains, idm, window, lookahead = settings
    min_lookahead, lookahead_time, steer_time, speed_gain = gains
    look = min_lookahead + lookahead_time * max(v, 0.0)
    s_rear, d_rear, j, tx, ty, gap, lead_v = route_inputs(
        route, fleet, (x, y, psi, length, width, center_offset), hint, look, offset, window,
        lookahead)  # fmt: skip
    limits = (wheelbase, delta_max, b_max, a_max, v_delta_max, steer_time, speed_gain)
    accel, steer_rate = pursuit_one(x, y, psi, v, delta, tx, ty, speed, limits)
    if np.isfinite(gap):
        accel = min(accel, idm_accel_pow(v, speed, gap, v - lead_v, *idm))
    return min(max(accel, -b_max), a_max), steer_rate, s_rear, d_rear, j
