"""Path-tracking controller for the bicycle model: pure pursuit steering, proportional speed.

Outputs the model's inputs (acceleration [m/s^2], steering rate [rad/s]) within the limits of
:class:`BicycleParams`. Used by the lane-following policy and the trajectory action.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gridsim.jit import jitable
from gridsim.road.polyline import Polyline
from gridsim.vehicle.kinematics import BicycleParams, V


@dataclass(frozen=True)
class PursuitGains:
    """``lookahead = min_lookahead + lookahead_time * v`` [m]; ``steer_time`` [s] is the time
    constant to reach the commanded steering angle; ``speed_gain`` [1/s]."""

    min_lookahead: float = 4.0
    lookahead_time: float = 0.8
    steer_time: float = 0.2
    speed_gain: float = 1.0


def pursuit_inputs(
    state: np.ndarray,
    target_xy: tuple[float, float] | np.ndarray,
    target_speed: float,
    params: BicycleParams,
    gains: PursuitGains = PursuitGains(),
) -> tuple[float, float]:
    """Inputs steering the rear axle toward ``target_xy`` [m, world] at ``target_speed`` [m/s]."""
    x, y, psi, v, delta = state.tolist()  # [x, y, psi, v, delta], see kinematics
    p, g = params, gains
    limits = (p.wheelbase, p.delta_max, p.b_max, p.a_max, p.v_delta_max, g.steer_time,
              g.speed_gain)  # fmt: skip
    return pursuit_one(x, y, psi, v, delta, float(target_xy[0]), float(target_xy[1]),
                       target_speed, limits)  # fmt: skip


@jitable
def pursuit_one(x, y, psi, v, delta, tx, ty, target_speed, limits):
    """:func:`pursuit_inputs` on floats (the same bits compiled): acceleration [m/s^2] and
    steering rate [rad/s] toward ``(tx, ty)`` [m, world]; ``limits``: ``(wheelbase,
    delta_max, b_max, a_max, v_delta_max, steer_time, speed_gain)``."""
    wheelbase, delta_max, b_max, a_max, v_delta_max, steer_time, speed_gain = limits
    dx, dy = tx - x, ty - y
    c, s = math.cos(psi), math.sin(psi)
    fwd, left = c * dx + s * dy, -s * dx + c * dy
    dist2 = max(fwd * fwd + left * left, 1e-6)
    delta_cmd = math.atan(2.0 * wheelbase * left / dist2)
    delta_cmd = _clip(delta_cmd, -delta_max, delta_max)
    steer_rate = (delta_cmd - delta) / steer_time
    accel = speed_gain * (target_speed - v)
    return _clip(accel, -b_max, a_max), _clip(steer_rate, -v_delta_max, v_delta_max)


@jitable
def _clip(x: float, lo: float, hi: float) -> float:
    """``float(np.clip(x, lo, hi))`` for finite Python scalars, without its overhead."""
    return float(min(max(x, lo), hi))


def pursuit_lookahead(v: float, gains: PursuitGains) -> float:
    """How far ahead [m] along the path pure pursuit aims at speed ``v`` [m/s]."""
    return gains.min_lookahead + gains.lookahead_time * max(v, 0.0)


def follow_path(
    state: np.ndarray,
    path: Polyline,
    target_speed: float,
    params: BicycleParams,
    gains: PursuitGains = PursuitGains(),
    offset: float = 0.0,
    s: float | None = None,
) -> tuple[float, float]:
    """Pure pursuit along ``path`` (at lateral ``offset`` [m], positive left). ``s`` is the
    vehicle's arc length on the path if already known."""
    ahead = pursuit_lookahead(state[V], gains)
    if s is None:
        x, y, _ = path.ahead_of(state[0], state[1], ahead, offset)
    else:
        x, y, _ = path.frenet_one(s + ahead, offset)
    return pursuit_inputs(state, (x, y), target_speed, params, gains)
