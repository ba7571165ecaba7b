"""The destination curve's arithmetic (:mod:`neurotrajectory.curves`): :func:`curve_into` computes
one curve on floats, in Python (``curve_to``) or compiled, and :func:`curves_many` a batch in
one compiled call (the network's prior and the destination-curve baseline take one per
environment and decision). Both are the same operations in the same order (``math`` and
numba's ``math`` both call libm), hence the same bits; ``min`` and ``max`` are written out as
Python's (the first argument wins ties and NaN comparisons).

Units: speeds [m/s], accelerations [m/s^2], curvature [1/m], positions [m] in the frame of the
heading ``(cos_h, sin_h)`` given (the grid frame), times [s].
"""

from __future__ import annotations

import math

from gridsim.jit import jitable, kernel


@jitable
def _lower(a, b):
    """Python's ``min(a, b)``."""
    return b if b < a else a


@jitable
def _upper(a, b):
    """Python's ``max(a, b)``."""
    return b if b > a else a


@jitable
def _distance(v, a, t, v_max):
    """Distance [m] covered in ``t`` [s] from speed ``v`` at acceleration ``a``, the speed
    held in ``[0, v_max]``."""
    if a < 0.0 and v + a * t < 0.0:  # stops on the way
        return v * v / (-2.0 * a)
    if a > 0.0 and v + a * t > v_max:  # reaches v_max on the way
        t_sw = _upper(v_max - v, 0.0) / a
        return v * t_sw + 0.5 * a * t_sw * t_sw + v_max * (t - t_sw)
    return v * t + 0.5 * a * t * t


@jitable
def _on_path(curvature, turn, d):
    """Position [m, body frame] after distance ``d`` on a path that leaves the origin along
    +x on a circle of ``curvature`` for ``turn`` metres, then goes straight on."""
    along = _lower(d, turn)
    theta = curvature * along
    if abs(theta) < 1e-9:
        x, y = along, 0.5 * along * theta
    else:
        x, y = math.sin(theta) / curvature, (1.0 - math.cos(theta)) / curvature
    rest = d - along
    return x + rest * math.cos(theta), y + rest * math.sin(theta)


@jitable
def curve_into(out, speed, cos_h, sin_h, dx, dy, times, horizon, limits) -> None:
    """The destination curve's set-points at ``times`` [s] into ``out`` ``(T, 2)``, for an ego
    at the origin with ``speed`` and heading (``cos_h``, ``sin_h``), heading for ``(dx, dy)``
    to arrive at ``horizon`` [s]; ``limits``: ``(a_max, b_max, v_max, max_curvature)``."""
    a_max, b_max, v_max, max_curvature = limits
    fwd, left = cos_h * dx + sin_h * dy, -sin_h * dx + cos_h * dy
    v = _lower(_upper(speed, 0.0), v_max)
    curvature = 0.0
    length = 0.0
    if fwd > 0.0:  # else not ahead: stop
        r2 = fwd * fwd + left * left
        curvature = 2.0 * left / r2  # of the arc through dest
        ratio = left / fwd
        length = r2 / fwd * (math.atan(ratio) / ratio if abs(ratio) > 1e-12 else 1.0)
        if abs(curvature) > max_curvature:  # inside the turning circle: to the closest point
            radius = 1.0 / max_curvature
            length = radius * math.atan2(fwd, radius - abs(left))
            curvature = math.copysign(max_curvature, left)
    accel = 2.0 * (length - v * horizon) / (horizon * horizon)
    accel = _lower(_upper(accel, -b_max), a_max)
    for i in range(len(times)):
        x, y = _on_path(curvature, length, _distance(v, accel, float(times[i]), v_max))
        out[i, 0] = cos_h * x - sin_h * y
        out[i, 1] = sin_h * x + cos_h * y


@kernel
def curves_many(speed, cos_h, sin_h, dest, times, horizon, limits, out) -> None:
    """:func:`curve_into` for every row: ``speed``, ``cos_h``, ``sin_h`` ``(N,)`` float64,
    ``dest`` ``(N, 2)`` float64, ``times`` ``(T,)`` float64 -> ``out`` ``(N, T, 2)``."""
    for n in range(len(speed)):
        curve_into(out[n], speed[n], cos_h[n], sin_h[n], dest[n, 0], dest[n, 1], times, horizon,
                   limits)  # fmt: skip
