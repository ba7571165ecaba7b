"""Kinematic set-point curves from the ego's state alone (no grid): the *destination curve*.

The destination curve is the floor a learned planner that is told its destination must beat,
and the prior the network can refine (``NetConfig.prior = "destination_curve"``). From the
ego's speed and heading it drives a circular arc that leaves the rear axle tangent to the
heading and passes through the destination (then straight on), at the constant acceleration
that covers the arc's length by the destination time (the end of the horizon, or the goal time
beyond it: the set-points are then where the car is on the way). The curve is
kinematically feasible: the curvature is at most the vehicle's ``tan(delta_max) / wheelbase``
(a destination inside that turning circle is approached by turning at the limit until the
closest point to it, then straight on), the acceleration within ``[-b_max, a_max]`` and the
speed within ``[0, v_max]`` (the car never reverses: a destination that is not ahead of the
rear axle means "stop").

Computed one sample at a time in Python floats: a sample's set-points do not depend on which
other samples share its batch (training requires it of every part of the forward pass).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CurveLimits:
    """The ego's limits the curve respects: accelerations [m/s^2], speed [m/s], curvature
    [1/m]."""

    a_max: float = 2.0
    b_max: float = 6.0
    v_max: float = 40.0
    max_curvature: float = math.tan(0.6) / 2.7

    @classmethod
    def from_params(cls, params) -> CurveLimits:
        """From :class:`~gridsim.vehicle.kinematics.BicycleParams` (scalar fields)."""
        return cls(
            a_max=float(params.a_max),
            b_max=float(params.b_max),
            v_max=float(params.v_max),
            max_curvature=math.tan(float(params.delta_max)) / float(params.wheelbase),
        )


def _distance(v: float, a: float, t: float, v_max: float) -> float:
    """Distance [m] covered in ``t`` [s] from speed ``v`` at acceleration ``a``, the speed
    held in ``[0, v_max]``."""
    if a < 0.0 and v + a * t < 0.0:  # stops on the way
        return v * v / (-2.0 * a)
    if a > 0.0 and v + a * t > v_max:  # reaches v_max on the way
        t_sw = max(v_max - v, 0.0) / a
        return v * t_sw + 0.5 * a * t_sw * t_sw + v_max * (t - t_sw)
    return v * t + 0.5 * a * t * t


def _on_path(curvature: float, turn: float, d: float) -> tuple[float, float]:
    """Position [m, body frame] after distance ``d`` on a path that leaves the origin along
    +x on a circle of ``curvature`` for ``turn`` metres, then goes straight on."""
    along = min(d, turn)
    theta = curvature * along
    if abs(theta) < 1e-9:
        x, y = along, 0.5 * along * theta
    else:
        x, y = math.sin(theta) / curvature, (1.0 - math.cos(theta)) / curvature
    rest = d - along
    return x + rest * math.cos(theta), y + rest * math.sin(theta)


def curve_to(
    speed: float,
    cos_h: float,
    sin_h: float,
    dest: tuple[float, float],
    times: np.ndarray,
    limits: CurveLimits,
    arrive: float | None = None,
) -> np.ndarray:
    """Set-points ``(T, 2)`` [m, grid frame] at ``times`` [s] for an ego at the grid origin
    with ``speed`` [m/s] and heading (``cos_h``, ``sin_h``) in the grid frame, heading for
    ``dest`` (x, y) [m, grid frame] to arrive at time ``arrive`` [s] (default: the last
    set-point's time)."""
    dx, dy = float(dest[0]), float(dest[1])
    fwd, left = cos_h * dx + sin_h * dy, -sin_h * dx + cos_h * dy
    horizon = float(times[-1]) if arrive is None else float(arrive)
    v = min(max(float(speed), 0.0), limits.v_max)
    curvature = length = 0.0
    if fwd > 0.0:  # else not ahead: stop
        r2 = fwd * fwd + left * left
        curvature = 2.0 * left / r2  # of the arc through dest
        ratio = left / fwd
        length = r2 / fwd * (math.atan(ratio) / ratio if abs(ratio) > 1e-12 else 1.0)
        k = limits.max_curvature
        if abs(curvature) > k:  # dest inside the turning circle: turn to the closest point
            radius = 1.0 / k
            length = radius * math.atan2(fwd, radius - abs(left))
            curvature = math.copysign(k, left)
    accel = 2.0 * (length - v * horizon) / (horizon * horizon)
    accel = min(max(accel, -limits.b_max), limits.a_max)
    out = np.empty((len(times), 2), np.float32)
    for i, t in enumerate(times):
        x, y = _on_path(curvature, length, _distance(v, accel, float(t), limits.v_max))
        out[i] = (cos_h * x - sin_h * y, sin_h * x + cos_h * y)
    return out


def destination_curves(
    ego: np.ndarray,
    dest: np.ndarray,
    times: np.ndarray,
    limits: CurveLimits,
    arrive: float | None = None,
) -> np.ndarray:
    """:func:`curve_to` for a batch: ``ego`` ``(N, 6)`` (GridSim-v0's ego features: speed
    first, cos / sin of the heading last), ``dest`` ``(N, 2)`` [m] reached at ``arrive`` [s]
    (default: the last of ``times``) -> ``(N, T, 2)`` float32."""
    ego = np.asarray(ego, np.float64).reshape(-1, ego.shape[-1])
    dest = np.asarray(dest, np.float64).reshape(-1, 2)
    out = np.empty((len(ego), len(times), 2), np.float32)
    for n in range(len(ego)):
        out[n] = curve_to(ego[n, 0], ego[n, 4], ego[n, 5], dest[n], times, limits, arrive)
    return out
