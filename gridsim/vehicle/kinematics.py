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
the exact speed and steering profiles (fourth order, like RK4, at three evaluations).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from gridsim import libm
from gridsim.jit import jitable

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
            "delta_max": 0 < self.delta_max < np.pi / 2,
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
    p = params
    state = np.asarray(state, dtype=np.float64)
    x0, y0, psi0, v0, d0 = (
        state[..., X],
        state[..., Y],
        state[..., PSI],
        state[..., V],
        state[..., DELTA],
    )
    # Steering rate: rate limit, and no farther than the steering limit by the end of the step.
    vd_lo = np.maximum(-p.v_delta_max, (-p.delta_max - d0) / dt)
    vd_hi = np.minimum(p.v_delta_max, (p.delta_max - d0) / dt)
    vd = np.minimum(np.maximum(steer_rate, vd_lo), vd_hi)
    a = np.minimum(np.maximum(accel, -p.b_max), p.a_max)
    v1 = v0 + a * dt
    vh = v0 + (0.5 * dt) * a
    if np.any(np.isfinite(p.v_switch)):
        # Power limit above v_switch: a <= a_max v_switch / v (CommonRoad). While it binds,
        # v(t) = sqrt(v0^2 + 2 a_max v_switch t) exactly.
        c = p.a_max * p.v_switch
        with np.errstate(divide="ignore", invalid="ignore"):
            power = (v0 > p.v_switch) & (a * v0 >= c)
        v1 = np.where(power, np.sqrt(v0 * v0 + 2.0 * c * dt), v1)
        vh = np.where(power, np.sqrt(v0 * v0 + c * dt), vh)
    v1_clipped = np.minimum(np.maximum(v1, p.v_min), p.v_max)
    if np.any(v1_clipped != v1):  # a speed limit is reached: speed linear to the limit
        vh = np.where(v1_clipped != v1, 0.5 * (v0 + v1_clipped), vh)
        v1 = v1_clipped
    # Yaw rate at t = 0, dt/2, dt; Simpson's rule for the heading and the position.
    ddt = vd * dt
    inv_l = 1.0 / p.wheelbase
    w0 = v0 * libm.tan(d0) * inv_l
    wh = vh * libm.tan(d0 + 0.5 * ddt) * inv_l
    w1 = v1 * libm.tan(d0 + ddt) * inv_l
    psih = psi0 + dt / 24.0 * (5.0 * w0 + 8.0 * wh - w1)
    psi1 = psi0 + dt / 6.0 * (w0 + 4.0 * wh + w1)
    x1 = x0 + dt / 6.0 * (v0 * np.cos(psi0) + 4.0 * vh * np.cos(psih) + v1 * np.cos(psi1))
    y1 = y0 + dt / 6.0 * (v0 * np.sin(psi0) + 4.0 * vh * np.sin(psih) + v1 * np.sin(psi1))
    shape = np.broadcast_shapes(state.shape[:-1], np.shape(v1), np.shape(vd))
    out = np.empty(shape + (STATE_SIZE,))
    out[..., X], out[..., Y], out[..., PSI], out[..., V], out[..., DELTA] = (
        x1,
        y1,
        psi1,
        v1,
        d0 + ddt,
    )
    accel_applied = np.broadcast_to((v1 - v0) / dt, shape).copy()
    return StepResult(out, accel_applied, np.broadcast_to(vd, shape).copy())


def _step_one(
    state: np.ndarray, accel: float, steer_rate: float, p: BicycleParams, dt: float
) -> StepResult:
    """:func:`step_bicycle` for one vehicle with finite float inputs, in Python floats: the
    same operations in the same order (``math`` and NumPy share libm), hence the same bits,
    without the per-call overhead of some 40 array operations."""
    x0, y0, psi0, v0, d0 = state.tolist()
    x1, y1, psi1, v1, d1, a, vd = step_one(x0, y0, psi0, v0, d0, accel, steer_rate,
                                           step_limits(p), dt)  # fmt: skip
    return StepResult(np.array([x1, y1, psi1, v1, d1]), np.array(a), np.array(vd))


@lru_cache(maxsize=16)
def step_limits(p: BicycleParams) -> tuple:
    """The limits of one vehicle (scalar fields) as :func:`step_one` takes them."""
    return (p.wheelbase, p.v_min, p.v_max, p.a_max, p.b_max, p.delta_max, p.v_delta_max,
            p.v_switch)  # fmt: skip


@jitable
def step_one(x0, y0, psi0, v0, d0, accel, steer_rate, limits, dt):
    """One vehicle's step on floats: the new ``(x, y, psi, v, delta)`` and the applied
    acceleration [m/s^2] and steering rate [rad/s]. ``limits``: ``(wheelbase, v_min, v_max,
    a_max, b_max, delta_max, v_delta_max, v_switch)`` of :class:`BicycleParams`. Compiled
    (inside a kernel) it gives the same bits (``math`` is libm there too)."""
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
