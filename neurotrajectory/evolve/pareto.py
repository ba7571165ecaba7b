"""Multi-objective selection: non-dominated sorting, crowding distance, hypervolume.

All objectives are minimised here (negate the ones to maximise before calling).

With a constraint ``violation`` per point (0: feasible), domination is Deb's constrained
domination (constrained NSGA-II): a point with a smaller violation dominates one with a larger
violation; among equal violations (in particular between feasible points) the usual Pareto
domination decides.
"""

from __future__ import annotations

import numpy as np


def dominates_matrix(f: np.ndarray, violation: np.ndarray | None = None) -> np.ndarray:
    """``D[i, j]``: point ``i`` dominates point ``j`` (no worse in all, better in one; with
    ``violation`` ``(N,)``, constrained domination: see the module docstring)."""
    le = np.all(f[:, None, :] <= f[None, :, :], axis=2)
    lt = np.any(f[:, None, :] < f[None, :, :], axis=2)
    if violation is None:
        return le & lt
    v = np.asarray(violation, dtype=np.float64)
    return (v[:, None] < v[None, :]) | ((v[:, None] == v[None, :]) & le & lt)


def non_dominated_sort(f: np.ndarray, violation: np.ndarray | None = None) -> np.ndarray:
    """Pareto rank of each row of ``f`` ``(N, M)``: 0 for the non-dominated front, 1 for the
    front after removing it, and so on. Duplicates share a rank. ``violation`` ``(N,)``
    (>= 0) makes it constrained."""
    f = np.asarray(f, dtype=np.float64)
    if f.ndim != 2 or not np.all(np.isfinite(f)):
        raise ValueError("objectives must be a finite (N, M) array")
    if violation is not None:
        violation = np.asarray(violation, dtype=np.float64)
        if violation.shape != (len(f),) or not np.all(violation >= 0):
            raise ValueError(f"violation must be {len(f)} numbers >= 0")
    dom = dominates_matrix(f, violation)
    count = dom.sum(axis=0)  # how many dominate each point
    rank = np.full(len(f), -1)
    current = np.flatnonzero(count == 0)
    r = 0
    while len(current):
        rank[current] = r
        count = count - dom[current].sum(axis=0)
        count[rank >= 0] = -1
        current = np.flatnonzero(count == 0)
        r += 1
    return rank


def crowding_distance(f: np.ndarray) -> np.ndarray:
    """Deb's NSGA-II crowding distance of the points ``f`` ``(N, M)`` of one front: boundary
    points get infinity; interior points the sum over objectives of the normalised gap
    between their neighbours (not divided by M)."""
    f = np.asarray(f, dtype=np.float64)
    n, m = f.shape
    dist = np.zeros(n)
    if n <= 2:
        return np.full(n, np.inf)
    for k in range(m):
        order = np.argsort(f[:, k], kind="stable")
        span = f[order[-1], k] - f[order[0], k]
        dist[order[0]] = dist[order[-1]] = np.inf
        if span > 0:
            dist[order[1:-1]] += (f[order[2:], k] - f[order[:-2], k]) / span
    return dist


def rank_and_crowding(
    f: np.ndarray, violation: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Pareto ranks (constrained with ``violation``) and crowding distances (computed within
    each front)."""
    rank = non_dominated_sort(f, violation)
    crowd = np.zeros(len(f))
    for r in np.unique(rank):
        members = np.flatnonzero(rank == r)
        crowd[members] = crowding_distance(f[members])
    return rank, crowd


def hypervolume(f: np.ndarray, ref: np.ndarray) -> float:
    """Hypervolume dominated by the points ``f`` (minimised) up to ``ref`` (moocore)."""
    import moocore

    f = np.asarray(f, dtype=np.float64)
    keep = np.all(f < ref, axis=1)
    if not np.any(keep):
        return 0.0
    return float(moocore.hypervolume(f[keep], ref=np.asarray(ref, dtype=np.float64)))


#: How far past the reference the box of :func:`hypervolume_ratio` reaches, as a ratio of
#: each objective: the reference alone dominates ``(HV_MARGIN - 1) ** 3`` of it.
HV_MARGIN = 1.1


def hypervolume_ratio(fitness: np.ndarray, reference: np.ndarray,
                      lost: np.ndarray | None = None) -> float:  # fmt: skip
    """How much more of the objective space the members ``fitness`` ``(K, 3)`` dominate than
    ``reference`` ``[l1, l2, l3]`` alone: each member as ratios to the reference (``l1 / l1_ref``,
    ``l2 / l2_ref``, ``l3_ref / l3``, all minimised, the reference at 1), the hypervolume up
    to :data:`HV_MARGIN` in each, divided by the reference's own ``(HV_MARGIN - 1) ** 3``.
    1: no member beyond the reference; 2: twice its volume. Members that ``lost`` episode
    time (> 0) do not count."""
    f = np.asarray(fitness, dtype=np.float64)
    ref = np.maximum(np.abs(np.asarray(reference, dtype=np.float64)), 1e-12)
    with np.errstate(divide="ignore"):
        ratios = np.column_stack([f[:, 0] / ref[0], f[:, 1] / ref[1],
                                  ref[2] / np.maximum(f[:, 2], 0.0)])  # fmt: skip
    if lost is not None:
        ratios = ratios[np.asarray(lost) <= 0]
    box = np.full(3, HV_MARGIN)
    own = (HV_MARGIN - 1.0) ** 3
    return max(hypervolume(np.vstack([ratios, np.ones((1, 3))]), box), own) / own


def generation_hypervolume(record: dict, first: dict, anchored: bool) -> float:
    """:func:`hypervolume_ratio` of a generation's ``history.json`` record against the
    reference on its own episodes: its individual 0 (the warm start or the centre) in an
    ``anchored`` run, else the median member of generation 0 (``first``)."""
    f = np.array(record["fitness"])
    ref = f[0] if anchored else np.median(np.array(first["fitness"]), axis=0)
    return hypervolume_ratio(f, ref, np.array(record.get("violation", np.zeros(len(f)))))


def minimised(fitness: np.ndarray) -> np.ndarray:
    """Fitness ``[l1, l2, l3]`` as objectives to minimise: ``[l1, l2, -l3]``."""
    f = np.asarray(fitness, dtype=np.float64)
    return np.column_stack([f[:, 0], f[:, 1], -f[:, 2]])


#: The front members a user can pick: the knee or the best on one objective.
PICKS = ("knee", "best-l1", "best-l2", "best-l3")


def knee_distance(f: np.ndarray) -> np.ndarray:
    """Each point's distance from the ideal point after scaling each (minimised) objective of
    ``f`` ``(N, M)`` to [0, 1] over the points; the knee is the nearest."""
    f = np.asarray(f, dtype=np.float64)
    lo, hi = f.min(axis=0), f.max(axis=0)
    z = (f - lo) / np.where(hi > lo, hi - lo, 1.0)
    return np.hypot.reduce(z, axis=1)


def pick_member(fitness: np.ndarray, pick: str) -> int:
    """Index into the front: ``best-lK`` optimises one objective; ``knee`` is the member
    closest to the ideal point after scaling each (minimised) objective to [0, 1] over
    the front (:func:`knee_distance`)."""
    f = minimised(fitness)
    if pick == "knee":
        return int(np.argmin(knee_distance(f)))
    if pick in PICKS:
        return int(np.argmin(f[:, PICKS.index(pick) - 1]))
    raise ValueError(f"unknown pick {pick!r}; choose from {list(PICKS)}")
