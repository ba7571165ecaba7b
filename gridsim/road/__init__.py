"""Roads: polylines, the seamless generator, the inner-city network and recorded maps."""

from gridsim.road.base import Lane, Road, StaticRoad
from gridsim.road.city import CityParams, CityRoad
from gridsim.road.lanelet import load_lanelet_road
from gridsim.road.polyline import Polyline
from gridsim.road.seamless import SeamlessParams, SeamlessRoad

__all__ = [
    "CityParams",
    "CityRoad",
    "Lane",
    "Polyline",
    "Road",
    "SeamlessParams",
    "SeamlessRoad",
    "StaticRoad",
    "load_lanelet_road",
]
