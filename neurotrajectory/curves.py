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

Computed one sample at a time on floats (:mod:`gridsim.vehicle.curve_kernels`, compiled for a
batch): a sample's set-points do not depend on which other samples share its batch (training
requires it of every part of the forward pass).
"""

from __future__ import annotations

import math
from dataclasses import astuple, dataclass

import numpy as np

from gridsim.vehicle.curve_kernels import curve_into, curves_many


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


def _horizon(times: np.ndarray, arrive: float | None) -> float:
    """When the curve arrives [s]: ``arrive``, or the last of ``times`` (1-D, not empty)."""
    if times.ndim != 1 or not len(times):
        raise ValueError(f"times must be a 1-D array of set-point times, got shape {times.shape}")
    horizon = float(times[-1]) if arrive is None else float(arrive)
    if not horizon > 0:
        raise ValueError(f"the arrival time must be > 0 s, got {horizon}")
    return horizon


def _floats(limits: CurveLimits) -> tuple[float, float, float, float]:
    return tuple(float(x) for x in astuple(limits))


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
    set-point's time). Computed in float64 whatever the inputs' type."""
    horizon = _horizon(np.asarray(times), arrive)
    out = np.empty((len(times), 2), np.float32)
    curve_into(out, float(speed), float(cos_h), float(sin_h), float(dest[0]), float(dest[1]),
               times, horizon, _floats(limits))  # fmt: skip
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
    ego = np.asarray(ego, np.float64).reshape(-1, np.shape(ego)[-1])
    dest = np.ascontiguousarray(np.asarray(dest, np.float64).reshape(-1, 2))
    times = np.asarray(times, np.float64)  # float32 times are exact in float64
    if len(dest) != len(ego) or ego.shape[1] < 6:
        raise ValueError(f"need one destination (x, y) per ego state of 6 features, got "
                         f"ego {ego.shape} and destinations {dest.shape}")  # fmt: skip
    horizon = _horizon(times, arrive)
    out = np.empty((len(ego), len(times), 2), np.float32)
    speed, cos_h, sin_h = (np.ascontiguousarray(ego[:, k]) for k in (0, 4, 5))
    curves_many(speed, cos_h, sin_h, dest, times, horizon, _floats(limits), out)
    return out
