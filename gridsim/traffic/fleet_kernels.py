"""Compiled :meth:`gridsim.traffic.fleet.Fleet.tick`: one call per tick finds the leaders
(the next vehicle on the same path, the ego, and candidates on other paths found by the
caller), advances every active participant (replay or IDM), updates the poses and reports
the participants whose profile ran out.

Every expression is the scalar form of the NumPy one it replaced, in the same order (the IDM
is the same source, :mod:`gridsim.vehicle.idm`), so the results are the same bits.

``state`` is the tuple of the fleet's arrays in :class:`FleetState` order (a plain tuple:
numba takes it in a third of the time it takes to take a named one); ``paths`` and
``profiles`` are the ``kernel_data()`` of its path and profile banks.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from gridsim.jit import kernel, search_right
from gridsim.traffic.table_kernels import SMALL_QUERY, frenet_one, lookup, point_on_segment
from gridsim.vehicle.footprint_kernels import oriented_boxes_apart
from gridsim.vehicle.idm import idm_accel, idm_gap

REPLAY, IDM = 0, 1
#: Up to this many active participants, the leader candidates on other paths come from all
#: pairs (cheaper than a k-d tree); the compiled world tick searches only up to as many.
ALL_PAIRS_MAX = 48
_S, _V, _D, _H = 0, 1, 2, 3


class FleetState(NamedTuple):
    """The arrays of a :class:`~gridsim.traffic.fleet.Fleet` (one entry per participant)."""

    active: np.ndarray
    geometric: np.ndarray
    mode: np.ndarray
    path: np.ndarray
    profile: np.ndarray
    s: np.ndarray
    d: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    k: np.ndarray
    d_bias: np.ndarray
    length: np.ndarray
    width: np.ndarray
    x: np.ndarray
    y: np.ndarray
    psi: np.ndarray
    gap: np.ndarray
    leader: np.ndarray
    lead_v: np.ndarray


@kernel
def _clamp(x, lo, hi):
    return min(max(x, lo), hi)


@kernel
def advance(idx, now, nxt, fleet, lead_v, limits, idm, dt, decay) -> None:
    """Advance participants ``idx`` by ``dt`` [s] in place.

    ``now``/``nxt``: their profile values ``(n, 4)`` at ``tau`` and ``tau + dt``; ``fleet``:
    the arrays ``(s, v, tau, d, d_bias, k, mode, geometric, gap)`` of the :class:`Fleet`;
    ``lead_v``: leader speeds; ``limits``: ``(v_min, v_max, a_max, b_max, resume_factor,
    resume_speed_tol)``; ``idm``: :attr:`IDMParams.values`; ``decay``: the factor of the
    lateral bias over one tick.
    """
    v_min, v_max, a_max, b_max, resume_factor, resume_tol = limits
    s_, v_, tau_, d_, bias_, k_, mode, geometric, gap = fleet
    for q in range(len(idx)):
        i = idx[q]
        v, k, g, lv = v_[i], k_[i], gap[i], lead_v[i]
        v_rep = min(k * nxt[q, _V], v_max)
        dv = v - lv
        m = mode[i]
        # back to replay at a gap with room to spare at the faster of its speed and the
        # replay's: a vehicle faster than its profile keeps its speed for a tick or more
        # after handing back (rate-limited), and the desired gap at the replay speed alone
        # could hand it back and forth tick after tick
        v_back = max(v, v_rep)
        if m == REPLAY and g < idm_gap(v, dv, *idm):
            m = IDM
        elif (
            m == IDM
            and g > resume_factor * idm_gap(v_back, v_back - lv, *idm)
            and v >= v_rep - resume_tol
        ):
            m = REPLAY
        bias = bias_[i] * decay
        if m == IDM:  # IDM, with the profile's current speed as desired speed
            v_des = k * now[q, _V]
            acc = idm_accel(v, v_des, g, dv, *idm)
            new_v = _clamp(v + acc * dt, 0.0, v_max)
            ds = 0.5 * (v + new_v) * dt
            new_s = s_[i] + ds
            new_tau = tau_[i] + _clamp(ds / max(v_des * dt, 1e-3), 0.0, 1.0) * dt
            new_d = d_[i] - bias  # hold the lateral position
        else:  # replay: recorded distance (exact poses) or the rate-limited scaled speed
            if geometric[i]:
                new_v = v_rep
                new_s = s_[i] + (nxt[q, _S] - now[q, _S])
            else:
                new_v = _clamp(_clamp(v_rep, v_min, v_max), v - b_max * dt, v + a_max * dt)
                new_s = s_[i] + 0.5 * (v + new_v) * dt
            new_tau = tau_[i] + dt
            new_d = nxt[q, _D]
        s_[i], v_[i], tau_[i], mode[i], bias_[i] = new_s, new_v, new_tau, m, bias
        d_[i] = new_d + bias


@kernel
def same_path(idx, path, s, length, v, psi, lookahead):
    """Candidates ``(a, b, gap, lead_v)`` (``a``, ``b`` index ``idx``): each participant and
    the next one ahead on its path (a stable sort by path, then arc length), within
    ``lookahead`` [m]; ``lead_v`` is the leader's speed along the follower's heading."""
    m = len(idx)
    ps, ss = path[idx], s[idx]
    order = np.argsort(ss, kind="mergesort")
    order = order[np.argsort(ps[order], kind="mergesort")]
    a, b = np.empty(m, np.int64), np.empty(m, np.int64)
    gap, lead_v = np.empty(m), np.empty(m)
    n = 0
    for q in range(m - 1):
        qa, qb = order[q], order[q + 1]
        if ps[qa] != ps[qb]:
            continue
        ia, ib = idx[qa], idx[qb]
        g = ss[qb] - ss[qa] - 0.5 * (length[ia] + length[ib])
        if g + 0.5 * (length[ia] + length[ib]) <= lookahead:
            a[n], b[n], gap[n] = qa, qb, g
            lead_v[n] = v[ib] * np.cos(psi[ib] - psi[ia])
            n += 1
    return a[:n], b[:n], gap[:n], lead_v[:n]


@kernel
def cross_path(idx, corridor, c, sn, pi, pj, test_close, state, paths, lookahead, margin):
    """Leader candidates ``(a, b, gap, lead_v)`` on other paths (``a``, ``b`` index ``idx``,
    the active participants): of the pairs ``(pi, pj)`` (``test_close``: only those closer
    than ``lookahead`` [m]), each way round where the other vehicle is ahead along the
    follower's heading (``c``, ``sn``: the cosines and sines of ``psi[idx]``) and lies on the
    follower's path as far ahead as it is (within half the widths and ``margin`` [m]), the
    two heading the same way, on different paths and not in one corridor (``corridor``: of
    ``path[idx]``, ``-1`` for none), and not both replaying a recorded track. Candidates
    come in the order of the NumPy code this replaced (every pair ahead one way, then every
    pair ahead the other way), with the same bits."""
    f = FleetState(*state)
    n = len(pi)
    a, b, lon = np.empty(2 * n, np.int64), np.empty(2 * n, np.int64), np.empty(2 * n)
    k = 0
    for way in range(2):
        for q in range(n):
            i, j = pi[q], pj[q]
            xi, yi, xj, yj = f.x[idx[i]], f.y[idx[i]], f.x[idx[j]], f.y[idx[j]]
            if test_close and not np.hypot(xi - xj, yi - yj) <= lookahead:
                continue
            dx, dy = xj - xi, yj - yi
            if way == 0:
                ahead, fa, fb = dx * c[i] + dy * sn[i], i, j
            else:
                ahead, fa, fb = -(dx * c[j] + dy * sn[j]), j, i
            if not ahead > 0:
                continue
            ia, ib = idx[fa], idx[fb]
            trusted_a = f.geometric[ia] and f.mode[ia] == REPLAY
            trusted_b = f.geometric[ib] and f.mode[ib] == REPLAY
            if (
                c[fa] * c[fb] + sn[fa] * sn[fb] > 0.0
                and not (trusted_a and trusted_b)
                and f.path[ia] != f.path[ib]
                and (corridor[fa] < 0 or corridor[fa] != corridor[fb])
            ):
                a[k], b[k], lon[k] = fa, fb, ahead
                k += 1
    buckets = k > SMALL_QUERY
    gap, lead_v = np.empty(k), np.empty(k)
    m = 0
    for q in range(k):
        ia, ib = idx[a[q]], idx[b[q]]
        px, py, _ = frenet_one(paths, f.path[ia], f.s[ia] + lon[q], f.d[ia], buckets)
        lat = np.hypot(f.x[ib] - px, f.y[ib] - py)
        if lat < 0.5 * (f.width[ia] + f.width[ib]) + margin:
            a[m], b[m] = a[q], b[q]
            gap[m] = lon[q] - 0.5 * (f.length[ia] + f.length[ib])
            lead_v[m] = f.v[ib] * (c[a[q]] * c[b[q]] + sn[a[q]] * sn[b[q]])
            m += 1
    return a[:m], b[:m], gap[:m], lead_v[:m]


@kernel
def no_candidates():
    """No leader candidates ``(a, b, gap, lead_v)`` (new arrays: a global one is read-only, of
    another type)."""
    return (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))


@kernel
def all_pairs_candidates(state, idx, corridors, paths, leader_settings, crossings):
    """The leader candidates on other paths (:func:`cross_path`, then, with ``crossings``,
    :func:`crossing_candidates`) of the active participants ``idx`` (at most
    :data:`ALL_PAIRS_MAX`), over all their pairs in ``np.triu_indices`` order; none when
    each is on a path in a lane corridor (``corridors``: every path slot's corridor, ``-1``
    for none; ``leader_settings``: ``(lookahead, lateral_margin, crossing_horizon)``).
    Python's tick (:meth:`~gridsim.traffic.fleet.Fleet.find_leaders`) and the compiled world
    tick both call it."""
    f = FleetState(*state)
    corridor = corridors[f.path[idx]]
    m = len(idx)
    outside = False
    for q in range(m):
        outside = outside or corridor[q] < 0
    if not outside:
        return no_candidates()
    pi, pj = np.empty(m * (m - 1) // 2, np.int64), np.empty(m * (m - 1) // 2, np.int64)
    k = 0
    for a in range(m):
        for b in range(a + 1, m):
            pi[k], pj[k] = a, b
            k += 1
    psi = f.psi[idx]
    lookahead, margin, horizon = leader_settings
    found = cross_path(idx, corridor, np.cos(psi), np.sin(psi), pi, pj, True, state, paths,
                       lookahead, margin)  # fmt: skip
    if not crossings:
        return found
    return joined(found, crossing_candidates(idx, pi, pj, state, paths, margin, horizon))


@kernel
def joined(first, second):
    """Two sets of leader candidates ``(a, b, gap, lead_v)`` as one, ``first``'s first."""
    a, b = np.concatenate((first[0], second[0])), np.concatenate((first[1], second[1]))
    return a, b, np.concatenate((first[2], second[2])), np.concatenate((first[3], second[3]))


