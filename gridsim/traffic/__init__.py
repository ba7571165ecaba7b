"""Traffic: recorded trajectories, the structure-of-arrays fleet and traffic sources."""

from gridsim.traffic.fleet import EgoPose, Fleet, FleetParams
from gridsim.traffic.library import TrajectoryLibrary
from gridsim.traffic.sources import CityTraffic, RecordedSceneTraffic, SeamlessTraffic, SpeedBounds
from gridsim.traffic.track import Track

__all__ = [
    "CityTraffic",
    "EgoPose",
    "Fleet",
    "FleetParams",
    "RecordedSceneTraffic",
    "SeamlessTraffic",
    "SpeedBounds",
    "Track",
    "TrajectoryLibrary",
]
