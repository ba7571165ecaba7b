"""Compiled per-vehicle update of :meth:`gridsim.traffic.fleet.Fleet.tick`.

One loop over the active participants replaces some 60 small array operations. Every
expression is the scalar form of the NumPy one it replaces, in the same order (the IDM is
the same source, :mod:`gridsim.vehicle.idm`), so the results are the same bits.
"""

from __future__ import annotations

from gridsim.jit import kernel
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