#: m: spacing of the samples of a participant's path ahead in :func:`swept_conflict`
SWEEP_STEP = 0.5
#: s: a participant yields to an ego that reaches the conflict this long after it would
#: have cleared it (or clears it this long before the participant gets there)
SWEEP_BUFFER = 1.0


@kernel
def swept_conflict(paths, path_id, s, d, length, width, v, ego, margin, horizon, buckets):
    """Gap [m] from a participant's front to where its path ahead enters the ego's footprint
    swept forward over ``horizon`` [s] (at the ego's speed, along its heading; both boxes
    grown by the participant's half width and ``margin``), if the ego will be at that place
    while the participant passes it (give or take :data:`SWEEP_BUFFER`); else inf.

    The participant is at arc length ``s`` [m], offset ``d`` [m] on path ``path_id``, with
    footprint ``length`` x ``width`` [m] and speed ``v`` [m/s] (at least 1 m/s is assumed);
    ``ego``: ``(x, y, v, length, width, cos psi, sin psi)``. A participant whose front is
    already inside the swept footprint is committed: it gets inf (it clears the way rather
    than stopping in it), and so is one whose front is in the ego's lane further ahead (in
    the ego's box swept forward without end): a car turning across the ego's lane beyond
    the sweep would otherwise stop in that lane, blocking it, for a conflict further on its
    path."""
    ex, ey, ev, e_len, e_wid, e_c, e_s = ego
    ev = max(ev, 0.0)
    half_along = 0.5 * e_len + 0.5 * width + margin  # ego box + participant, along the ego
    half_across = 0.5 * e_wid + 0.5 * width + margin
    ahead = half_along + ev * horizon
    vp = max(v, 1.0)
    u_front = 0.5 * length
    u_last = u_front + vp * horizon  # the front's travel within the horizon
    u_in, a_in = -1.0, 0.0
    u = u_front
    while u <= u_last + 2.0 * ahead:
        px, py, _ = frenet_one(paths, path_id, s + u, d, buckets)
        a = (px - ex) * e_c + (py - ey) * e_s
        b = (py - ey) * e_c - (px - ex) * e_s
        inside = -half_along < a < ahead and abs(b) < half_across
        if u == u_front and -half_along < a and abs(b) < half_across:
            return np.inf  # committed: its front is in the ego's lane ahead
        if u_in < 0:
            if inside:
                u_in, a_in = u, a
            elif u > u_last:
                return np.inf  # no conflict within the horizon
        elif not inside:
            break
        u += SWEEP_STEP
    if u_in < 0:
        return np.inf
    # the participant passes the conflict from its front's arrival to its rear's departure
    p_in, p_out = (u_in - u_front) / vp, (u + u_front) / vp
    if ev < 1e-3:  # a standing ego: the swept footprint is where it stands
        return u_in - u_front
    e_in, e_out = (a_in - half_along) / ev, (a_in + half_along) / ev
    if e_in < p_out + SWEEP_BUFFER and e_out > p_in - SWEEP_BUFFER:
        return u_in - u_front
    return np.inf


