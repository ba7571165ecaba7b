"""Compiled look-ups in the flat arrays of a :class:`~gridsim.traffic.tables.TableBank`.

One pass per query: clamp, locate the segment (binary search, or one bucket read and one
comparison when many queries come at once), interpolate. The operations are those of the
NumPy expressions they replace, in the same order, so the results are the same bits.
"""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel, search_right

#: Up to this many queries, plain binary search; more use the bucket index.
SMALL_QUERY = 128


@kernel
def _segment(bank: tuple, t: int, x: float, clamp: bool, buckets: bool) -> tuple[int, float]:
    """Segment index and shared-axis key of table ``t`` at ``x``."""
    keys, base, first, last, lo, hi, counts, width = bank
    if clamp:
        x = min(max(x, lo[t]), hi[t])
    k = x + base[t]
    n = len(keys)
    if buckets:
        b = min(max(np.int64((k - keys[0]) / width), 0), len(counts) - 2)
        c0, c1 = counts[b], counts[b + 1]
        if c1 - c0 > 1 or k < keys[0] or k > keys[n - 1]:
            i = search_right(keys, k)
        else:  # at most one key inside the bucket: one comparison decides
            i = c0 - 1 + (1 if keys[min(c0, n - 1)] <= k else 0)
    else:
        i = search_right(keys, k)
    return min(max(i, first[t]), last[t]), k


@kernel
def lookup(bank, ys, slope, slots, x, clamp, buckets, out) -> None:
    """``out[q] = ys[i] + (k - keys[i]) * slope[i]`` for table ``slots[q]`` at ``x[q]``."""
    keys = bank[0]
    for q in range(len(x)):
        i, k = _segment(bank, slots[q], x[q], clamp, buckets)
        dk = k - keys[i]
        for c in range(ys.shape[1]):
            out[q, c] = ys[i, c] + dk * slope[i, c]


@kernel
def frenet_one(path, t, s, d, buckets) -> tuple[float, float, float]:
    """Point ``(x, y)`` at arc length ``s`` and offset ``d`` on path ``t`` (end segments
    extended) and the path heading; ``path`` is :meth:`PathBank.kernel_data`."""
    i, k = _segment(path[0], t, s, False, buckets)
    x, y = point_on_segment(path, i, k, d)
    return x, y, path[4][i]


@kernel
def point_on_segment(path, i, k, d) -> tuple[float, float]:
    """Point ``(x, y)`` of segment ``i`` (a flat index) of :meth:`PathBank.kernel_data`
    ``path`` at the shared-axis key ``k`` (its line extended), ``d`` [m] to its left."""
    _, ys, slope, normal, _ = path
    dk = k - path[0][0][i]
    x = (ys[i, 0] + dk * slope[i, 0]) + d * normal[i, 0]
    y = (ys[i, 1] + dk * slope[i, 1]) + d * normal[i, 1]
    return x, y


@kernel
def frenet(path, slots, s, d, buckets, xy, h) -> None:
    """:func:`frenet_one` for every query, into ``xy`` ``(n, 2)`` and ``h`` ``(n,)``."""
    for q in range(len(s)):
        xy[q, 0], xy[q, 1], h[q] = frenet_one(path, slots[q], s[q], d[q], buckets)


@kernel
def flat_tables(xs, lengths, ys, gap, keys, slope, base, first, last) -> None:
    """The flat arrays of tables laid back to back (``TableBank._rebuild``): table ``k`` holds
    ``lengths[k]`` knots of the concatenated ``xs`` and ``ys`` ``(N, width)``; its keys are
    ``xs + base[k]``, ``base[k] = offset - x[0]``, the next table's offset ``x[-1] + base[k] +
    gap``; ``slope[i] = (ys[i + 1] - ys[i]) / (keys[i + 1] - keys[i])`` (the last knot: 0 over
    a key step of 1). The NumPy expressions' operations, in their order: the same bits."""
    offset, n = 0.0, 0
    for k in range(len(lengths)):
        m = lengths[k]
        b = offset - xs[n]
        for j in range(n, n + m):
            keys[j] = xs[j] + b
        base[k], first[k], last[k] = b, n, n + m - 2
        offset = xs[n + m - 1] + b + gap
        n += m
    width = ys.shape[1]
    for i in range(n - 1):
        dx = keys[i + 1] - keys[i]
        for c in range(width):
            slope[i, c] = (ys[i + 1, c] - ys[i, c]) / dx
    dx = (keys[n - 1] + 1.0) - keys[n - 1]
    for c in range(width):
        slope[n - 1, c] = (ys[n - 1, c] - ys[n - 1, c]) / dx


@kernel
def counts_up_to(keys, edges, out) -> None:
    """``out[b]``: how many of the increasing ``keys`` are <= ``edges[b]`` (increasing):
    ``np.searchsorted(keys, edges, side="right")`` in one merge pass."""
    i, n = 0, len(keys)
    for b in range(len(edges)):
        while i < n and keys[i] <= edges[b]:
            i += 1
        out[b] = i
