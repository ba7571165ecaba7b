"""Turn a validated :class:`Scenario` into a :class:`World` and an occupancy-grid sensor.

Dispatch is by the road config's type through :data:`WORLD_BUILDERS`; static maps and
libraries are cached so that resets are cheap. One reset seed is split into independent
streams for the road, the traffic and the ego.
"""

from __future__ import annotations

import copy
from collections import OrderedDict
from collections.abc import Callable
from functools import lru_cache, partial
from pathlib import Path

import numpy as np

from gridsim.errors import DataError, ScenarioError
from gridsim.road.base import StaticRoad
from gridsim.road.city import CityParams, CityRoad
from gridsim.road.lanelet import load_lanelet_road
from gridsim.road.polyline import Polyline
from gridsim.road.seamless import SeamlessParams, SeamlessRoad
from gridsim.scenario.loader import Scenario
from gridsim.scenario.schema import (
    CityRoadConfig,
    RecordedRoadConfig,
    SeamlessRoadConfig,
    VehicleConfig,
)
from gridsim.sensors.occupancy import GridSpec, OccupancyGridSensor, SensorMount
from gridsim.traffic.commonroad import scene_id
from gridsim.traffic.library import Track, TrajectoryLibrary
from gridsim.traffic.sources import (
    CityTraffic,
    RecordedSceneTraffic,
    SeamlessTraffic,
    SpeedBounds,
    SyntheticTraffic,
    track_path,
)
from gridsim.vehicle.kinematics import BicycleParams
from gridsim.world.collision import EDGE_TOLERANCE, CollisionChecker
from gridsim.world.world import World

#: Recorded tracks shorter than this [s] are neither human profiles nor egos.
MIN_TRACK_SECONDS = 2.0
#: Seamless road held beyond the traffic window [m]: behind it and ahead of it (with the
#: default window of 80 / 160 m, 150 m behind the ego and 400 m ahead).
ROAD_MARGIN_BEHIND, ROAD_MARGIN_AHEAD = 70.0, 240.0
#: An inner-city ego route is as long as the episode at the ego's speed (at least
#: :data:`ROUTE_MIN_SPEED` [m/s]) plus :data:`ROUTE_MARGIN` [m].
ROUTE_MIN_SPEED, ROUTE_MARGIN = 5.0, 200.0


def vehicle_params(
    cfg: VehicleConfig, length: float | None = None, width: float | None = None
) -> BicycleParams:
    """Bicycle parameters from the YAML vehicle block (angles converted to radians)."""
    length = cfg.length if length is None else length
    width = cfg.width if width is None else width
    wheelbase = min(cfg.wheelbase, 0.7 * length)
    return BicycleParams(
        wheelbase=wheelbase,
        length=length,
        width=width,
        center_offset=0.5 * wheelbase,
        v_min=cfg.v_min,
        v_max=cfg.v_max,
        a_max=cfg.a_max,
        b_max=cfg.b_max,
        delta_max=np.deg2rad(cfg.max_steer_deg),
        v_delta_max=np.deg2rad(cfg.max_steer_rate_deg),
    )


def build_sensor(scenario: Scenario) -> OccupancyGridSensor:
    s = scenario.config.sensor
    mounts = tuple(
        SensorMount(m.x, m.y, np.deg2rad(m.yaw_deg), np.deg2rad(m.fov_deg)) for m in s.mounts
    )
    spec = GridSpec(
        rows=s.rows,
        cols=s.cols,
        cell_size=s.cell_size,
        orientation=s.orientation,
        max_range=s.max_range,
        rays=s.rays,
        hit_depth=s.hit_depth,
        ray_step=s.ray_step,
        mounts=mounts,
    )
    return OccupancyGridSensor(spec)


def _resolve(scenario: Scenario, ref: str, builtin_dir: tuple[str, ...], suffix: str) -> Path:
    from importlib import resources

    if ref.startswith("builtin:"):
        name = ref.split(":", 1)[1]
        entry = resources.files("gridsim").joinpath(*builtin_dir, name + suffix)
        if not entry.is_file():
            raise ScenarioError(f"{scenario.source}: no built-in file {ref!r}")
        return Path(str(entry))
    path = Path(ref)
    if not path.is_absolute() and scenario.base_dir is not None:
        path = scenario.base_dir / path
    if not path.is_file():
        raise ScenarioError(f"{scenario.source}: file not found: {ref!r} (resolved to {path})")
    return path


