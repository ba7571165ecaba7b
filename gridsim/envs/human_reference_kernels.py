"""Compiled look-up of a reference trajectory: the same operations, in the same order, as the
NumPy code it replaced (``np.interp`` compiled gives NumPy's bits;
``tests/test_gridsim/envs/test_reference.py`` compares them on random trajectories)."""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel


@kernel
def positions(times, t, xy, n, end, ex, ey, c, s):
    """Positions at ``times`` [s]: ``np.interp`` over the first ``n`` samples ``(t, xy)``,
    extrapolated past the last time ``t[-1]`` with ``end = (v, cos psi, sin psi)`` of the last
    sample. Returns them ``(N, 2)`` [m, world] and in the grid frame of an ego at ``(ex, ey)``
    rotated by ``(c, s)`` = cos, sin of the grid rotation (float32, as
    :func:`~gridsim.frames.world_to_grid`)."""
    x = np.interp(times, t[:n], xy[:n, 0])
    y = np.interp(times, t[:n], xy[:n, 1])
    world = np.empty((len(times), 2))
    grid = np.empty((len(times), 2), np.float32)
    t_end = t[-1]
    v, cos_psi, sin_psi = end
    for i in range(len(times)):
        if times[i] > t_end:
            extra = times[i] - t_end
            x[i] += extra * v * cos_psi
            y[i] += extra * v * sin_psi
        world[i, 0], world[i, 1] = x[i], y[i]
        dx, dy = x[i] - ex, y[i] - ey
        grid[i, 0] = np.float32(c * dx + s * dy)
        grid[i, 1] = np.float32(-s * dx + c * dy)
    return world, grid
