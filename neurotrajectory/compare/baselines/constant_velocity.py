"""The sanity baseline: constant speed and heading."""

from __future__ import annotations

import numpy as np

from neurotrajectory.compare.predictors import Setting
from neurotrajectory.data.windows import Windows


def constant_velocity_setpoints(speed: np.ndarray, heading: np.ndarray, times: np.ndarray):
    """Where egos at ``speed`` ``(N,)`` [m/s] with ``heading`` ``(N,)`` [rad, grid frame] are
    at ``times`` ``(T,)`` [s] holding both: ``(N, T, 2)`` [m]."""
    dist = np.asarray(speed, float)[:, None] * np.asarray(times, float)[None, :]
    h = np.asarray(heading, float)[:, None]
    return np.stack([dist * np.cos(h), dist * np.sin(h)], axis=2)


class ConstantVelocity:
    """The sanity baseline: the ego keeps its speed and heading."""

    name = "constant velocity"

    def __init__(self, setting: Setting) -> None:
        self.setting = setting

    def predict(self, batch: Windows) -> np.ndarray:
        return constant_velocity_setpoints(batch.speed, batch.heading, self.setting.times)
