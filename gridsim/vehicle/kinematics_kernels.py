"""The bicycle model's one integration (:mod:`gridsim.vehicle.kinematics`): :func:`step_one`
steps one vehicle on floats, in Python (one ego per tick) or compiled inside the world's and
the shadow world's kernels, and :func:`step_many` steps many vehicles in one compiled call
(the batched :func:`~gridsim.vehicle.kinematics.step_bicycle`). Both are the same operations
in the same order as the NumPy code they replaced (``math`` and NumPy share libm), hence the
same bits; NaN inputs give NaN as NumPy's ``minimum`` and ``maximum`` did."""

from __future__ import annotations

import math

import numpy as np

from gridsim.jit import jitable, kernel


@jitable
def step_one(x0, y0, psi0, v0, d0, accel, steer_rate, limits, dt):
    """One vehicle's step on floats: the new ``(x, y, psi, v, delta)`` and the applied
    acceleration [m/s^2] and steering rate [rad/s]. ``limits``: ``(wheelbase, v_min, v_max,
    a_max, b_max, delta_max, v_delta_max, v_switch)`` of
    :class:`~gridsim.vehicle.kinematics.BicycleParams`."""
    wheelbase, v_min, v_max, a_max, b_max, delta_max, v_delta_max, v_switch = limits
    vd_lo = max(-v_delta_max, (-delta_max - d0) / dt)
    vd_hi = min(v_delta_max, (delta_max - d0) / dt)
    vd = float(min(max(steer_rate, vd_lo), vd_hi))
    a = float(min(max(accel, -b_max), a_max))
    v1 = v0 + a * dt
    vh = v0 + (0.5 * dt) * a
    if math.isfinite(v_switch):
        c = a_max * v_switch
        if v0 > v_switch and a * v0 >= c:
            v1 = math.sqrt(v0 * v0 + 2.0 * c * dt)
            vh = math.sqrt(v0 * v0 + c * dt)
    v1_clipped = float(min(max(v1, v_min), v_max))
    if v1_clipped != v1:
        vh = 0.5 * (v0 + v1_clipped)
        v1 = v1_clipped
    ddt = vd * dt
    inv_l = 1.0 / wheelbase
    w0 = v0 * math.tan(d0) * inv_l
    wh = vh * math.tan(d0 + 0.5 * ddt) * inv_l
    w1 = v1 * math.tan(d0 + ddt) * inv_l
    psih = psi0 + dt / 24.0 * (5.0 * w0 + 8.0 * wh - w1)
    psi1 = psi0 + dt / 6.0 * (w0 + 4.0 * wh + w1)
    x1 = x0 + dt / 6.0 * (v0 * math.cos(psi0) + 4.0 * vh * math.cos(psih) + v1 * math.cos(psi1))
    y1 = y0 + dt / 6.0 * (v0 * math.sin(psi0) + 4.0 * vh * math.sin(psih) + v1 * math.sin(psi1))
    return x1, y1, psi1, v1, d0 + ddt, (v1 - v0) / dt, vd


@kernel
def step_many(states, accel, steer_rate, limits, dt):
    """:func:`step_one` for each row: ``states`` ``(N, 5)``, ``accel`` and ``steer_rate``
    ``(N,)``, ``limits`` ``(N, 8)`` (:func:`step_one`'s, one row per vehicle). Returns the new
    states ``(N, 5)`` and the applied accelerations and steering rates ``(N,)``."""
    n = states.shape[0]
    out = np.empty((n, 5))
    applied = np.empty(n)
    rates = np.empty(n)
    for i in range(n):
        lim = limits[i]
        x, y, psi, v, delta, applied[i], rates[i] = step_one(
            states[i, 0],
            states[i, 1],
            states[i, 2],
            states[i, 3],
            states[i, 4],
            accel[i],
            steer_rate[i],
            (lim[0], lim[1], lim[2], lim[3], lim[4], lim[5], lim[6], lim[7]),
            dt,
        )
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = x, y, psi, v, delta
    return out, applied, rates
