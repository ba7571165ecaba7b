"""Compiled look-ups in the flat arrays of a :class:`~gridsim.traffic.tables.TableBank`.

One pass per query: clamp, locate the segment (binary search, or one bucket read and one
comparison when many queries come at once), interpolate. The operations are those of the
NumPy expressions they replace, in the same order, so the results are the same bits.
"""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel


@kernel
def _search_right(keys: np.ndarray, k: float) -> int:
    """``searchsorted(keys, k, side="right") - 1``."""
    lo, hi = 0, len(keys)
    while lo < hi:
        mid = (lo + hi) >> 1
        if keys[mid] <= k:
            lo = mid + 1
        else:
            hi = mid
    return lo - 1


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
            i = _search_right(keys, k)
        else:  # at most one key inside the bucket: one comparison decides
            i = c0 - 1 + (1 if keys[min(c0, n - 1)] <= k else 0)
    else:
        i = _search_right(keys, k)
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
def frenet(bank, ys, slope, normal, heading, slots, s, d, buckets, xy, h) -> None:
    """Points ``xy[q]`` at arc length ``s[q]`` and offset ``d[q]`` on path ``slots[q]``
    (end segments extended), and the path headings ``h[q]``."""
    keys = bank[0]
    for q in range(len(s)):
        i, k = _segment(bank, slots[q], s[q], False, buckets)
        dk = k - keys[i]
        for c in range(2):
            xy[q, c] = (ys[i, c] + dk * slope[i, c]) + d[q] * normal[i, c]
        h[q] = heading[i]
