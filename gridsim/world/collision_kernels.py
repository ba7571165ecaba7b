"""Compiled broad phases of :class:`~gridsim.world.collision.CollisionChecker`: for vehicles
the same operations, in the same order, as the NumPy code it replaced (``np.hypot`` compiled
is libm's ``hypot``, as NumPy's); for road edges a conservative distance test before pymunk's
query."""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel


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
        dx, dy = x1 - x0, y1 - y0
        den = dx * dx + dy * dy
        t = 0.0
        if den > 0.0:
            t = min(max(((cx - x0) * dx + (cy - y0) * dy) / den, 0.0), 1.0)
        if not np.hypot(cx - x0 - t * dx, cy - y0 - t * dy) > reach:
            out[n] = k
            n += 1
    return out[:n]
