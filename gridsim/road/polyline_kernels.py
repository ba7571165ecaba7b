"""Compiled queries on the arrays of a :class:`~gridsim.road.polyline.Polyline`.

Each kernel does the operations of the NumPy expressions it replaced, in the same order, so
its results are the same bits (``tests/test_gridsim/road/test_roads.py`` keeps the NumPy
versions as the reference; ``tests/test_golden.py`` replays whole episodes against recorded
digests).
Coordinates are metres in the world frame; ``d`` is positive to the left.
"""

from __future__ import annotations

import math

import numpy as np

from gridsim.jit import kernel, search_right


@kernel
def segment_at(s_cum: np.ndarray, s: float) -> int:
    """The segment holding arc length ``s`` [m]: ``searchsorted(s_cum, s, "right") - 1``,
    clipped to the segments (beyond the ends: the end segments, extended)."""
    return min(max(search_right(s_cum, s), 0), len(s_cum) - 2)


@kernel
def frenet_one(points, seg, seg_len, s_cum, heading, s, d) -> tuple[float, float, float]:
    """World point ``(x, y)`` [m] at arc length ``s`` and lateral offset ``d``, and the
    path heading [rad] there."""
    i = segment_at(s_cum, s)
    t = (s - s_cum[i]) / seg_len[i]
    h = heading[i]
    x = (points[i, 0] + t * seg[i, 0]) + d * -math.sin(h)
    y = (points[i, 1] + t * seg[i, 1]) + d * math.cos(h)
    return x, y, h


@kernel
def project(points, seg, seg_len, s_cum, xy, lo, hi, s_out, d_out, seg_out) -> None:
    """Nearest point on segments ``lo:hi`` for each of ``xy`` ``(N, 2)``: arc length,
    signed lateral offset and segment index into ``s_out``, ``d_out``, ``seg_out``. On a tie
    the first segment wins (as ``argmin``)."""
    for n in range(len(xy)):
        x, y = xy[n, 0], xy[n, 1]
        best, j, tj, rx_j, ry_j = np.inf, lo, 0.0, 0.0, 0.0
        for m in range(lo, hi):
            ax, ay, sx, sy = points[m, 0], points[m, 1], seg[m, 0], seg[m, 1]
            rx, ry = x - ax, y - ay
            t = min(max((rx * sx + ry * sy) / (seg_len[m] * seg_len[m]), 0.0), 1.0)
            ex, ey = x - (ax + t * sx), y - (ay + t * sy)
            dist2 = ex * ex + ey * ey
            if m == lo or dist2 < best:
                best, j, tj, rx_j, ry_j = dist2, m, t, rx, ry
        s_out[n] = s_cum[j] + tj * seg_len[j]
        cross = seg[j, 0] * ry_j - seg[j, 1] * rx_j
        d_out[n] = np.sign(cross) * math.sqrt(best)
        seg_out[n] = j


@kernel
def ahead_of(points, seg, seg_len, s_cum, heading, x, y, ahead, d) -> tuple[float, float, float]:
    """:func:`frenet_one` at ``ahead`` [m] past the nearest point to ``(x, y)`` on the whole
    curve (found by :func:`project`), lateral offset ``d`` [m]."""
    xy = np.empty((1, 2))
    xy[0, 0], xy[0, 1] = x, y
    s_out, d_out, seg_out = np.empty(1), np.empty(1), np.empty(1, np.int64)
    project(points, seg, seg_len, s_cum, xy, 0, len(seg), s_out, d_out, seg_out)
    return frenet_one(points, seg, seg_len, s_cum, heading, s_out[0] + ahead, d)


@kernel
def _foot(points, seg, seg_len_pow2, i, x, y) -> float:
    """Parameter of the foot of ``(x, y)`` on the line through segment ``i``
    (``seg_len_pow2``: squared segment lengths computed by libm's ``pow``, as the NumPy scalar
    code this replaced did; ``project`` divides by ``seg_len * seg_len`` instead, as its array
    code did)."""
    return ((x - points[i, 0]) * seg[i, 0] + (y - points[i, 1]) * seg[i, 1]) / seg_len_pow2[i]


@kernel
def track(points, seg, seg_len, seg_len_pow2, s_cum, x, y, hint) -> tuple[float, float, int]:
    """Project ``(x, y)`` walking from segment ``hint`` to the nearest local segment (see
    :meth:`~gridsim.road.polyline.Polyline.track`): ``(s, d, segment index)``."""
    n = len(seg)
    i = min(max(hint, 0), n - 1)
    step = 0
    while True:  # walk to a segment whose foot point parameter is inside [0, 1]
        t = _foot(points, seg, seg_len_pow2, i, x, y)
        if t > 1.0 and i < n - 1 and step >= 0:
            i, step = i + 1, 1
        elif t < 0.0 and i > 0 and step <= 0:
            i, step = i - 1, -1
        else:
            break
    best, bj, bt, bcross = np.inf, -1, 0.0, 0.0
    for j in range(i - 1, i + 2):  # inside a bend the point may project onto neighbours too
        if 0 <= j < n:
            t = min(max(_foot(points, seg, seg_len_pow2, j, x, y), 0.0), 1.0)
            ax, ay, sx, sy = points[j, 0], points[j, 1], seg[j, 0], seg[j, 1]
            dist = np.hypot(x - ax - t * sx, y - ay - t * sy)
            if bj < 0 or dist < best:
                best, bj, bt, bcross = dist, j, t, sx * (y - ay) - sy * (x - ax)
    return s_cum[bj] + bt * seg_len[bj], math.copysign(best, bcross), bj


@kernel
def segments(pts, s_start) -> tuple:
    """The arrays of a polyline through ``pts`` ``(M, 2)``: ``(points, seg, seg_len, heading,
    s_cum)``, points closer than 1e-9 m to the one before dropped (fewer than 2 points left
    means the curve has no length)."""
    m = len(pts)
    keep = np.zeros(m, np.bool_)
    keep[0] = True
    for i in range(1, m):
        keep[i] = np.hypot(pts[i, 0] - pts[i - 1, 0], pts[i, 1] - pts[i - 1, 1]) > 1e-9
    points = pts[keep]
    n = len(points) - 1
    seg, seg_len, heading = np.empty((max(n, 0), 2)), np.empty(max(n, 0)), np.empty(max(n, 0))
    s_cum = np.empty(len(points))
    s_cum[0] = s_start + 0.0
    total = 0.0
    for i in range(n):
        sx, sy = points[i + 1, 0] - points[i, 0], points[i + 1, 1] - points[i, 1]
        seg[i, 0], seg[i, 1] = sx, sy
        seg_len[i] = np.hypot(sx, sy)
        heading[i] = math.atan2(sy, sx)
        total += seg_len[i]
        s_cum[i + 1] = s_start + total
    return points, seg, seg_len, heading, s_cum
