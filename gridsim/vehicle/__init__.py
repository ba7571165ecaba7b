"""Vehicle models: the kinematic single-track (bicycle) model and the IDM car follower."""

from gridsim.vehicle.idm import IDMParams, idm_acceleration
from gridsim.vehicle.kinematics import (
    DELTA,
    PSI,
    STATE_SIZE,
    BicycleParams,
    StepResult,
    V,
    X,
    Y,
    box_corners,
    step_bicycle,
)

__all__ = [
    "DELTA",
    "PSI",
    "STATE_SIZE",
    "V",
    "X",
    "Y",
    "BicycleParams",
    "IDMParams",
    "StepResult",
    "box_corners",
    "idm_acceleration",
    "step_bicycle",
]