#: the cosine of the smallest angle between two participants' headings at which their paths
#: count as crossing in :func:`first_conflict` (30 degrees): nearer the same direction is a
#: merge, or a follower (which :func:`cross_path` and :func:`same_path` see)
CROSSING_COS = 0.8660254037844387

#: The touches :func:`first_conflict` counts: at :data:`CROSSING_COS` or more (crossing),
#: at less (merging or following), at any angle.
ANGLED, SHALLOW, ANY_ANGLE = 0, 1, 2


#: m: spacing of the samples of a participant's path ahead in :func:`path_samples`
CROSSING_STEP = 1.0

#: m/s: a participant slower than this counts as standing where it is for one behind it on
#: another path whose path clips its footprint (a car turning past one that waits)
STANDING_SPEED = 1.0


@kernel
def path_samples(paths, t, s, d, pose, reach):
    """Where a participant on path ``t`` at arc length ``s`` [m], lateral offset ``d`` [m]
    and ``pose`` ``(x, y, psi)`` now will be over the next ``reach`` [m]: rows ``(x, y, cos
    psi, sin psi, u, x_min, x_max, y_min, y_max)``, first the pose now (``u = 0``), then
    every :data:`CROSSING_STEP` ahead along the path (end segments extended), shifted ``d``
    to the left, with the path's heading there and the distance ``u`` [m] ahead; the last
    four columns bound the rows up to each (running minima and maxima). ``paths``:
    :meth:`~gridsim.traffic.tables.PathBank.kernel_data`."""
    keys, base, first, last = paths[0][0], paths[0][1], paths[0][2], paths[0][3]
    normal = paths[3]
    steps = max(int(reach / CROSSING_STEP), 0)
    out = np.empty((steps + 1, 9))
    x, y, h = pose
    c, sn, u = np.cos(h), np.sin(h), 0.0
    i = min(max(search_right(keys, s + base[t]), first[t]), last[t])
    for q in range(steps + 1):
        if q > 0:
            u = q * CROSSING_STEP
            key = s + u + base[t]
            while i < last[t] and keys[i + 1] <= key:
                i += 1
            x, y = point_on_segment(paths, i, key, d)
            c, sn = normal[i, 1], -normal[i, 0]  # the normal is (-sin, cos) of the heading
        out[q, 0], out[q, 1], out[q, 2], out[q, 3], out[q, 4] = x, y, c, sn, u
        if q == 0:
            out[q, 5], out[q, 6], out[q, 7], out[q, 8] = x, x, y, y
        else:
            out[q, 5], out[q, 6] = min(out[q - 1, 5], x), max(out[q - 1, 6], x)
            out[q, 7], out[q, 8] = min(out[q - 1, 7], y), max(out[q - 1, 8], y)
    return out


