"""Compiled broad phases of :class:`~gridsim.world.collision.CollisionChecker`: for vehicles
the same operations, in the same order, as the NumPy code it replaced (``np.hypot`` compiled
is libm's ``hypot``, as NumPy's); for road edges a conservative distance test before pymunk's
query; and a conservative separating-axis test that rules a vehicle contact out without
pymunk (the reference's compiled shadow ticks)."""

from __future__ import annotations

import numpy as np

from gridsim.jit import jitable, kernel
from gridsim.traffic.fleet_kernels import FleetState
from gridsim.vehicle.footprint_kernels import boxes_apart

#: A vehicle contact is ruled out without pymunk when the boxes are apart by more than this
#: [m] along a separating axis (:func:`boxes_apart`; pymunk's rounding is some 1e-12 m).
APART = 1e-3


@jitable
def _point_box_distance(ux, uy, hl, hw) -> float:
    """Distance [m] from ``(ux, uy)`` to the box ``[-hl, hl] x [-hw, hw]`` (0 inside)."""
    return np.hypot(max(abs(ux) - hl, 0.0), max(abs(uy) - hw, 0.0))


@jitable
def _point_segment_distance(px, py, x0, y0, x1, y1) -> float:
    """Distance [m] from ``(px, py)`` to the segment from ``(x0, y0)`` to ``(x1, y1)``."""
    dx, dy = x1 - x0, y1 - y0
    den = dx * dx + dy * dy
    t = 0.0
    if den > 0.0:
        t = min(max(((px - x0) * dx + (py - y0) * dy) / den, 0.0), 1.0)
    return np.hypot(px - x0 - t * dx, py - y0 - t * dy)


@jitable
def _segment_crosses_box(x0, y0, x1, y1, hl, hw) -> bool:
    """Whether the segment meets the box ``[-hl, hl] x [-hw, hw]`` (Liang-Barsky clipping)."""
    lo, hi = 0.0, 1.0
    dx, dy = x1 - x0, y1 - y0
    for p, q in ((-dx, x0 + hl), (dx, hl - x0), (-dy, y0 + hw), (dy, hw - y0)):
        if p == 0.0:
            if q < 0.0:
                return False
        else:
            r = q / p
            if p < 0.0:
                lo = max(lo, r)
            else:
                hi = min(hi, r)
            if lo > hi:
                return False
    return True


@kernel
def within_reach(active, x, y, length, width, cx, cy, radius):
    """Indices of the active boxes (centres ``x, y``, sizes ``length x width`` [m]) whose
    bounding circle touches the circle of ``radius`` [m] around ``(cx, cy)``."""
    out = np.empty(len(x), np.int64)
    n = 0
    for i in range(len(x)):
        if active[i] and np.hypot(x[i] - cx, y[i] - cy) <= radius + 0.5 * np.hypot(
            length[i], width[i]
        ):
            out[n] = i
            n += 1
    return out[:n]


@kernel
def near_segments(segments, cx, cy, reach):
    """Indices of the segments ``(M, 4)`` = ``[x0, y0, x1, y1]`` [m] that come within
    ``reach`` [m] of ``(cx, cy)`` (a distance that is not a number counts as near)."""
    out = np.empty(len(segments), np.int64)
    n = 0
    for k in range(len(segments)):
        x0, y0, x1, y1 = segments[k, 0], segments[k, 1], segments[k, 2], segments[k, 3]
        if not _point_segment_distance(cx, cy, x0, y0, x1, y1) > reach:
            out[n] = k
            n += 1
    return out[:n]


@kernel
def may_touch(state, ego, radius, margin) -> bool:
    """Whether the ego box ``(x, y, psi, length, width)`` (centre [m], heading [rad], size [m])
    may touch an active participant of a fleet (``state``: its arrays in
    :class:`~gridsim.traffic.fleet_kernels.FleetState` order): one within the broad phase
    (:func:`within_reach`, ego ``radius`` [m]) not :func:`boxes_apart` by ``margin``."""
    f = FleetState(*state)
    for i in within_reach(f.active, f.x, f.y, f.length, f.width, ego[0], ego[1], radius):
        if not boxes_apart(ego, (f.x[i], f.y[i], f.psi[i], f.length[i], f.width[i]), margin):
            return True
    return False


@kernel
def edges_near_boxes(px, py, psi, half_length, half_width, reach, segments, margin):
    """For each box (centre ``px[i], py[i]`` [m], heading ``psi[i]`` [rad], half sizes [m]),
    whether a segment of ``segments`` ``(M, 4)`` comes within ``margin`` [m] of it: exact
    distances, for the segments within ``reach[i]`` [m] of the centre (:func:`near_segments`'
    test). A whole recorded scene's samples at once; farther boxes cannot touch an edge."""
    out = np.zeros(len(px), np.bool_)
    for i in range(len(px)):
        cx, cy, c, s = px[i], py[i], np.cos(psi[i]), np.sin(psi[i])
        hl, hw = half_length[i], half_width[i]
        for k in range(len(segments)):
            x0, y0, x1, y1 = segments[k, 0], segments[k, 1], segments[k, 2], segments[k, 3]
            if _point_segment_distance(cx, cy, x0, y0, x1, y1) > reach[i]:
                continue
            # the segment in the box's frame
            a0 = c * (x0 - cx) + s * (y0 - cy)
            b0 = -s * (x0 - cx) + c * (y0 - cy)
            a1 = c * (x1 - cx) + s * (y1 - cy)
            b1 = -s * (x1 - cx) + c * (y1 - cy)
            if _segment_crosses_box(a0, b0, a1, b1, hl, hw):
                out[i] = True
                break
            d = min(_point_box_distance(a0, b0, hl, hw), _point_box_distance(a1, b1, hl, hw))
            for cu, cv in ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw)):
                d = min(d, _point_segment_distance(cu, cv, a0, b0, a1, b1))
            if not d > margin:
                out[i] = True
                break
    return out


@kernel
def pairs_apart(x, y, psi, length, width, i, j, margin):
    """For each pair ``(i[k], j[k])`` of boxes ``(x, y, psi, length, width)`` (centres [m],
    headings [rad], sizes [m]), :func:`boxes_apart` by ``margin`` [m]."""
    out = np.zeros(len(i), np.bool_)
    for k in range(len(i)):
        a, b = i[k], j[k]
        out[k] = boxes_apart((x[a], y[a], psi[a], length[a], width[a]),
                             (x[b], y[b], psi[b], length[b], width[b]), margin)  # fmt: skip
    return out
