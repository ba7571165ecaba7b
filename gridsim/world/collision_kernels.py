"""Compiled broad phase of :class:`~gridsim.world.collision.CollisionChecker`: the same
operations, in the same order, as the NumPy code it replaced (``np.hypot`` compiled is libm's
``hypot``, as NumPy's)."""

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
