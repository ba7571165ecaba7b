"""The destination-curve baseline: the feasible arc to the given destination at constant
acceleration (:mod:`neurotrajectory.curves`), no grid. When the destination is known, this
is the floor a learned planner must beat."""

from __future__ import annotations

import numpy as np

from neurotrajectory.compare.predictors import Setting
from neurotrajectory.curves import CurveLimits, destination_curves
from neurotrajectory.data.windows import Windows


class DestinationCurve:
    """Drives the destination curve; ignores the grids."""

    name = "destination curve"

    def __init__(self, setting: Setting) -> None:
        self.setting = setting
        self.limits = CurveLimits.from_params(setting.params)

    def predict(self, batch: Windows) -> np.ndarray:
        s = self.setting
        curves = destination_curves(batch.ego, batch.destination, s.times, self.limits,
                                    s.goal_time if s.far_goal else None)  # fmt: skip
        return curves.astype(np.float64)
