"""Compiled sampling of a :class:`~gridsim.traffic.profiles.ProfileChain`: the same
operations, in the same order, as the NumPy scalar code it replaced (``np.interp`` and
``math.exp`` give the same bits compiled; ``tests/test_golden.py`` replays the references)."""

from __future__ import annotations

import math

import numpy as np

from gridsim.jit import jitable, kernel


@kernel
def chain_samples(out, m0, m1, profile, state, limits) -> tuple[int, float]:
    """Fill samples ``m0:m1`` of ``out = (times, speeds, offsets)`` from one profile
    ``(t, v, d)`` [s, m/s, m] scaled by ``k``, started at time ``start`` [s], with the offset
    bias ``d_bias`` [m] decaying over 2 s; ``state = (k, start, d_bias, v_prev)``,
    ``limits = (v_min, v_max, a_max, dt)``. Stops at the first sample past the profile's end.
    Returns that sample's index (``m1`` if none) and the last speed [m/s]."""
    times, speeds, offsets = out
    t_prof, v_prof, d_prof = profile
    k, start, d_bias, v_prev = state
    v_min, v_max, a_max, dt = limits
    for m in range(m0, m1):
        tau = times[m] - start
        if tau > t_prof[-1]:
            return m, v_prev
        v = min(max(k * np.interp(tau, t_prof, v_prof), v_min), v_max)
        v_prev = min(max(v, v_prev - a_max * dt), v_prev + a_max * dt)
        speeds[m] = v_prev
        offsets[m] = np.interp(tau, t_prof, d_prof) + d_bias * math.exp(-tau / 2.0)
    return m1, v_prev


@kernel
def chain_at(t, times, speeds, offsets, n) -> tuple[float, float]:
    """Speed [m/s] and offset [m] at time ``t`` [s], ``np.interp`` over the first ``n``
    samples (compiled, the same bits as NumPy's: ``tests/test_gridsim/envs/test_reference.py``)."""
    return np.interp(t, times[:n], speeds[:n]), np.interp(t, times[:n], offsets[:n])


@jitable
def start_scale(v_now, v0, v_lo, v_hi, v_min, v_max) -> float:
    """The speed scale that starts a profile (first speed ``v0``, speeds within ``[v_lo,
    v_hi]`` [m/s]) at about ``v_now`` [m/s], clipped to keep it within ``[v_min, v_max]``
    (when both bounds cannot hold, the upper one wins: ``HumanProfiles.scale_range``)."""
    hi = v_max / v_hi
    lo = min(v_min / v_lo, hi)
    return float(min(max(v_now / max(v0, 0.1), lo), hi))  # np.clip's bits


@kernel
def continue_profiles(ended, draws, firsts, bounds, fleet) -> None:
    """Participants ``ended`` (in order) continue with the profiles ``draws`` (one random
    profile index each), scaled to start at their speed, their lateral offset kept:
    ``HumanProfiles.continue_from`` for each. ``firsts``: per profile ``(v0, d0, v_lo,
    v_hi)`` (first speed and offset, speed range); ``bounds``: ``(v_min, v_max)`` [m/s];
    ``fleet``: the fleet's ``(profile, tau, k, d_bias, v, d)`` arrays, written in place."""
    v0, d0, v_lo, v_hi = firsts
    profile, tau, k, d_bias, v, d = fleet
    for q in range(len(ended)):
        i, p = ended[q], draws[q]
        profile[i], tau[i] = p, 0.0
        k[i] = start_scale(v[i], v0[p], v_lo[p], v_hi[p], bounds[0], bounds[1])
        d_bias[i] = d[i] - d0[p]