@kernel
def _within(samples, reach) -> int:
    """How many rows of :func:`path_samples` ``samples`` lie at most ``reach`` [m] ahead."""
    return min(len(samples), max(int(reach / CROSSING_STEP), 0) + 1)


@kernel
def first_conflict(a, reach_a, b, reach_b, size, margin, angles=ANY_ANGLE):
    """How far [m] participant ``a`` moves along its path (looking ``reach_a`` [m] ahead)
    before its footprint touches (within ``margin`` [m]) participant ``b``'s footprint now
    or on its path up to ``reach_b`` [m] ahead, at any angle to each other, or with
    ``angles`` :data:`ANGLED` at 30 degrees or more (:data:`CROSSING_COS`), with
    :data:`SHALLOW` at less: 0 if it does where it stands, inf if not within reach. ``a``,
    ``b``: their :func:`path_samples`; ``size``: ``(length_a, width_a, length_b, width_b)``
    [m]."""
    la, wa, lb, wb = size
    na, nb = _within(a, reach_a), _within(b, reach_b)
    near = 0.5 * (np.hypot(la, wa) + np.hypot(lb, wb)) + margin  # the footprints' circles
    x_lo, x_hi, y_lo, y_hi = b[nb - 1, 5], b[nb - 1, 6], b[nb - 1, 7], b[nb - 1, 8]
    if (a[na - 1, 5] > x_hi + near or a[na - 1, 6] < x_lo - near
            or a[na - 1, 7] > y_hi + near or a[na - 1, 8] < y_lo - near):  # fmt: skip
        return np.inf
    for k in range(na):
        x, y, c, sn = a[k, 0], a[k, 1], a[k, 2], a[k, 3]
        if not (x_lo - near < x < x_hi + near and y_lo - near < y < y_hi + near):
            continue
        q = 0
        while q < nb:
            dx, dy = x - b[q, 0], y - b[q, 1]
            d2 = dx * dx + dy * dy
            if d2 >= near * near:  # skip the samples that cannot come near yet: along a path
                # (offset, around bends) a point moves less than twice the arc length
                ahead = b[q, 4] + 0.5 * (np.sqrt(d2) - near)
                q += 1
                while q < nb and b[q, 4] < ahead:
                    q += 1
                continue
            angled = c * b[q, 2] + sn * b[q, 3] < CROSSING_COS  # (the cosine of the angle)
            if (angles == ANY_ANGLE or angled == (angles == ANGLED)) and not oriented_boxes_apart(
                (x, y, c, sn, la, wa), (b[q, 0], b[q, 1], b[q, 2], b[q, 3], lb, wb), margin
            ):  # at the angle asked for, touching
                return a[k, 4]
            q += 1
    return np.inf


@kernel
def _who(state, i):
    """What :func:`pair_conflict` reads of participant ``i`` (a fleet index): ``(path,
    recorded, x, y, v, length, width)``."""
    f = FleetState(*state)
    return f.path[i], f.geometric[i], f.x[i], f.y[i], f.v[i], f.length[i], f.width[i]


@kernel
def _reach(v, length, horizon) -> float:
    """How far [m] a participant at speed ``v`` [m/s] looks ahead for a crossing: what it
    covers within ``horizon`` [s] (at least 1 m/s), from its centre to its front."""
    return max(v, 1.0) * horizon + 0.5 * length


@kernel
def pair_conflict(who_i, who_j, samples_i, samples_j, margin, horizon):
    """:func:`first_conflict` of generated participants ``i`` and ``j`` each way round
    ``(u_i, u_j)`` [m], each looking :func:`_reach` ahead along its own path and, along the
    other's, past where it stands (two that meet head-on share a stretch of path beyond the
    other's own reach): inf where there is none; ``(inf, inf)`` for two heading the same way
    of which one drives into the other where it stands (a follower: :func:`cross_path` and
    :func:`same_path` find those). ``who_i``, ``who_j``: their :func:`_who`, a
    :func:`near_pair` (the callers test it first, before they make the samples: recorded
    participants, two on one path and two too far apart are not); ``samples_i``,
    ``samples_j``: their :func:`path_samples`, at least as far as :func:`sample_reach`."""
    _, _, xi, yi, vi, li, wi = who_i
    _, _, xj, yj, vj, lj, wj = who_j
    reach_i, reach_j = _reach(vi, li, horizon), _reach(vj, lj, horizon)
    past = np.hypot(xi - xj, yi - yj) + li + lj + margin
    size_ij, size_ji = (li, wi, lj, wj), (lj, wj, li, wi)
    u_i = first_conflict(samples_i, reach_i, samples_j, max(reach_j, past), size_ij, margin)
    if u_i == np.inf:
        return np.inf, np.inf
    u_j = first_conflict(samples_j, reach_j, samples_i, max(reach_i, past), size_ji, margin)
    if u_j == np.inf:
        return np.inf, np.inf
    # one behind the other, both heading the same way now (a follower, or a car about to
    # turn ahead of it): the leader search's, not a crossing
    if samples_i[0, 2] * samples_j[0, 2] + samples_i[0, 3] * samples_j[0, 3] >= CROSSING_COS and (
        first_conflict(samples_i, reach_i, samples_j, 0.0, size_ij, margin, SHALLOW) < np.inf
        or first_conflict(samples_j, reach_j, samples_i, 0.0, size_ji, margin, SHALLOW) < np.inf
    ):
        return np.inf, np.inf
    return u_i, u_j


