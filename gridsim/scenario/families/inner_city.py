"""The inner-city family: a jittered grid of streets with turning fillets
(:mod:`gridsim.road.city`), human-profile traffic on random routes, the ego on a random route
long enough for the episode."""

from __future__ import annotations

import math
from functools import lru_cache, partial
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from gridsim.errors import ScenarioError
from gridsim.road.base import (
    MAX_RASTER_CELLS,
    RASTER_MARGIN,
    RASTER_RESOLUTION,
    raster_cells,
)
from gridsim.road.city import CityParams, CityRoad
from gridsim.scenario.family import Family, register_family
from gridsim.scenario.parts import (
    fixed_route,
    library_data_report,
    seed_streams,
    speed_bounds,
    synthetic_tracks,
    vehicle_params,
)
from gridsim.scenario.schema import Scenario, Seed, Strict
from gridsim.traffic.sources import CityTraffic
from gridsim.world.world import World


class CityRoadConfig(Strict):
    """``road:`` of the inner-city family (:class:`~gridsim.road.city.CityParams`' defaults)."""

    type: Literal["inner_city"]
    seed: Seed | None = 0
    blocks_x: Annotated[int, Field(ge=1, le=40)] = CityParams.blocks_x
    blocks_y: Annotated[int, Field(ge=1, le=40)] = CityParams.blocks_y
    block_size: Annotated[float, Field(ge=20, le=500, description="[m]")] = CityParams.block_size
    jitter: Annotated[float, Field(ge=0, le=50, description="[m]")] = CityParams.jitter
    lanes_per_direction: Annotated[int, Field(ge=1, le=4)] = CityParams.lanes_per_direction
    lane_width: Annotated[float, Field(ge=2, le=6, description="[m]")] = CityParams.lane_width
    turn_radius: Annotated[float, Field(ge=3, le=50, description="[m]")] = CityParams.turn_radius
    turn_probability: Annotated[
        float, Field(ge=0, le=1, description="a probability, 0-1 (not per cent)")
    ] = CityParams.turn_probability

    @model_validator(mode="after")
    def _sizes(self) -> CityRoadConfig:
        if self.jitter >= 0.25 * self.block_size:
            raise ValueError(
                f"jitter ({self.jitter}) must be < block_size / 4 ({self.block_size / 4})"
            )
        # the streets' extent at most (nodes jittered outwards, the outer streets' width),
        # with the raster's margins: more cells than a road rasterises is refused here, by key
        street = 2 * self.lanes_per_direction * self.lane_width
        sides = [n * self.block_size + 2 * self.jitter + street + 2 * RASTER_MARGIN
                 for n in (self.blocks_x, self.blocks_y)]  # fmt: skip
        if raster_cells(sides) > MAX_RASTER_CELLS:
            most = math.sqrt(MAX_RASTER_CELLS) * RASTER_RESOLUTION / 1000  # [km] a side
            raise ValueError(
                f"blocks_x ({self.blocks_x}) and blocks_y ({self.blocks_y}) blocks of "
                f"block_size {self.block_size:g} m make a city of about {sides[0] / 1000:.1f} "
                f"km x {sides[1] / 1000:.1f} km, more than a road's raster holds "
                f"({MAX_RASTER_CELLS:.0e} cells of {RASTER_RESOLUTION:g} m: about {most:.0f} km "
                f"x {most:.0f} km); use fewer or smaller blocks"
            )
        return self


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


FAMILY = register_family(Family(
    CityRoadConfig,
    build,
    # city speeds and more participants than the schema's defaults (the seamless road's)
    defaults={
        "traffic": {"participants": 20, "v_min": 2.77, "v_max": 8.33},
        "ego": {"speed": 5.0, "vehicle": {"v_max": 8.33}},
    },
    data_report=library_data_report,
    ignores={"ego.track": "only recorded scenes have tracks",
             "ego.lane": "the ego starts on a route of the street network"},
))  # fmt: skip
