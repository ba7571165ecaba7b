"""Path-tracking controller for the bicycle model: pure pursuit steering, proportional speed.

Outputs the model's inputs (acceleration [m/s^2], steering rate [rad/s]) within the limits of
:class:`BicycleParams`. Used by the lane-following policy and the trajectory action.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gridsim.road.polyline import Polyline
from gridsim.vehicle.kinematics import DELTA, PSI, BicycleParams, V, X, Y


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
    target_xy: np.ndarray,
    target_speed: float,
    params: BicycleParams,
    gains: PursuitGains = PursuitGains(),
) -> tuple[float, float]:
    """Inputs steering the rear axle toward ``target_xy`` [m, world] at ``target_speed`` [m/s]."""
    dx, dy = target_xy[0] - state[X], target_xy[1] - state[Y]
    c, s = np.cos(state[PSI]), np.sin(state[PSI])
    fwd, left = c * dx + s * dy, -s * dx + c * dy
    dist2 = max(fwd * fwd + left * left, 1e-6)
    delta_cmd = np.arctan(2.0 * params.wheelbase * left / dist2)
    delta_cmd = float(np.clip(delta_cmd, -params.delta_max, params.delta_max))
    steer_rate = (delta_cmd - state[DELTA]) / gains.steer_time
    accel = gains.speed_gain * (target_speed - state[V])
    return float(np.clip(accel, -params.b_max, params.a_max)), float(
        np.clip(steer_rate, -params.v_delta_max, params.v_delta_max)
    )


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
    if s is None:
        s = float(path.project(state[None, :2])[0][0])
    look = gains.min_lookahead + gains.lookahead_time * max(state[V], 0.0)
    target, _ = path.frenet_to_world(s + look, offset)
    return pursuit_inputs(state, target, target_speed, params, gains)