@kernel
def _into_where_it_stands(who_a, who_b, samples_a, samples_b, margin, horizon) -> float:
    """How far [m] ``a`` moves (looking :func:`_reach` ahead) before it touches ``b`` where
    ``b`` stands now (:func:`first_conflict`; ``who``: :func:`_who`)."""
    la, wa, lb, wb = who_a[5], who_a[6], who_b[5], who_b[6]
    reach = _reach(who_a[4], la, horizon)
    return first_conflict(samples_a, reach, samples_b, 0.0, (la, wa, lb, wb), margin)


@kernel
def near_pair(who_i, who_j, margin, horizon) -> bool:
    """Whether :func:`pair_conflict` looks at two participants (:func:`_who`): both generated,
    on different paths, and near enough to meet within their reach."""
    path_i, rec_i, xi, yi, vi, li, wi = who_i
    path_j, rec_j, xj, yj, vj, lj, wj = who_j
    if rec_i or rec_j or path_i == path_j:
        return False
    reach = _reach(vi, li, horizon) + _reach(vj, lj, horizon)
    return np.hypot(xi - xj, yi - yj) <= reach + li + lj + margin


@kernel
def sample_reach(who, longest, horizon, margin) -> float:
    """How far [m] :func:`pair_conflict` may read a participant's (:func:`_who`)
    :func:`path_samples` when the others look at most ``longest`` [m] ahead (their
    :func:`_reach` plus twice their length): its own reach, or, as the other of a pair, past
    the one it meets."""
    v, length = who[4], who[5]
    return _reach(v, length, horizon) + longest + 2.0 * (length + margin)


@kernel
def _samples_of(state, paths, i, reach):
    """:func:`path_samples` of participant ``i`` (a fleet index)."""
    f = FleetState(*state)
    return path_samples(paths, f.path[i], f.s[i], f.d[i], (f.x[i], f.y[i], f.psi[i]), reach)


@kernel
def longest_reach(state, idx, horizon) -> float:
    """The longest :func:`_reach` plus twice the length [m] of participants ``idx``."""
    f = FleetState(*state)
    out = 0.0
    for i in idx:
        out = max(out, _reach(f.v[i], f.length[i], horizon) + 2.0 * f.length[i])
    return out


@kernel
def crossing_candidates(idx, pi, pj, state, paths, margin, horizon):
    """Leader candidates ``(a, b, gap, lead_v = 0)`` (``a``, ``b`` index ``idx``) of generated
    participants giving way to each other where their paths cross (:func:`pair_conflict`;
    merges and followers are :func:`cross_path`'s and :func:`same_path`'s), for the pairs
    ``(pi, pj)``. The one already in the other's way goes, else the first to get there (at
    its speed, at least 1 m/s; the first of the pair on a tie); the other stops short of
    where it would touch the other's path (gap [m]), unless it gets there more than
    :data:`SWEEP_BUFFER` after the first has cleared it. Each in the other's way already
    (where it was not seen in time): the one whose path runs into the other where it stands
    later (or not at all) goes, the other stands (gap 0). Where the waits close a circle
    (four cars at a crossroads, each with another on its right), the one of the circle
    nearest its crossing (in time) goes (:func:`_unblocked`)."""
    f = FleetState(*state)
    generated = 0
    for i in idx:
        generated += not f.geometric[i]
    if generated < 2:  # (a recorded scene: every pair replays its recording)
        return no_candidates()
    longest = longest_reach(state, idx, horizon)
    soonest = np.full(len(idx), np.inf)  # each one's time [s] to its nearest crossing
    none = np.empty((0, 9))
    samples = [none for _ in range(len(idx))]  # made when a near pair needs them
    n = len(pi)
    a, b, gap = np.empty(2 * n, np.int64), np.empty(2 * n, np.int64), np.empty(2 * n)
    held = np.zeros(2 * n, np.bool_)  # the one waited for stands in the waiting one's way
    m = 0
    for q in range(n):
        i, j = idx[pi[q]], idx[pj[q]]
        who_i, who_j = _who(state, i), _who(state, j)
        if not near_pair(who_i, who_j, margin, horizon):
            continue
        for p, who in ((pi[q], who_i), (pj[q], who_j)):
            if len(samples[p]) == 0:
                samples[p] = _samples_of(state, paths, idx[p],
                                         sample_reach(who, longest, horizon, margin))  # fmt: skip
        s_i, s_j = samples[pi[q]], samples[pj[q]]
        u_i, u_j = pair_conflict(who_i, who_j, s_i, s_j, margin, horizon)
        if u_j == np.inf:  # no crossing; one behind another that stands, on another path?
            for p, w_p, s_p, o, w_o, s_o in ((pi[q], who_i, s_i, pj[q], who_j, s_j),
                                             (pj[q], who_j, s_j, pi[q], who_i, s_i)):  # fmt: skip
                if w_o[4] < STANDING_SPEED:
                    u = _into_where_it_stands(w_p, w_o, s_p, s_o, margin, horizon)
                    if u < np.inf:
                        a[m], b[m], gap[m], held[m] = p, o, u, True
                        m += 1
            continue
        vi, vj = max(f.v[i], 1.0), max(f.v[j], 1.0)
        soonest[pi[q]] = min(soonest[pi[q]], max(u_i, 0.0) / vi)
        soonest[pj[q]] = min(soonest[pj[q]], max(u_j, 0.0) / vj)
        if u_i <= 0 and u_j <= 0:  # the one that runs into the other later goes
            here_i = _into_where_it_stands(who_i, who_j, s_i, s_j, margin, horizon)
            here_j = _into_where_it_stands(who_j, who_i, s_j, s_i, margin, horizon)
            a[m], b[m], gap[m] = (pj[q], pi[q], 0.0) if here_i >= here_j else (pi[q], pj[q], 0.0)
            held[m] = True
            m += 1
            continue
        if _first_goes(u_i, u_j, vi, vj):  # i goes, j waits
            u_go, v_go, u_wait, v_wait, a[m], b[m] = u_i, vi, u_j, vj, pj[q], pi[q]
        else:
            u_go, v_go, u_wait, v_wait, a[m], b[m] = u_j, vj, u_i, vi, pi[q], pj[q]
        cleared = (max(u_go, 0.0) + f.length[i] + f.length[j] + 2 * margin) / v_go
        if u_wait / v_wait <= cleared + SWEEP_BUFFER:
            gap[m], held[m] = u_wait, u_go <= 0
            m += 1
    keep = _unblocked(a[:m], b[:m], soonest, held[:m])
    return a[:m][keep], b[:m][keep], gap[:m][keep], np.zeros(int(keep.sum()))


