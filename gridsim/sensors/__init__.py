"""Simulated sensors: the ego-centred occupancy grid."""

from gridsim.sensors.occupancy import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    GridSpec,
    OccupancyGridSensor,
    SensorMount,
)

__all__ = [
    "FREE",
    "OCCUPIED",
    "UNKNOWN",
    "GridSpec",
    "OccupancyGridSensor",
    "SensorMount",
]
