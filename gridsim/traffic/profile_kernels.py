"""Compiled sampling of a :class:`~gridsim.traffic.profiles.ProfileChain`: the same
operations, in the same order, as the NumPy scalar code it replaced (``np.interp`` and
``math.exp`` give the same bits compiled; ``tests/test_golden.py`` replays the references)."""

from __future__ import annotations

import math

import numpy as np

from gridsim.jit import kernel


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
    samples (compiled, the same bits as NumPy's: ``tests/test_reference.py``)."""
    return np.interp(t, times[:n], speeds[:n]), np.interp(t, times[:n], offsets[:n])
