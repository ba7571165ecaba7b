"""The inner-city family: a jittered grid of streets with turning fillets
(:mod:`gridsim.road.city`), human-profile traffic on random routes, the ego on a random route
long enough for the episode."""

from __future__ import annotations

from functools import lru_cache, partial

import numpy as np

from gridsim.errors import ScenarioError
from gridsim.road.city import CityParams, CityRoad
from gridsim.scenario.loader import Scenario
from gridsim.scenario.parts import (
    fixed_route,
    seed_streams,
    speed_bounds,
    synthetic_tracks,
    vehicle_params,
)
from gridsim.scenario.schema import CityRoadConfig
from gridsim.traffic.sources import CityTraffic
from gridsim.world.world import World

#: An inner-city ego route is as long as the episode at the ego's speed (at least
#: :data:`ROUTE_MIN_SPEED` [m/s]) plus :data:`ROUTE_MARGIN` [m].
ROUTE_MIN_SPEED, ROUTE_MARGIN = 5.0, 200.0


@lru_cache(maxsize=4)
def _city_road(params: CityParams, seed: int) -> CityRoad:
    return CityRoad(params, seed)


#: The most participants of inner-city traffic: each has its own route, and a reset builds
#: them one by one (200: a reset in about 5 s).
MAX_PARTICIPANTS = 200


def build(scenario: Scenario, seed: int) -> World:
    cfg = scenario.config
    rc: CityRoadConfig = cfg.road
    road_seed, traffic_rng, ego_rng = seed_streams(seed)
    params = CityParams(**rc.model_dump(exclude={"type", "seed"}))
    road = _city_road(params, rc.seed if rc.seed is not None else road_seed)
    ego = vehicle_params(cfg.ego.vehicle)
    length = max(cfg.ego.speed, ROUTE_MIN_SPEED) * cfg.simulation.duration + ROUTE_MARGIN
    route = road.random_route(ego_rng, length)
    start, heading = route.point_at(5.0)
    state = np.array([start[0], start[1], heading, cfg.ego.speed, 0.0])
    tracks = synthetic_tracks(scenario)
    radius = max(cfg.traffic.window)
    traffic = CityTraffic(road, tracks, cfg.traffic.participants, speed_bounds(scenario), radius)
    most = min(traffic.capacity, MAX_PARTICIPANTS)
    if cfg.traffic.participants > most:
        raise ScenarioError(
            f"{scenario.source}: traffic.participants {cfg.traffic.participants} is more than "
            f"inner-city traffic holds: {most} (the streets within {radius:g} m of the ego "
            f"hold about {traffic.capacity}, one per {traffic.spacing:.1f} m of lane; each "
            f"participant drives its own route, and above {MAX_PARTICIPANTS} resets take "
            "seconds)"
        )
    return World(
        road, traffic, ego, state, cfg.simulation.dt, partial(fixed_route, route), traffic_rng
    )
