"""Compiled part of the scripted drivers (:mod:`gridsim.world.scripted_drivers`): the ego's
position on its route, its pure-pursuit target and the leader on the route. Same operations,
in the same order, as the NumPy code they replaced (same bits)."""

from __future__ import annotations

import math

import numpy as np

from gridsim.jit import kernel
from gridsim.road.polyline_kernels import frenet_one, project, track


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
