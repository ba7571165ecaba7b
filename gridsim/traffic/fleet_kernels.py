"""Compiled parts of :meth:`gridsim.traffic.fleet.Fleet.tick`: the per-vehicle update and the
leader candidates on the same path and behind the ego, and the choice among candidates.

One loop over the active participants replaces dozens of small array operations. Every
expression is the scalar form of the NumPy one it replaces, in the same order (the IDM is
the same source, :mod:`gridsim.vehicle.idm`), so the results are the same bits.
"""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel
from gridsim.traffic.table_kernels import SMALL_QUERY, frenet_one
from gridsim.vehicle.idm import idm_accel, idm_gap

REPLAY, IDM = 0, 1
_S, _V, _D = 0, 1, 2


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
        if m == REPLAY and g < idm_gap(v, dv, *idm):
            m = IDM
        elif (
            m == IDM
            and g > resume_factor * idm_gap(v_rep, v_rep - lv, *idm)
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
def ego_ahead(idx, fleet, c, sn, ego, paths, lookahead, margin, crossing_horizon):
    """Candidates ``(a, b = -2, gap, lead_v)`` of participants that have the ego ahead on
    their path. ``fleet``: the arrays ``(x, y, s, d, path, length, width, v, geometric)``;
    ``c``, ``sn``: the participants' heading cosines and sines; ``ego``: ``(x, y, v, length,
    width, cos psi, sin psi)``; ``paths``: :meth:`PathBank.kernel_data`. An ego heading the
    same way is a leader wherever it is on the path. For synthetic participants (not
    replaying a recorded track's exact pose) so is an ego crossing the path or coming the
    other way (its footprint taken across the path), within ``crossing_horizon`` [s] at the
    participant's speed (at least 1 m/s) and only if it would not have cleared the path by
    the time the participant got there: generated traffic does not drive into the ego."""
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
                if crossing_gap[q] < max(v[i], 1.0) * crossing_horizon:
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
        if off < reach:
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