@kernel
def _first_goes(u_i, u_j, v_i, v_j) -> bool:
    """Whether of two participants meeting ``u_i`` and ``u_j`` [m] ahead (:func:`pair_conflict`)
    at speeds ``v_i``, ``v_j`` [m/s] (at least 1 m/s) the first goes and the second waits: the
    one already in the other's way goes, else the first to get there (the first on a tie)."""
    return u_i <= 0 or (u_j > 0 and u_i / v_i <= u_j / v_j)


@kernel
def _unblocked(wait, go, soonest, held):
    """Which of the waits ``wait[e]`` -> ``go[e]`` (positions of participants) to keep so that
    none closes a circle: while some do, the participant of a circle with the lowest
    ``soonest`` [s] (the first of those) stops waiting, of those whose waits are not
    ``held`` (the one waited for standing in its way already) if the circle has any."""
    n, m = len(soonest), len(wait)
    keep = np.ones(m, np.bool_)
    while True:
        free = np.zeros(n, np.bool_)  # waits for no one who is not free: it will move
        changed = True
        while changed:
            changed = False
            for node in range(n):
                if free[node]:
                    continue
                stuck = False
                for e in range(m):
                    if keep[e] and wait[e] == node and not free[go[e]]:
                        stuck = True
                        break
                if not stuck:
                    free[node] = changed = True
        if free.all():
            return keep
        # walk the waits from one that is not free until a participant comes again
        order = np.full(n, -1, np.int64)
        node, k = np.flatnonzero(~free)[0], 0
        while order[node] < 0:
            order[node], k = k, k + 1
            for e in range(m):
                if keep[e] and wait[e] == node and not free[go[e]]:
                    node = go[e]
                    break
        first = node  # on the circle: those visited from its first visit on
        free_way = np.ones(n, np.bool_)  # no one stands in its way
        for e in range(m):
            if keep[e] and held[e]:
                free_way[wait[e]] = False
        best, best_free = first, free_way[first]
        for other in range(n):
            if order[other] >= order[first] and (
                (free_way[other] and not best_free)
                or (free_way[other] == best_free and soonest[other] < soonest[best])
            ):
                best, best_free = other, free_way[other]
        for e in range(m):
            if wait[e] == best:
                keep[e] = False


@kernel
def blocked(state, paths, i, margin, horizon, decel) -> bool:
    """Whether generated participant ``i`` and another active one would meet with the one
    that must give way unable to stop short braking at ``decel`` [m/s^2]: where their paths
    cross or merge (:func:`pair_conflict`; who waits: :func:`_first_goes`), or where one runs
    into the other where it stands (one close behind the other on another path): a spawn to
    refuse (one of them would drive into the other). Each looks at least as far ahead as it
    needs to stop (the ``horizon`` [s] made longer where a car is faster than ``2 * decel *
    horizon``)."""
    f = FleetState(*state)
    active = np.flatnonzero(f.active)
    fastest = 0.0
    for j in active:
        fastest = max(fastest, f.v[j])
    horizon = max(horizon, fastest / (2 * decel))  # then v * horizon >= v^2 / (2 decel)
    longest = longest_reach(state, active, horizon)
    who_i = _who(state, i)
    own = _samples_of(state, paths, i, sample_reach(who_i, longest, horizon, margin))
    for j in range(len(f.active)):
        who_j = _who(state, j)
        if j == i or not f.active[j] or not near_pair(who_i, who_j, margin, horizon):
            continue
        other = _samples_of(state, paths, j, sample_reach(who_j, longest, horizon, margin))
        stop_i, stop_j = f.v[i] ** 2 / (2 * decel), f.v[j] ** 2 / (2 * decel)
        u_i, u_j = pair_conflict(who_i, who_j, own, other, margin, horizon)
        if u_j < np.inf:
            if _first_goes(u_i, u_j, max(f.v[i], 1.0), max(f.v[j], 1.0)):
                if u_j <= stop_j:
                    return True
            elif u_i <= stop_i:
                return True
        into_j = _into_where_it_stands(who_i, who_j, own, other, margin, horizon)
        into_i = _into_where_it_stands(who_j, who_i, other, own, margin, horizon)
        if into_j <= stop_i or into_i <= stop_j:
            return True
    return False


