"""Compiled set-point handling of the trajectory action: the same operations, in the same
order, as the NumPy code it replaced (clip, :func:`~gridsim.frames.grid_to_world`,
``np.hypot`` of the steps; ``tests/test_gridsim/envs/test_env.py`` compares them on random
actions)."""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel
from gridsim.road.polyline_kernels import segments


@kernel
def setpoint_path(a, low, high, ex, ey, c, s):
    """Set-points ``a`` ``(H, 2)`` [m, grid frame] clipped to ``[low, high]``, in the world
    frame of an ego at ``(ex, ey)`` with grid rotation ``(c, s)`` = its cos, sin. Returns
    them ``(H, 2)`` [m, world], the distance [m] from the ego to the first, and the path
    from the ego through them, dropping points within 1 mm of the one before, as the arrays of
    :func:`~gridsim.road.polyline_kernels.segments` (its points ``(K, 2)`` first)."""
    h = a.shape[0]
    pts = np.empty((h, 2))
    path = np.empty((h + 1, 2))
    path[0, 0], path[0, 1] = ex, ey
    k = 1
    for i in range(h):
        p0 = min(max(a[i, 0], np.float64(low[i, 0])), np.float64(high[i, 0]))
        p1 = min(max(a[i, 1], np.float64(low[i, 1])), np.float64(high[i, 1]))
        x, y = c * p0 - s * p1 + ex, s * p0 + c * p1 + ey
        pts[i, 0], pts[i, 1] = x, y
        px, py = ex, ey
        if i > 0:
            px, py = pts[i - 1, 0], pts[i - 1, 1]
        if np.hypot(x - px, y - py) > 1e-3:
            path[k, 0], path[k, 1] = x, y
            k += 1
    return pts, np.hypot(pts[0, 0] - ex, pts[0, 1] - ey), segments(path[:k], 0.0)