def _stamped(path: Path) -> tuple[str, int, int]:
    """A file as a cache key: its path, modification time and size, so that a file edited
    on disk is read again."""
    st = path.stat()
    return str(path), st.st_mtime_ns, st.st_size


def library_for(scenario: Scenario) -> TrajectoryLibrary:
    """The tracks of ``traffic.library``: ``builtin``, ``scene`` (the recorded map file's
    dynamic obstacles) and trajectory files (CSV or CommonRoad XML)."""
    files = []
    for ref in scenario.config.traffic.library:
        if ref == "builtin":
            files.append("builtin")
        elif ref == "scene":
            if not isinstance(scenario.config.road, RecordedRoadConfig):
                raise ScenarioError(
                    f"{scenario.source}: traffic.library 'scene' needs road.type recorded (the "
                    "tracks of its CommonRoad map file)"
                )
            files.append(_stamped(map_path(scenario)))
        else:
            files.append(_stamped(_resolve(scenario, ref, ("data", "ngsim"), ".csv")))
    return _library(tuple(files))


@lru_cache(maxsize=8)
def _library(files: tuple) -> TrajectoryLibrary:
    tracks = []
    for f in files:
        lib = TrajectoryLibrary.builtin() if f == "builtin" else TrajectoryLibrary.from_files(f[0])
        tracks += lib.tracks
    return TrajectoryLibrary(tracks)


@lru_cache(maxsize=8)
def _lanelet_road(file: tuple[str, int, int]):
    return load_lanelet_road(file[0])


@lru_cache(maxsize=4)
def _city_road(params: CityParams, seed: int) -> CityRoad:
    return CityRoad(params, seed)


def _seeds(seed: int) -> tuple[int, np.random.Generator, np.random.Generator]:
    road_ss, traffic_ss, ego_ss = np.random.SeedSequence(seed).spawn(3)
    return (
        int(road_ss.generate_state(1)[0]),
        np.random.default_rng(traffic_ss),
        np.random.default_rng(ego_ss),
    )


def synthetic_tracks(scenario: Scenario) -> list[Track]:
    """Library tracks usable as human profiles (>= 2 s long, not longer than the limit)."""
    t = scenario.config.traffic
    tracks = library_for(scenario).select(
        min_duration=MIN_TRACK_SECONDS, max_length=t.max_vehicle_length
    )
    if not tracks:
        raise ScenarioError(
            f"{scenario.source}: traffic.library has no track of >= 2 s and <= "
            f"{t.max_vehicle_length} m (traffic.max_vehicle_length)"
        )
    return tracks


def road_lane_width(scenario: Scenario) -> float:
    """Lane width [m] of a generated road (3.5 m for recorded maps)."""
    return float(getattr(scenario.config.road, "lane_width", 3.5))


def _bounds(scenario: Scenario) -> SpeedBounds:
    t = scenario.config.traffic
    return SpeedBounds(t.v_min, t.v_max, t.a_max)


