"""The seamless family: a never-ending multi-lane road generated from a seed
(:mod:`gridsim.road.seamless`), human-profile traffic kept in a window around the ego, the
ego in its lane."""

from __future__ import annotations

from functools import partial
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from gridsim.errors import ScenarioError
from gridsim.road.polyline import Polyline
from gridsim.road.seamless import SeamlessParams, SeamlessRoad
from gridsim.scenario.family import Family, register_family
from gridsim.scenario.parts import (
    library_data_report,
    seed_streams,
    speed_bounds,
    synthetic_tracks,
    vehicle_params,
)
from gridsim.scenario.schema import PositiveFloat, Scenario, Seed, Strict
from gridsim.traffic.sources import SeamlessTraffic
from gridsim.world.world import World


class SeamlessRoadConfig(Strict):
    """``road:`` of the seamless family (:class:`~gridsim.road.seamless.SeamlessParams`'
    defaults)."""

    type: Literal["seamless"]
    seed: Seed | None = None
    lanes: Annotated[int, Field(ge=1, le=8)] = SeamlessParams.lanes
    lane_width: Annotated[float, Field(ge=2, le=6, description="[m]")] = SeamlessParams.lane_width
    straight_fraction: Annotated[
        float, Field(ge=0, lt=1, description="the straight share of the road, 0-1 (not per cent)")
    ] = SeamlessParams.straight_fraction
    mean_curve_angle_deg: Annotated[float, Field(gt=0, le=120, description="[deg]")] = (
        SeamlessParams.mean_curve_angle_deg
    )
    curve_radius: tuple[PositiveFloat, PositiveFloat] = SeamlessParams.curve_radius

    @model_validator(mode="after")
    def _radius(self) -> SeamlessRoadConfig:
        lo, hi = self.curve_radius
        if lo > hi:
            raise ValueError(
                f"curve_radius must be [min, max] with min <= max, got {list(self.curve_radius)}"
            )
        half = 0.5 * self.lanes * self.lane_width
        if lo <= half + 1.0:
            raise ValueError(
                f"curve_radius min {lo} m must exceed the road half-width {half} m + 1 m"
            )
        return self


#: Seamless road held beyond the traffic window [m]: behind it and ahead of it (with the
#: default window of 80 / 160 m, 150 m behind the ego and 400 m ahead).
ROAD_MARGIN_BEHIND, ROAD_MARGIN_AHEAD = 70.0, 240.0


def build(scenario: Scenario, seed: int) -> World:
    cfg = scenario.config
    rc: SeamlessRoadConfig = cfg.road
    road_seed, traffic_rng, _ = seed_streams(seed)
    behind, ahead = cfg.traffic.window
    params = SeamlessParams(
        **rc.model_dump(exclude={"type", "seed"}),
        keep_behind=behind + ROAD_MARGIN_BEHIND,
        keep_ahead=ahead + ROAD_MARGIN_AHEAD,
    )
    road = SeamlessRoad(params, rc.seed if rc.seed is not None else road_seed)
    ego = vehicle_params(cfg.ego.vehicle)
    lane = cfg.ego.lane
    start, heading = road.lanes[lane].centre.point_at(0.0)
    state = np.array([start[0], start[1], heading, cfg.ego.speed, 0.0])
    tracks = synthetic_tracks(scenario)
    count = cfg.traffic.participants
    traffic = SeamlessTraffic(road, tracks, count, speed_bounds(scenario), behind, ahead)
    if count > traffic.capacity:
        raise ScenarioError(
            f"{scenario.source}: traffic.participants {count} is more than the "
            f"{traffic.capacity} vehicles that fit in traffic.window [{behind:g}, {ahead:g}] m "
            f"on {rc.lanes} lane(s) (one per {traffic.spacing:.1f} m): lower it or widen the "
            "window"
        )
    return World(
        road, traffic, ego, state, cfg.simulation.dt, partial(_lane_centre, road, lane), traffic_rng
    )


def _lane_centre(road: SeamlessRoad, lane: int) -> Polyline:
    return road.lanes[lane].centre


FAMILY = register_family(Family(
    SeamlessRoadConfig,
    build,
    data_report=library_data_report,
    ignores={"ego.track": "only recorded scenes have tracks"},
))  # fmt: skip
