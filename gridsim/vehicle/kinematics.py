"""Kinematic single-track (bicycle) model, rear-axle reference, batched over vehicles.

State rows are ``[x, y, psi, v, delta]`` (column indices :data:`X`, :data:`Y`, :data:`PSI`,
:data:`V`, :data:`DELTA`):

- ``x, y`` [m]: rear-axle centre in the right-handed world frame (x east, y north);
- ``psi`` [rad]: heading, counter-clockwise from +x;
- ``v`` [m/s]: longitudinal speed of the rear axle;
- ``delta`` [rad]: front-wheel steering angle, positive to the left.

Inputs are ``[a, v_delta]``: longitudinal acceleration [m/s^2] and steering rate [rad/s].
The dynamics are those of CommonRoad's ``vehicle_dynamics_ks``::

    x' = v cos(psi)   y' = v sin(psi)   psi' = v tan(delta) / l_wb   v' = a   delta' = v_delta

Within one step the (clipped) inputs are constant, so ``delta(t)`` is linear and ``v(t)`` is
linear, or ``sqrt(v0^2 + 2 a_max v_switch t)`` while the power limit is active. The yaw rate
is then a known function of time; heading and position are integrated with Simpson's rule on
the exact speed and steering profiles (fourth order, like RK4, at three evaluations). The
integration is written once, :func:`~gridsim.vehicle.kinematics_kernels.step_one`, for one
vehicle in Python floats and, compiled, for many (:func:`step_bicycle`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from gridsim.vehicle.kinematics_kernels import step_many, step_one

X, Y, PSI, V, DELTA = range(5)
STATE_SIZE = 5


@dataclass(frozen=True)
class BicycleParams:
    """Geometry and limits of a vehicle (SI units). Fields may be floats or per-vehicle arrays.

    ``center_offset`` is the distance [m] from the rear axle forward to the centre of the
    ``length`` x ``width`` footprint rectangle.
    """

    wheelbase: float = 2.7
    length: float = 4.5
    width: float = 1.8
    center_offset: float = 1.35
    v_min: float = 0.0
    v_max: float = 40.0
    a_max: float = 2.0
    b_max: float = 6.0
    delta_max: float = 0.6
    v_delta_max: float = 0.8
    v_switch: float = np.inf

    def __post_init__(self) -> None:
        checks = {
            "wheelbase": self.wheelbase > 0,
            "length": self.length > 0,
            "width": self.width > 0,
            "a_max": self.a_max > 0,
            "b_max": self.b_max > 0,
            "delta_max": np.logical_and(self.delta_max > 0, self.delta_max < np.pi / 2),
            "v_delta_max": self.v_delta_max > 0,
            "v_switch": self.v_switch > 0,
            "v_max": self.v_max >= self.v_min,
        }
        bad = [name for name, ok in checks.items() if not np.all(ok)]
        if bad:
            from gridsim.errors import GridSimError

            values = ", ".join(f"{n}={getattr(self, n)!r}" for n in bad)
            raise GridSimError(
                f"invalid vehicle parameters: {values} (need positive sizes and limits, "
                "0 < delta_max < pi/2, v_max >= v_min)"
            )
        # All fields scalar: one vehicle can take the pure-Python path of step_bicycle.
        scalar = all(np.ndim(getattr(self, f.name)) == 0 for f in fields(self))
        object.__setattr__(self, "_scalar", scalar)


class StepResult(NamedTuple):
    """New state ``(N, 5)`` and the inputs actually applied after clipping, ``(N,)`` each."""

    state: np.ndarray
    accel: np.ndarray
    steer_rate: np.ndarray


def step_bicycle(
    state: np.ndarray,
    accel: np.ndarray | float,
    steer_rate: np.ndarray | float,
    params: BicycleParams,
    dt: float,
) -> StepResult:
    """Advance every vehicle by ``dt`` seconds with inputs held constant over the step.

    ``state`` has shape ``(N, 5)`` (or ``(5,)``); inputs broadcast against ``N``. Inputs are
    clipped to ``[-b_max, a_max]`` (and the power limit) and ``[-v_delta_max, v_delta_max]``,
    and further so that ``v`` stays in ``[v_min, v_max]`` and ``|delta| <= delta_max`` at the
    end of the step. Returns a new array; ``state`` is not modified.
    """
    if (
        params._scalar
        and np.ndim(state) == 1
        and isinstance(accel, float)
        and isinstance(steer_rate, float)
        and math.isfinite(accel)
        and math.isfinite(steer_rate)
    ):
        return _step_one(state, accel, steer_rate, params, dt)
    state = np.asarray(state, dtype=np.float64)
    fields_ = [np.asarray(getattr(params, name), dtype=np.float64) for name in LIMIT_FIELDS]
    accel = np.asarray(accel, dtype=np.float64)
    steer_rate = np.asarray(steer_rate, dtype=np.float64)
    shape = np.broadcast_shapes(state.shape[:-1], accel.shape, steer_rate.shape,
                                *(f.shape for f in fields_))  # fmt: skip
    n = math.prod(shape)
    limits = np.empty((n, len(LIMIT_FIELDS)))
    for k, f in enumerate(fields_):
        limits[:, k] = np.broadcast_to(f, shape).reshape(n)
    # writable C-contiguous copies: one compiled signature whatever the caller's layout
    out, applied, rates = step_many(
        np.array(np.broadcast_to(state, shape + (STATE_SIZE,)).reshape(n, STATE_SIZE), order="C"),
        np.array(np.broadcast_to(accel, shape).reshape(n), order="C"),
        np.array(np.broadcast_to(steer_rate, shape).reshape(n), order="C"),
        limits,
        float(dt),
    )
    return StepResult(out.reshape(shape + (STATE_SIZE,)), applied.reshape(shape),
                      rates.reshape(shape))  # fmt: skip


def _step_one(
    state: np.ndarray, accel: float, steer_rate: float, p: BicycleParams, dt: float
) -> StepResult:
    """:func:`step_bicycle` for one vehicle with finite float inputs, in Python floats: the
    same operations in the same order (``math`` and NumPy share libm), hence the same bits,
    without the overhead of a compiled call on arrays of one."""
    x0, y0, psi0, v0, d0 = state.tolist()
    x1, y1, psi1, v1, d1, a, vd = step_one(x0, y0, psi0, v0, d0, accel, steer_rate,
                                           step_limits(p), dt)  # fmt: skip
    return StepResult(np.array([x1, y1, psi1, v1, d1]), np.array(a), np.array(vd))


#: The :class:`BicycleParams` fields :func:`step_one` takes as its ``limits``, in order.
LIMIT_FIELDS = ("wheelbase", "v_min", "v_max", "a_max", "b_max", "delta_max", "v_delta_max",
                "v_switch")  # fmt: skip


@lru_cache(maxsize=16)
def step_limits(p: BicycleParams) -> tuple:
    """The limits of one vehicle (scalar fields) as :func:`step_one` takes them."""
    return tuple(getattr(p, name) for name in LIMIT_FIELDS)


def rear_axle_of(centre: np.ndarray, heading, center_offset) -> np.ndarray:
    """Rear-axle positions ``(..., 2)`` [m] of vehicles whose footprints are centred at
    ``centre`` ``(..., 2)`` with ``heading`` ``(...)`` [rad] (``center_offset``: see
    :class:`BicycleParams`)."""
    u = np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    return centre - center_offset * u


def centre_of(rear: np.ndarray, heading, center_offset) -> np.ndarray:
    """Footprint centres ``(..., 2)`` [m] of vehicles with the rear axle at ``rear`` and
    ``heading`` [rad]: the inverse of :func:`rear_axle_of`."""
    return rear + center_offset * np.stack([np.cos(heading), np.sin(heading)], axis=-1)


def centre_xy(x: float, y: float, heading: float, center_offset: float) -> tuple[float, float]:
    """:func:`centre_of` one vehicle, in Python floats (``math``, not NumPy: a world tick asks
    for the ego's centre a few times, and NumPy's call overhead would be ten times the sum)."""
    cos, sin = math.cos(heading), math.sin(heading)
    return float(x + center_offset * cos), float(y + center_offset * sin)


def box_corners(
    x: np.ndarray, y: np.ndarray, psi: np.ndarray, length: np.ndarray, width: np.ndarray
) -> np.ndarray:
    """Corners ``(N, 4, 2)`` [m] of oriented rectangles centred at ``(x, y)`` with heading ``psi``.

    Order: rear-right, front-right, front-left, rear-left (counter-clockwise).
    """
    c, s = np.cos(psi), np.sin(psi)
    hl, hw = 0.5 * np.asarray(length, float), 0.5 * np.asarray(width, float)
    lx = np.array([-1.0, 1.0, 1.0, -1.0])
    ly = np.array([-1.0, -1.0, 1.0, 1.0])
    dx = np.multiply.outer(hl, lx) if np.ndim(hl) else hl * lx
    dy = np.multiply.outer(hw, ly) if np.ndim(hw) else hw * ly
    dx = np.broadcast_to(dx, np.shape(x) + (4,))
    dy = np.broadcast_to(dy, np.shape(x) + (4,))
    c, s = np.asarray(c)[..., None], np.asarray(s)[..., None]
    cx = np.asarray(x)[..., None] + c * dx - s * dy
    cy = np.asarray(y)[..., None] + s * dx + c * dy
    return np.stack([cx, cy], axis=-1)
