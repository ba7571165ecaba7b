"""Recorded vehicles whose footprints overlap at a common time stamp (a quirk of the
recording: real cars do not drive through each other).

The cost grows with the number of samples, not with the square of the number of tracks: the
samples of all tracks are sorted by time stamp and x, and only neighbours in that order within
reach of each other are compared (a sweep); the few pairs whose bounding circles touch are
tested with separating axes, and the undecided ones with OpenCV's exact intersection.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gridsim.traffic.track import Track
from gridsim.world import collision_kernels

#: Time stamps are matched to the millisecond [s].
TIME_QUANTUM = 1e-3


def _samples(tracks: Sequence[Track]) -> tuple[np.ndarray, ...]:
    """All samples ``(time key, x, y, heading, track index)``, one per distinct time stamp
    of a track (its first sample), sorted by time key then x."""
    keys, xs, ys, hs, idx = [], [], [], [], []
    for i, tr in enumerate(tracks):
        key = np.rint(np.asarray(tr.t) / TIME_QUANTUM).astype(np.int64)
        _, first = np.unique(key, return_index=True)
        keys.append(key[first])
        xs.append(tr.x[first])
        ys.append(tr.y[first])
        hs.append(tr.heading[first])
        idx.append(np.full(len(first), i, np.int64))
    cat = [np.concatenate(a) for a in (keys, xs, ys, hs, idx)]
    order = np.lexsort((cat[1], cat[0]))
    return tuple(a[order] for a in cat)


def overlapping_tracks(tracks: Sequence[Track]) -> set[int]:
    """Indices of the tracks whose footprint (``length`` x ``width`` box at the recorded
    centre and heading) overlaps another's at a time stamp both have."""
    import cv2

    if len(tracks) < 2:
        return set()
    key, x, y, psi, owner = _samples(tracks)
    length = np.array([t.length for t in tracks])[owner]
    width = np.array([t.width for t in tracks])[owner]
    reach = 0.5 * np.hypot(length, width)
    widest = 2.0 * float(reach.max())
    pairs_i, pairs_j = [], []
    for gap in range(1, len(key)):
        i = np.arange(len(key) - gap)
        j = i + gap
        same = (key[i] == key[j]) & (x[j] - x[i] <= widest)
        if not same.any():
            break  # sorted by x within a time key: farther neighbours are farther still
        i, j = i[same], j[same]
        near = (owner[i] != owner[j]) & (np.hypot(x[i] - x[j], y[i] - y[j]) <= reach[i] + reach[j])
        pairs_i.append(i[near])
        pairs_j.append(j[near])
    none = [np.zeros(0, np.int64)]
    i, j = np.concatenate(pairs_i or none), np.concatenate(pairs_j or none)
    # boxes apart by more than APART along a separating axis do not overlap; the others are
    # left to OpenCV's exact intersection (whose own tolerance is far smaller)
    undecided = ~collision_kernels.pairs_apart(x, y, psi, length, width, i, j,
                                               collision_kernels.APART)  # fmt: skip
    bad: set[int] = set()
    for a, b in zip(i[undecided].tolist(), j[undecided].tolist(), strict=True):
        if owner[a] in bad and owner[b] in bad:
            continue
        ra = ((x[a], y[a]), (length[a], width[a]), np.rad2deg(psi[a]))
        rb = ((x[b], y[b]), (length[b], width[b]), np.rad2deg(psi[b]))
        if cv2.rotatedRectangleIntersection(ra, rb)[0] != cv2.INTERSECT_NONE:
            bad |= {int(owner[a]), int(owner[b])}
    return bad