def _build_seamless(scenario: Scenario, seed: int) -> World:
    cfg = scenario.config
    rc: SeamlessRoadConfig = cfg.road
    road_seed, traffic_rng, _ = _seeds(seed)
    behind, ahead = cfg.traffic.window
    params = SeamlessParams(
        rc.lanes,
        rc.lane_width,
        rc.straight_fraction,
        rc.mean_curve_angle_deg,
        tuple(rc.curve_radius),
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
    traffic = SeamlessTraffic(road, tracks, count, _bounds(scenario), behind, ahead)
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


def _build_city(scenario: Scenario, seed: int) -> World:
    cfg = scenario.config
    rc: CityRoadConfig = cfg.road
    road_seed, traffic_rng, ego_rng = _seeds(seed)
    params = CityParams(
        rc.blocks_x,
        rc.blocks_y,
        rc.block_size,
        rc.jitter,
        rc.lanes_per_direction,
        rc.lane_width,
        rc.turn_radius,
        rc.turn_probability,
    )
    road = _city_road(params, rc.seed if rc.seed is not None else road_seed)
    ego = vehicle_params(cfg.ego.vehicle)
    length = max(cfg.ego.speed, ROUTE_MIN_SPEED) * cfg.simulation.duration + ROUTE_MARGIN
    route = road.random_route(ego_rng, length)
    start, heading = route.point_at(5.0)
    state = np.array([start[0], start[1], heading, cfg.ego.speed, 0.0])
    tracks = synthetic_tracks(scenario)
    radius = max(cfg.traffic.window)
    traffic = CityTraffic(road, tracks, cfg.traffic.participants, _bounds(scenario), radius)
    return World(road, traffic, ego, state, cfg.simulation.dt, partial(_fixed, route), traffic_rng)


def map_path(scenario: Scenario) -> Path:
    """The CommonRoad file of a recorded scenario's ``road.map``."""
    return _resolve(scenario, scenario.config.road.map, ("data", "ngsim", "commonroad-xml"), ".xml")


def scene_of(scenario: Scenario) -> str:
    """The scene a recorded scenario replays: ``road.scene``, or its map file's scene id."""
    return scenario.config.road.scene or scene_id(map_path(scenario))


def recorded_scene(scenario: Scenario) -> tuple[StaticRoad, list[Track]]:
    """The map and the tracks of a recorded scenario (cached)."""
    road = _lanelet_road(_stamped(map_path(scenario)))
    try:
        return road, library_for(scenario).scene(scene_of(scenario))
    except DataError as exc:
        if "scene" in scenario.config.traffic.library:
            raise
        raise DataError(
            f"{scenario.source}: {exc}; to replay the vehicles of the CommonRoad file itself, "
            "set traffic.library: [scene] (or give the .xml file as the scenario)"
        ) from None


def _build_recorded(scenario: Scenario, seed: int) -> World:
    cfg = scenario.config
    _, traffic_rng, ego_rng = _seeds(seed)
    road, tracks = recorded_scene(scenario)
    ego_track = _pick_ego_track(scenario, tracks, road, ego_rng)
    ego = vehicle_params(cfg.ego.vehicle, ego_track.length, ego_track.width)
    u = np.array([np.cos(ego_track.heading[0]), np.sin(ego_track.heading[0])])
    rear = np.array([ego_track.x[0], ego_track.y[0]]) - ego.center_offset * u
    state = np.array([rear[0], rear[1], ego_track.heading[0], ego_track.speed[0], 0.0])
    state[4] = initial_steering(ego_track, ego)
    route = Polyline(track_path(ego_track)[0])
    traffic = RecordedSceneTraffic(tracks, exclude=ego_track.track_id)
    return World(
        road, traffic, ego, state, cfg.simulation.dt, partial(_fixed, route), traffic_rng, ego_track
    )


def ego_candidates(
    scenario: Scenario, tracks: list[Track] | None = None, road: StaticRoad | None = None
) -> list[Track]:
    """The tracks of a recorded scene that can be the ego: at least 2 s long, not too long a
    vehicle, and inside the road (``tracks`` and ``road``: the scene's, if already loaded)."""
    if tracks is None or road is None:
        road, tracks = recorded_scene(scenario)
    unfit = unfit_experts(scene_of(scenario), tuple(tracks), road)
    longest = scenario.config.traffic.max_vehicle_length
    return [t for t in tracks if t.duration >= MIN_TRACK_SECONDS and t.length <= longest
            and t.track_id not in unfit]  # fmt: skip


def _pick_ego_track(scenario: Scenario, tracks, road: StaticRoad, rng) -> Track:
    """The ego's track: ``ego.track`` by id, or drawn from the seed among the fit tracks (at
    least 2 s long, not too long a vehicle, inside the road) of the scene (``"random"``) or of
    a list of ids."""
    cfg, scene = scenario.config, scene_of(scenario)
    wanted = cfg.ego.track
    if isinstance(wanted, str) and wanted != "random":
        match = [t for t in tracks if t.track_id == wanted]
        if not match:
            ids = ", ".join(t.track_id for t in tracks)
            raise ScenarioError(
                f"{scenario.source}: ego.track {wanted!r} is not in scene {scene!r}; tracks: {ids}"
            )
        return match[0]
    if isinstance(wanted, list):
        missing = sorted(set(wanted) - {t.track_id for t in tracks})
        if missing:
            raise ScenarioError(
                f"{scenario.source}: ego.track lists {len(missing)} track(s) not in scene "
                f"{scene!r}: {', '.join(missing[:10])}"
            )
    listed = set(wanted) if isinstance(wanted, list) else {t.track_id for t in tracks}
    fit = [t for t in ego_candidates(scenario, tracks, road) if t.track_id in listed]
    if not fit:
        which = "the listed tracks" if isinstance(wanted, list) else f"scene {scene!r}"
        raise ScenarioError(f"{scenario.source}: {which} have no track >= 2 s to use as ego")
    return fit[int(rng.integers(len(fit)))]


def initial_steering(track: Track, params: BicycleParams) -> float:
    """Steering angle [rad] matching the curvature of the first second of ``track``."""
    n = min(len(track.t), 11)
    dist = float(np.sum(np.hypot(np.diff(track.x[:n]), np.diff(track.y[:n]))))
    if dist < 1.0:
        return 0.0
    curvature = (track.heading[n - 1] - track.heading[0]) / dist
    delta = np.arctan(params.wheelbase * curvature)
    return float(np.clip(delta, -params.delta_max, params.delta_max))


#: An expert's recorded footprint must stay this far [m] inside the off-road tolerance, so
#: that tracking it with small errors does not count as leaving the road.
EXPERT_EDGE_MARGIN = 0.25


@lru_cache(maxsize=16)
def unfit_experts(scene: str, tracks: tuple[Track, ...], road: StaticRoad) -> frozenset[str]:
    """Tracks that cannot serve as the expert ego because of quirks of the recording: their
    footprint overlaps another's, or comes within :data:`EXPERT_EDGE_MARGIN` of counting as
    off the mapped road. The reference must be driveable without collision or leaving it."""
    import cv2

    bad = set()
    no_traffic = (np.zeros(0),) * 5
    for a in tracks:  # the same edge test as the world's
        checker = CollisionChecker(a.length, a.width, EDGE_TOLERANCE - EXPERT_EDGE_MARGIN)
        for k in range(len(a.t)):
            centre = np.array([a.x[k], a.y[k]])
            checker.set_boundaries(road.boundary_segments(), road.version, centre)
            if checker.check(centre, float(a.heading[k]), no_traffic, np.zeros(0, int)).boundaries:
                bad.add(a.track_id)
                break
    for i, a in enumerate(tracks):
        ta = np.round(a.t, 3)
        for b in tracks[i + 1 :]:
            tb = np.round(b.t, 3)
            for t in np.intersect1d(ta, tb):
                ka, kb = np.searchsorted(ta, t), np.searchsorted(tb, t)
                reach = 0.5 * (np.hypot(a.length, a.width) + np.hypot(b.length, b.width))
                if np.hypot(a.x[ka] - b.x[kb], a.y[ka] - b.y[kb]) > reach:
                    continue
                ra = ((a.x[ka], a.y[ka]), (a.length, a.width), np.rad2deg(a.heading[ka]))
                rb = ((b.x[kb], b.y[kb]), (b.length, b.width), np.rad2deg(b.heading[kb]))
                if cv2.rotatedRectangleIntersection(ra, rb)[0] != cv2.INTERSECT_NONE:
                    bad |= {a.track_id, b.track_id}
                    break
    return frozenset(bad)


WORLD_BUILDERS: dict[type, Callable[[Scenario, int], World]] = {
    SeamlessRoadConfig: _build_seamless,
    CityRoadConfig: _build_city,
    RecordedRoadConfig: _build_recorded,
}


_PRISTINE: OrderedDict[tuple[str, str, int], World] = OrderedDict()
_PRISTINE_SIZE = 64


def build_world(scenario: Scenario, seed: int = 0) -> World:
    """A fresh world for ``scenario``; the same seed always gives the same world.

    The first world built for a (scenario, seed) is kept untouched and later ones are copies
    of it (a copy costs a fraction of a build: warm resets). Objects that do not depend on
    the seed and never change (static maps, profile tables) are shared, not copied."""
    key = (scenario.config.model_dump_json(), str(scenario.base_dir), int(seed))
    pristine = _PRISTINE.get(key)
    if pristine is None:
        pristine = WORLD_BUILDERS[type(scenario.config.road)](scenario, int(seed))
        _PRISTINE[key] = pristine
        if len(_PRISTINE) > _PRISTINE_SIZE:
            _PRISTINE.popitem(last=False)
    else:
        _PRISTINE.move_to_end(key)
    return copy.deepcopy(pristine, {id(o): o for o in _shared_parts(pristine)})


def _shared_parts(world: World) -> list:
    """The parts of ``world`` that copies share: immutable (frozen settings, the last tick's
    result) or independent of the seed and never changed."""
    parts = [world.ego_params, world.last, world.traffic.fleet.p]
    if world.ego_track is not None:
        parts.append(world.ego_track)
    if isinstance(world.road, StaticRoad):
        parts.append(world.road)
    if isinstance(world.traffic, SyntheticTraffic):
        parts += [world.traffic.profiles, world.traffic.fleet.profiles]
    return parts


def _lane_centre(road: SeamlessRoad, lane: int) -> Polyline:
    return road.lanes[lane].centre


def _fixed(route: Polyline) -> Polyline:
    return route
