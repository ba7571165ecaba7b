"""Compiled ray casting for the occupancy grid: first hits along sampled rays, visibility.

A ray is sampled at whole cells (OpenCV's ``CV_16SC2`` nearest-neighbour map of ``(column,
row)`` pairs, ``ray_step`` cells apart). :func:`ray_runs` turns each ray's samples into runs
of the same cell, cut at the first sample outside the grid; walking each ray only up to its
first obstacle, one cell per run, costs a fraction of remapping the whole polar image.
"""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel


def index_dtype(n: int) -> type:
    """The smallest of int16 and int32 that holds the indices ``0 .. n - 1`` (smaller tables
    stay in cache between steps)."""
    return np.int16 if n <= np.iinfo(np.int16).max + 1 else np.int32


def ray_runs(samples: np.ndarray, rows: int, cols: int) -> tuple[np.ndarray, ...]:
    """The walk tables of the sampled rays ``samples`` ``(rays, S, 2)`` (int16 column, row):
    ``cells`` ``(rays, M)`` flat cell indices (row * cols + column) and ``firsts``
    ``(rays, M)`` the sample index where each run of equal cells starts, ``counts``
    ``(rays,)`` the runs per ray, and ``ends`` ``(rays,)`` the hit index of a ray that meets
    no obstacle: its first sample outside the grid, at most its last sample (``S - 1``).
    Indices are int16 where they fit (:func:`index_dtype`)."""
    n_rays, n_samples = samples.shape[:2]
    u = samples[:, :-1, 0].astype(np.int64)
    v = samples[:, :-1, 1].astype(np.int64)
    outside = (u < 0) | (v < 0) | (u >= cols) | (v >= rows)
    ends = np.where(outside.any(axis=1), np.argmax(outside, axis=1), n_samples - 1)
    flat = v * cols + u
    j = np.arange(n_samples - 1)
    starts = np.ones(flat.shape, bool)
    starts[:, 1:] = flat[:, 1:] != flat[:, :-1]
    starts &= j[None] < ends[:, None]
    counts = starts.sum(axis=1)
    order = np.argsort(~starts, axis=1, kind="stable")[:, : max(int(counts.max()), 1)]
    cells = np.take_along_axis(flat, order, axis=1).astype(index_dtype(rows * cols))
    firsts = np.broadcast_to(j, flat.shape)[np.arange(n_rays)[:, None], order]
    return (
        cells,
        firsts.astype(index_dtype(n_samples)),
        counts.astype(np.int32),
        ends.astype(np.int32),
    )


@kernel
def first_hits(obstacles, cells, firsts, counts, ends, out) -> None:
    """``out[k]``: index of the first sample of ray ``k`` on an obstacle (a non-zero cell of
    ``obstacles``, C-contiguous) or outside the grid, given the tables of :func:`ray_runs`;
    the last sample of every ray counts as a hit."""
    flat = obstacles.reshape(-1)
    for k in range(len(counts)):
        hit = ends[k]
        for e in range(counts[k]):
            if flat[cells[k, e]] != 0:
                hit = firsts[k, e]
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


def ray_cells(ray: np.ndarray, rad: np.ndarray, n_rays: int) -> tuple[np.ndarray, ...]:
    """The cells of each ray in order of radius, for :func:`cell_states_by_ray`: flat cell
    indices ``(rows * cols,)`` and their radii (float32), grouped by ray (ray ``k``'s at
    ``offsets[k]:offsets[k + 1]``), given each cell's ``ray`` and radius ``rad``
    ``(rows, cols)``."""
    order = np.lexsort((rad.ravel(), ray.ravel()))
    offsets = np.searchsorted(ray.ravel()[order], np.arange(n_rays + 1)).astype(np.int32)
    return order.astype(index_dtype(rad.size)), rad.ravel()[order], offsets


@kernel
def cell_states_by_ray(obstacles, cells, cell_rad, offsets, reach, lut, out) -> None:
    """``out = lut[obstacles + 2 * visible]`` (uint8, C-contiguous) where a cell is visible if
    its radius is within the ``reach`` of its ray (as :func:`mark_visible` into a cleared
    grid, then :func:`cell_states`): per ray only its visible cells are visited, nearest
    first (the tables of :func:`ray_cells`). ``obstacles`` holds 0 and 1 only."""
    seen = obstacles.reshape(-1)
    flat = out.reshape(-1)
    if lut[0] == lut[1]:  # unseen cells are all alike (obstacle or not): one fill
        flat[:] = lut[0]
    else:
        for c in range(len(flat)):
            flat[c] = lut[seen[c]]
    for k in range(len(reach)):
        r = reach[k]
        for j in range(offsets[k], offsets[k + 1]):
            if not cell_rad[j] <= r:
                break
            c = cells[j]
            flat[c] = lut[seen[c] + 2]


@kernel
def grid_states(obstacles, cells, firsts, counts, ends, depth, by_ray, cell_rad, offsets, lut,
                hits, out) -> None:  # fmt: skip
    """One mount seeing all around: :func:`first_hits` into ``hits``, the reach of each ray
    ``float32(hit) + depth`` (``depth`` float32, as NumPy's ``hits.astype(np.float32) +
    np.float32(depth)``) and :func:`cell_states_by_ray` into ``out``, in one call."""
    first_hits(obstacles, cells, firsts, counts, ends, hits)
    reach = np.empty(len(hits), np.float32)
    for k in range(len(hits)):
        reach[k] = np.float32(hits[k]) + depth
    cell_states_by_ray(obstacles, by_ray, cell_rad, offsets, reach, lut, out)
