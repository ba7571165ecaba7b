"""Discrete driving commands (End2End's output) and the trajectories they stand for.

A command is a pair ``(steer, longitudinal)``:

- ``steer``: the direction of travel over the horizon relative to the ego's heading,
  discretised at :data:`STEER_STEP_DEG` degrees: class ``k`` in ``[0, 2 K]`` stands for
  ``(k - K) * 3`` degrees, with ``K =`` :data:`STEER_BINS_EACH_SIDE` (left positive);
- ``longitudinal``: 0 decelerate, 1 keep speed, 2 accelerate (the mean acceleration over the
  horizon below ``-ACCEL_THRESHOLD``, within, or above ``+ACCEL_THRESHOLD`` m/s^2).

As in the paper, the trajectory of a command is a line segment through the ego along the
commanded direction; the set-points lie on it at the distances the speed and the class's
acceleration give at the set-point times.

All positions are in the grid frame [m] (see :mod:`gridsim.frames`); ``heading`` is the
ego's heading in that frame [rad].
"""

from __future__ import annotations

import numpy as np

from gridsim import libm

STEER_STEP_DEG = 3.0
STEER_BINS_EACH_SIDE = 10  # +-30 degrees
N_STEER = 2 * STEER_BINS_EACH_SIDE + 1
LONGITUDINAL = ("decelerate", "keep", "accelerate")
ACCEL_THRESHOLD = 0.3  # m/s^2
#: Acceleration [m/s^2] a longitudinal class stands for until fitted to data.
DEFAULT_CLASS_ACCEL = np.array([-1.0, 0.0, 1.0])
_MIN_TRAVEL = 0.5  # m: below this the direction of travel is undefined (steer class K)


def steer_angles() -> np.ndarray:
    """The direction [rad] each steering class stands for, ``(N_STEER,)``."""
    k = np.arange(N_STEER) - STEER_BINS_EACH_SIDE
    return np.deg2rad(STEER_STEP_DEG * k)


def implied_commands(
    setpoints: np.ndarray, speed: np.ndarray, heading: np.ndarray, times: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The commands that set-points ``(N, T, 2)`` imply for egos at ``speed`` ``(N,)`` [m/s]
    and ``heading`` ``(N,)`` [rad], set-point ``times`` ``(T,)`` [s].

    Returns ``(steer class (N,), longitudinal class (N,), mean acceleration (N,) [m/s^2])``.
    The direction is that of the last set-point; the acceleration is the constant one that
    covers the distance to it in ``times[-1]``."""
    last = np.asarray(setpoints, float)[:, -1]
    dist = np.hypot(last[:, 0], last[:, 1])
    angle = libm.arctan2(last[:, 1], last[:, 0]) - heading
    angle = np.where(dist >= _MIN_TRAVEL, (angle + np.pi) % (2 * np.pi) - np.pi, 0.0)
    steer = (
        np.clip(
            np.rint(np.rad2deg(angle) / STEER_STEP_DEG), -STEER_BINS_EACH_SIDE, STEER_BINS_EACH_SIDE
        ).astype(np.int64)
        + STEER_BINS_EACH_SIDE
    )
    horizon = float(times[-1])
    accel = 2.0 * (dist - speed * horizon) / horizon**2
    longitudinal = 1 + (accel > ACCEL_THRESHOLD).astype(np.int64) - (accel < -ACCEL_THRESHOLD)
    return steer, longitudinal, accel


def command_setpoints(
    steer: np.ndarray,
    longitudinal: np.ndarray,
    speed: np.ndarray,
    heading: np.ndarray,
    times: np.ndarray,
    class_accel: np.ndarray = DEFAULT_CLASS_ACCEL,
) -> np.ndarray:
    """Set-points ``(N, T, 2)`` [m] on the line segment of each command: direction ``heading
    + steer angle``, distance ``v t + a t^2 / 2`` with ``a = class_accel[longitudinal]``
    (stopping, never reversing, when braking)."""
    direction = np.asarray(heading, float) + steer_angles()[steer]
    a = np.asarray(class_accel, float)[longitudinal][:, None]
    v = np.asarray(speed, float)[:, None]
    t = np.asarray(times, float)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_stop = np.where(a < 0, v / -a, np.inf)
    tt = np.minimum(t, t_stop)
    dist = np.maximum(v * tt + 0.5 * a * tt**2, 0.0)
    return np.stack([dist * np.cos(direction)[:, None], dist * np.sin(direction)[:, None]], axis=2)


def fit_class_accel(longitudinal: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """Median acceleration [m/s^2] of each longitudinal class in labelled data (the default
    for classes that do not occur)."""
    out = DEFAULT_CLASS_ACCEL.copy()
    for c in range(len(LONGITUDINAL)):
        sel = longitudinal == c
        if np.any(sel):
            out[c] = float(np.median(accel[sel]))
    return out