@kernel
def ego_ahead(idx, fleet, c, sn, ego, paths, lookahead, margin, crossing_horizon):
    """Candidates ``(a, b = -2, gap, lead_v)`` of participants that have the ego ahead on
    their path. ``fleet``: the arrays ``(x, y, s, d, path, length, width, v, geometric)``;
    ``c``, ``sn``: the participants' heading cosines and sines; ``ego``: ``(x, y, v, length,
    width, cos psi, sin psi)``; ``paths``: :meth:`PathBank.kernel_data`. An ego heading the
    same way is a leader wherever it is on the path. For synthetic participants (not
    replaying a recorded track's exact pose) so is an ego crossing the path or coming the
    other way (its footprint taken across the path), within ``crossing_horizon`` [s] at the
    participant's speed (at least 1 m/s) and only if it would not have cleared the path by
    the time the participant got there; and, failing that, an ego that will pass through the
    participant's path ahead within ``crossing_horizon`` (:func:`swept_conflict`: a car
    about to turn across the ego's lane waits before the lane): generated traffic does not
    drive into the ego. An ego at less than 90 degrees to the participant's heading takes the
    same-direction branch, and never the sweep."""
    x, y, s, d, path_id, length, width, v, recorded = fleet
    ex, ey, ev, e_len, e_wid, e_c, e_s = ego
    m = len(idx)
    near = np.empty(m, np.int64)
    lon, dot, cross, crossing_gap = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    n = 0
    for q in range(m):  # candidates, before any path look-up
        i = idx[q]
        dx, dy = ex - x[i], ey - y[i]
        lon[q] = dx * c[q] + dy * sn[q]
        if lon[q] > 0 and np.hypot(dx, dy) <= lookahead:
            dot[q] = c[q] * e_c + sn[q] * e_s
            if dot[q] > 0:
                near[n] = q
                n += 1
            elif not recorded[i]:
                cross[q] = abs(c[q] * e_s - sn[q] * e_c)
                crossing_gap[q] = lon[q] - 0.5 * (length[i] + e_len * -dot[q] + e_wid * cross[q])
                swept = (max(v[i], 1.0) + max(ev, 0.0)) * crossing_horizon
                if crossing_gap[q] < swept + e_len + width[i] + 2.0 * margin:
                    near[n] = q
                    n += 1
    buckets = n > SMALL_QUERY
    a, gap, lead_v = np.empty(n, np.int64), np.empty(n), np.empty(n)
    k = 0
    for q in near[:n]:
        i = idx[q]
        px, py, h = frenet_one(paths, path_id[i], s[i] + lon[q], d[i], buckets)
        off = np.hypot(ex - px, ey - py)
        if dot[q] > 0:
            if off < 0.5 * (width[i] + e_wid) + margin:
                a[k], gap[k] = q, lon[q] - 0.5 * (length[i] + e_len)
                lead_v[k] = ev * dot[q]
                k += 1
            continue
        g = crossing_gap[q]
        reach = 0.5 * (width[i] + e_len * cross[q] + e_wid * -dot[q]) + margin
        if g < max(v[i], 1.0) * crossing_horizon and off < reach:
            # only if the ego is still across the path when the participant gets there
            nx, ny = -np.sin(h), np.cos(h)  # the path's left normal
            side = (ex - px) * nx + (ey - py) * ny
            drift = ev * (e_c * nx + e_s * ny)  # the ego's speed across the path
            clear = np.inf
            if abs(drift) > 1e-9:
                clear = (reach - side * np.sign(drift)) / abs(drift)
            if clear * max(v[i], 1e-9) > g:
                a[k], gap[k] = q, g
                lead_v[k] = ev * dot[q]
                k += 1
                continue
        g = swept_conflict(paths, path_id[i], s[i], d[i], length[i], width[i], v[i], ego,
                           margin, crossing_horizon, buckets)  # fmt: skip
        if g < np.inf:
            a[k], gap[k], lead_v[k] = q, g, 0.0
            k += 1
    return a[:k], np.full(k, -2, np.int64), gap[:k], lead_v[:k]


@kernel
def nearest_leaders(idx, a, b, gap, lead_v, gap_out, leader_out, lead_v_out) -> None:
    """For each follower ``a`` (index into ``idx``) keep its candidate with the smallest
    gap (the first of equal ones, NaN last, as a stable sort would), and write gap, leader
    (fleet index, ``-2`` for the ego) and leader speed at its fleet index."""
    best = np.full(len(idx), -1, np.int64)
    for q in range(len(a)):
        p = best[a[q]]
        if p < 0 or gap[q] < gap[p] or (gap[p] != gap[p] and gap[q] == gap[q]):
            best[a[q]] = q
    for f in range(len(idx)):
        q = best[f]
        if q >= 0:
            i = idx[f]
            gap_out[i], lead_v_out[i] = gap[q], lead_v[q]
            leader_out[i] = idx[b[q]] if b[q] >= 0 else -2


@kernel
def poses(idx, path, s, d, paths, x, y, psi) -> None:
    """World pose of participants ``idx`` from their path coordinates: ``x, y`` [m] at
    ``(s, d)`` on their path and the path heading [rad] (:func:`frenet_one`)."""
    buckets = len(idx) > SMALL_QUERY
    for i in idx:
        x[i], y[i], psi[i] = frenet_one(paths, path[i], s[i], d[i], buckets)


