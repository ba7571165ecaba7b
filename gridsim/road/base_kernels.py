"""Compiled look-up of a road's pieces near a point: the same comparisons as the NumPy code
it replaced (``tests/test_gridsim/road/test_roads.py`` compares them on random boxes)."""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel


@kernel
def near(boxes, cx, cy, radius):
    """Indices of the boxes ``(N, 4)`` = ``[x_min, y_min, x_max, y_max]`` [m] that intersect
    the square of half-size ``radius`` [m] around ``(cx, cy)``."""
    hi_x, lo_x, hi_y, lo_y = cx + radius, cx - radius, cy + radius, cy - radius
    out = np.empty(len(boxes), np.int64)
    n = 0
    for i in range(len(boxes)):
        if (
            boxes[i, 0] <= hi_x
            and boxes[i, 2] >= lo_x
            and boxes[i, 1] <= hi_y
            and boxes[i, 3] >= lo_y
        ):
            out[n] = i
            n += 1
    return out[:n]
