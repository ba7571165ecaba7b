"""Compiled ray casting for the occupancy grid: first hits along sampled rays, visibility.

The rays are sampled at whole cells given by a ``(rays, samples, 2)`` int16 map of
``(column, row)`` pairs (OpenCV's ``CV_16SC2`` nearest-neighbour map). Walking each ray only
up to its first obstacle costs a fraction of remapping the whole polar image.
"""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel


@kernel
def first_hits(obstacles: np.ndarray, samples: np.ndarray, out: np.ndarray) -> None:
    """``out[k]``: index of the first sample of ray ``k`` on an obstacle (a non-zero cell of
    ``obstacles`` or a cell outside the grid); the last sample of every ray counts as a hit."""
    rows, cols = obstacles.shape
    n_rays, n_samples = samples.shape[0], samples.shape[1]
    for k in range(n_rays):
        hit = n_samples - 1
        for j in range(n_samples - 1):
            u, v = samples[k, j, 0], samples[k, j, 1]
            if u < 0 or v < 0 or u >= cols or v >= rows or obstacles[v, u] != 0:
                hit = j
                break
        out[k] = hit


@kernel
def mark_visible(rad: np.ndarray, ray: np.ndarray, reach: np.ndarray, visible: np.ndarray) -> None:
    """``visible[r, c] = 1`` where the cell's radius ``rad`` (in samples) is within the
    ``reach`` of its ray ``ray[r, c]``; other cells are left as they are."""
    rows, cols = rad.shape
    for r in range(rows):
        for c in range(cols):
            if rad[r, c] <= reach[ray[r, c]]:
                visible[r, c] = 1


@kernel
def cell_states(obstacles: np.ndarray, visible: np.ndarray, lut: np.ndarray, out: np.ndarray):
    """``out = lut[obstacles + 2 * visible]`` (uint8 grids)."""
    rows, cols = obstacles.shape
    for r in range(rows):
        for c in range(cols):
            out[r, c] = lut[obstacles[r, c] + 2 * visible[r, c]]
