"""Frames and layouts shared by the simulator, the environment and the trainer.

The ego-centred **grid frame** of observations, actions and labels: origin at the ego's rear
axle; with ``north_up`` grids the axes are parallel to the world's (x east, y north), with
``heading_up`` grids they are the body axes (x forward, y left). Either way the frame
matches the occupancy grid the network sees; :func:`grid_to_pixel` and
:func:`world_to_pixel` give its pixels.

The **set-point times** of a plan, and the **ego feature vector** of an observation
(:data:`EGO_FEATURES`, read by name through the ``EGO_*`` indices).
"""

from __future__ import annotations

import math

import numpy as np

from gridsim import libm

#: The largest world coordinate accepted in maps and recorded tracks [m] (UTM coordinates are
#: below 1e7): the world frame's extent.
MAX_COORDINATE = 1e7

#: The observation's ego vector, in this order (float32; heading in the grid frame).
EGO_FEATURES = (
    "speed",  # [m/s]
    "steering_angle",  # [rad]
    "acceleration",  # [m/s^2], the last tick's
    "steering_rate",  # [rad/s], the last tick's
    "cos_heading",
    "sin_heading",
)
EGO_SPEED, EGO_STEERING, EGO_ACCEL, EGO_STEER_RATE, EGO_COS, EGO_SIN = range(len(EGO_FEATURES))


def setpoint_times(period: float, horizon: int) -> np.ndarray:
    """The times [s] after a decision of a plan's ``horizon`` set-points, ``period`` apart."""
    return period * np.arange(1, horizon + 1)


def ego_heading(ego: np.ndarray) -> np.ndarray:
    """The heading [rad, grid frame] of ego vectors ``(..., 6)``."""
    return libm.arctan2(ego[..., EGO_SIN], ego[..., EGO_COS])


def grid_rotation(orientation: str, psi: float) -> float:
    """Angle [rad] from the grid frame's x axis to the world's x axis."""
    return 0.0 if orientation == "north_up" else float(psi)


def world_to_grid(points: np.ndarray, ego_xy: np.ndarray, rotation: float) -> np.ndarray:
    """World points ``(N, 2)`` into the grid frame."""
    c, s = math.cos(rotation), math.sin(rotation)
    d = np.asarray(points, dtype=np.float64) - ego_xy
    out = np.empty(d.shape)
    out[:, 0] = c * d[:, 0] + s * d[:, 1]
    out[:, 1] = -s * d[:, 0] + c * d[:, 1]
    return out


def grid_to_world(points: np.ndarray, ego_xy: np.ndarray, rotation: float) -> np.ndarray:
    """Grid-frame points ``(N, 2)`` into the world frame."""
    c, s = math.cos(rotation), math.sin(rotation)
    p = np.asarray(points, dtype=np.float64)
    out = np.empty(p.shape)
    out[:, 0] = c * p[:, 0] - s * p[:, 1]
    out[:, 1] = s * p[:, 0] + c * p[:, 1]
    out += ego_xy
    return out


def grid_to_pixel(
    points: np.ndarray, rows: int, cols: int, cell_size: float, orientation: str
) -> np.ndarray:
    """Grid-frame points ``(..., 2)`` [m] -> fractional pixel coordinates ``(..., 2)`` =
    (column u, row v) of the occupancy grid (cell centres at whole numbers; see
    :mod:`gridsim.sensors.occupancy`)."""
    p = np.asarray(points, dtype=np.float64)
    right, up = (p[..., 0], p[..., 1]) if orientation == "north_up" else (-p[..., 1], p[..., 0])
    return np.stack([cols / 2 - 0.5 + right / cell_size, rows / 2 - 0.5 - up / cell_size], axis=-1)


def world_to_pixel(
    ego_xy: np.ndarray, ego_psi: float, rows: int, cols: int, cell_size: float, orientation: str
) -> np.ndarray:
    """Affine map ``(2, 3)``: world points [m] -> fractional pixel coordinates (column u, row
    v) of the occupancy grid around the ego at ``ego_xy`` [m] with heading ``ego_psi`` [rad]
    (the same pixels as :func:`world_to_grid` then :func:`grid_to_pixel`)."""
    k = 1.0 / cell_size
    cu, cv = cols / 2 - 0.5, rows / 2 - 0.5
    if orientation == "north_up":
        # A scale: each product of ``rot @ ego_xy`` is one rounding plus an exact zero.
        x, y = float(ego_xy[0]), float(ego_xy[1])
        return np.array([[k, 0.0, cu - k * x], [0.0, -k, cv - -k * y]])
    # up = heading, right = heading - 90 deg
    c, sn = np.cos(ego_psi), np.sin(ego_psi)
    rot = np.array([[sn * k, -c * k], [-c * k, -sn * k]])
    t = np.array([cu, cv]) - rot @ np.asarray(ego_xy, dtype=np.float64)
    return np.hstack([rot, t[:, None]])