@kernel
def update_poses(idx, state, paths, profiles) -> None:
    """:func:`poses` of participants ``idx``; recorded (``geometric``) ones keep the heading
    [rad] of their profile at their profile time, in IDM mode too (the tangent of a recorded
    path is noise where the vehicle stood still)."""
    f = FleetState(*state)
    poses(idx, f.path, f.s, f.d, paths, f.x, f.y, f.psi)
    geo = idx[f.geometric[idx]]
    if len(geo):
        vals = np.empty((len(geo), profiles[1].shape[1]))
        lookup(*profiles, f.profile[geo], f.tau[geo], True, len(geo) > SMALL_QUERY, vals)
        for q in range(len(geo)):
            f.psi[geo[q]] = vals[q, _H]


@kernel
def deactivate(idx, state) -> None:
    """Take participants ``idx`` out of the fleet (no gap, no leader)."""
    f = FleetState(*state)
    for i in idx:
        f.active[i], f.gap[i], f.leader[i] = False, np.inf, -1


@kernel
def leave_window(state, x0, y0, ux, uy, lo, hi) -> None:
    """Deactivate the participants whose distance [m] from ``(x0, y0)`` along the unit
    vector ``(ux, uy)`` is outside ``[lo, hi]``."""
    f = FleetState(*state)
    for i in range(len(f.active)):
        if f.active[i]:
            lon = (f.x[i] - x0) * ux + (f.y[i] - y0) * uy
            if lon < lo or lon > hi:
                f.active[i], f.gap[i], f.leader[i] = False, np.inf, -1


@kernel
def occupied(state, ego, x, y, heading, length, width, along, side) -> bool:
    """Whether an active participant or the ego (``(x, y, length, width)``) overlaps a
    ``length`` x ``width`` box at ``(x, y)`` with ``heading`` [rad], each box grown by
    ``along`` [m] ahead and behind and ``side`` [m] to each side."""
    f = FleetState(*state)
    c, sn = np.cos(heading), np.sin(heading)
    for i in range(len(f.active) + 1):
        if i < len(f.active):
            if not f.active[i]:
                continue
            xi, yi, li, wi = f.x[i], f.y[i], f.length[i], f.width[i]
        else:
            xi, yi, li, wi = ego
        lon = (xi - x) * c + (yi - y) * sn
        lat = -(xi - x) * sn + (yi - y) * c
        if abs(lon) < 0.5 * (li + length) + along and abs(lat) < 0.5 * (wi + width) + side:
            return True
    return False


@kernel
def leaders(state, ego, cross, paths, lookahead, margin, crossing_horizon):
    """Set ``gap`` [m], ``leader`` and ``lead_v`` [m/s] of every participant (see
    :meth:`Fleet.find_leaders`) and return the active indices. ``ego``: ``(present, x, y, v,
    length, width, cos psi, sin psi)``; ``cross``: candidates ``(a, b, gap, lead_v)`` on
    other paths (``a``, ``b`` index the active participants), which rank after the one on
    the same path and before the ego's when gaps are equal."""
    f = FleetState(*state)
    f.gap[:] = np.inf
    f.leader[:] = -1
    f.lead_v[:] = 0.0
    idx = np.flatnonzero(f.active)
    if len(idx) == 0:
        return idx
    a, b, g, lv = same_path(idx, f.path, f.s, f.length, f.v, f.psi, lookahead)
    if ego[0]:
        c, sn = np.cos(f.psi[idx]), np.sin(f.psi[idx])
        fleet = (f.x, f.y, f.s, f.d, f.path, f.length, f.width, f.v, f.geometric)
        ea, eb, eg, elv = ego_ahead(idx, fleet, c, sn, ego[1:], paths, lookahead, margin,
                                    crossing_horizon)  # fmt: skip
    else:
        ea, eb, eg, elv = cross[0][:0], cross[1][:0], cross[2][:0], cross[3][:0]
    nearest_leaders(idx, np.concatenate((a, cross[0], ea)), np.concatenate((b, cross[1], eb)),
                    np.concatenate((g, cross[2], eg)), np.concatenate((lv, cross[3], elv)),
                    f.gap, f.leader, f.lead_v)  # fmt: skip
    return idx


@kernel
def tick(state, ego, cross, paths, profiles, leader_params, limits, idm, dt, decay, window):
    """Advance the fleet by ``dt`` [s]: :func:`leaders` (``leader_params``: ``(lookahead,
    lateral_margin, crossing_horizon)``), then :func:`advance` with the profile values at
    ``tau`` and ``tau + dt``, then the poses. Recorded participants whose profile ran out are
    deactivated, and, if there is an ego, those outside ``window = (lo, hi)`` [m] along its
    heading (:func:`leave_window`). Returns the indices of all participants whose profile
    ran out."""
    f = FleetState(*state)
    idx = leaders(state, ego, cross, paths, *leader_params)
    n = len(idx)
    if n == 0:
        return idx
    prof, tau = f.profile[idx], f.tau[idx]
    buckets = 2 * n > SMALL_QUERY  # as one query of both times
    now, nxt = np.empty((n, 4)), np.empty((n, 4))
    lookup(*profiles, prof, tau, True, buckets, now)
    lookup(*profiles, prof, tau + dt, True, buckets, nxt)
    fleet = (f.s, f.v, f.tau, f.d, f.d_bias, f.k, f.mode, f.geometric, f.gap)
    advance(idx, now, nxt, fleet, f.lead_v, limits, idm, dt, decay)
    update_poses(idx, state, paths, profiles)
    hi = profiles[0][5]
    ended = idx[f.tau[idx] > hi[prof] + 1e-9]
    deactivate(ended[f.geometric[ended]], state)
    if ego[0]:
        leave_window(state, ego[1], ego[2], ego[6], ego[7], window[0], window[1])
    return ended
