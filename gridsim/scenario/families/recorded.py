"""The recorded family: a CommonRoad lanelet map (:mod:`gridsim.road.lanelet`) with its
recorded vehicles replayed, one of them the ego (its track is the human reference)."""

from __future__ import annotations

import dataclasses
from functools import lru_cache, partial
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import Field

from gridsim import libm
from gridsim.errors import DataError, ScenarioError, UnfitEgoWarning, UnselectedScene, warn_data
from gridsim.road.base import StaticRoad
from gridsim.road.lanelet import load_lanelet_road
from gridsim.road.polyline import Polyline
from gridsim.scenario.checks import feet_hint, flawed_tracks, scene_report
from gridsim.scenario.family import Family, register_family
from gridsim.scenario.parts import (
    MIN_TRACK_SECONDS,
    fixed_route,
    library_for,
    map_path,
    seed_streams,
    stamped,
    vehicle_params,
)
from gridsim.scenario.schema import Scenario, Strict
from gridsim.traffic.commonroad import scene_id
from gridsim.traffic.sources import RecordedSceneTraffic, track_path
from gridsim.traffic.track import Track, ids_in_scene
from gridsim.vehicle.kinematics import BicycleParams, rear_axle_of
from gridsim.world import collision_kernels
from gridsim.world.collision import EDGE_TOLERANCE, CollisionChecker
from gridsim.world.overlaps import overlapping_tracks
from gridsim.world.world import World


class RecordedRoadConfig(Strict):
    """``road:`` of the recorded family: a CommonRoad map and the scene whose tracks replay."""

    type: Literal["recorded"]
    map: Annotated[str, Field(min_length=1, description="CommonRoad XML: builtin:NAME or a path")]
    scene: Annotated[
        str | None,
        Field(
            min_length=1,
            description="scenario_id of the tracks to replay; default: the map file's "
            "benchmarkID (or its file name without .xml)",
        ),
    ] = None


def scene_of(scenario: Scenario) -> str:
    """The scene a recorded scenario replays: ``road.scene``, or its map file's scene id."""
    return scenario.config.road.scene or _file_scene_id(stamped(map_path(scenario)))


@lru_cache(maxsize=64)
def _file_scene_id(file: tuple) -> str:
    """:func:`~gridsim.traffic.commonroad.scene_id` of the file ``file`` (:func:`stamped`):
    read once, not at every episode of a scene (it parses the file's head)."""
    return scene_id(file[0])


@lru_cache(maxsize=8)
def _lanelet_road(file: tuple):
    return load_lanelet_road(file[0])


def recorded_scene(scenario: Scenario, check: bool = True) -> tuple[StaticRoad, list[Track]]:
    """The map and the tracks of a recorded scenario (cached). With ``check``, an implausible
    scene is refused (:class:`DataError` listing its problems) and flawed tracks are named
    in a :class:`~gridsim.errors.DataWarning`: see
    :mod:`gridsim.scenario.checks`."""
    road, tracks = _scene(scenario)
    if check:
        report = scene_report(scenario, road, tracks)
        if report.problems:
            raise DataError(report.refusal(scenario.source))
        if report.warnings:  # shown once per message and place (Python's default filter)
            warn_data("\n".join(report.warnings))
        note = _unfit_ego_note(scenario, road, tracks)
        if note:
            warn_data(note, UnfitEgoWarning)
    return road, tracks


def data_report(scenario: Scenario):
    """The plausibility report of the scene's map and tracks
    (:func:`~gridsim.scenario.checks.scene_report`), without refusing anything."""
    road, tracks = recorded_scene(scenario, check=False)
    return _scene_report(scenario, road, tracks)


def _scene_report(scenario: Scenario, road: StaticRoad, tracks: list[Track]):
    """:func:`~gridsim.scenario.checks.scene_report`, and among its warnings
    :func:`_unfit_ego_note` or, with a random ego, how many of the scene's tracks are not
    drawn and why (``record`` drives them as the ego: a validation lists it)."""
    report = scene_report(scenario, road, tracks)
    if report.problems:
        return report
    note = _unfit_ego_note(scenario, road, tracks)
    if scenario.config.ego.track == "random":
        fit = {t.track_id for t in ego_candidates(scenario, tracks, road)}
        unfit = {t.track_id for t in tracks} - fit - report.flawed  # (flaws: warned each)
        if unfit:
            note = (f"{scenario.source}: {len(unfit)} of its {len(tracks)} tracks are not drawn "
                    f"as a random ego ({why_unfit(scenario, tracks, road, unfit)})")  # fmt: skip
    return dataclasses.replace(report, warnings=(*report.warnings, note)) if note else report


def _unfit_ego_note(scenario: Scenario, road: StaticRoad, tracks: list[Track]) -> str | None:
    """Why the track named as ``ego.track`` is one a random ego is not drawn from (it
    overlaps another, grazes a road edge, is a long vehicle: its episodes may end at once),
    or None."""
    wanted = scenario.config.ego.track
    if not isinstance(wanted, str) or wanted == "random":
        return None
    named = ego_track_ids(scenario, scene_of(scenario))
    track = next((t for t in tracks if t.track_id == named), None)
    if track is None:
        return None
    unfit = [why for why, test in _unfit_tests(scenario, tracks, road).items() if test(track)]
    unfit = [why for why in unfit if not why.startswith("implausible")]  # (a problem already)
    if not unfit:
        return None
    return (f"{scenario.source}: ego.track {named} is {'; '.join(unfit)}: not a track a random "
            "ego is drawn from (its episodes may end at once, or not as recorded)")  # fmt: skip


def _scene(scenario: Scenario) -> tuple[StaticRoad, list[Track]]:
    path = map_path(scenario)
    try:
        road = _lanelet_road(stamped(path))
    except DataError as exc:  # (a YAML's road.map: named; a CommonRoad file is its own map)
        if Path(scenario.source).resolve() == path.resolve():
            raise
        raise DataError(f"{scenario.source}: road.map: {exc}") from None
    library = library_for(scenario)
    try:
        return road, library.scene(scene_of(scenario))
    except DataError as exc:  # the library has no track of the map's scene
        if "scene" in scenario.config.traffic.library:
            given = scenario.config.road.scene
            if given is None:
                raise DataError(f"{scenario.source}: {exc}") from None
            own = _file_scene_id(stamped(path))
            raise DataError(
                f"{scenario.source}: road.scene {given!r} (set in this file or one it extends) "
                f"is not the scene of road.map {scenario.config.road.map} ({own!r}): {exc}; "
                "leave road.scene out to replay the map's own scene"
            ) from None
        raise DataError(
            f"{scenario.source}: {exc}; to replay the vehicles of the CommonRoad file itself, "
            "set traffic.library: [scene] (or give the .xml file as the scenario)"
        ) from None


def build(scenario: Scenario, seed: int) -> World:
    cfg = scenario.config
    _, traffic_rng, ego_rng = seed_streams(seed)
    road, tracks = recorded_scene(scenario)
    ego_track = _pick_ego_track(scenario, tracks, road, ego_rng)
    ego = vehicle_params(cfg.ego.vehicle, ego_track.length, ego_track.width)
    centre = np.array([ego_track.x[0], ego_track.y[0]])
    rear = rear_axle_of(centre, ego_track.heading[0], ego.center_offset)
    state = np.array([rear[0], rear[1], ego_track.heading[0], ego_track.speed[0], 0.0])
    state[4] = initial_steering(ego_track, ego)
    route = Polyline(track_path(ego_track)[0])
    # the traffic replays from the ego's first recorded time: the scene as the ego saw it
    traffic = RecordedSceneTraffic(tracks, exclude=ego_track.track_id,
                                   start_time=float(ego_track.t[0]),
                                   until=float(ego_track.t[-1]))  # fmt: skip
    return World(
        road,
        traffic,
        ego,
        state,
        cfg.simulation.dt,
        partial(fixed_route, route),
        traffic_rng,
        ego_track,
    )


def ego_candidates(
    scenario: Scenario, tracks: list[Track] | None = None, road: StaticRoad | None = None
) -> list[Track]:
    """The tracks of a recorded scene that can be the ego: at least 2 s long, not too long a
    vehicle, not flawed (:func:`~gridsim.scenario.checks.flawed_tracks`), and inside the road
    (``tracks`` and ``road``: the scene's, if already loaded)."""
    if tracks is None or road is None:
        road, tracks = recorded_scene(scenario)
    unfit = _unfit_tests(scenario, tracks, road)
    return [t for t in tracks if not any(test(t) for test in unfit.values())]


def _unfit_tests(scenario: Scenario, tracks, road: StaticRoad) -> dict:
    """Why a track of the scene cannot be the ego: a test per reason, by its wording."""
    flawed = flawed_tracks(tuple(tracks), road).keys()
    quirks = unfit_experts(scene_of(scenario), tuple(tracks), road)
    longest = scenario.config.traffic.max_vehicle_length
    fastest = scenario.config.ego.vehicle.v_max
    return {
        "of a pedestrian or bicycle": lambda t: not t.drivable_as_ego,
        f"shorter than {MIN_TRACK_SECONDS:g} s": lambda t: t.duration < MIN_TRACK_SECONDS,
        f"of a vehicle longer than {longest:g} m": lambda t: t.length > longest,
        "implausible (see the warning)": lambda t: t.track_id in flawed,
        "overlapping another or grazing a road edge": lambda t: t.track_id in quirks,
        f"faster than ego.vehicle.v_max {fastest:g} m/s (raise it to drive them)":
            lambda t: outruns_ego(scenario, t),
    }  # fmt: skip


def outruns_ego(scenario: Scenario, track: Track) -> bool:
    """Whether ``track`` drives faster than the scenario's ego may (``ego.vehicle.v_max``):
    an ego driving it falls behind the human, and what is measured against the human's
    future (labels, ``l1``) is measured from the wrong place."""
    return float(track.speed.max()) > scenario.config.ego.vehicle.v_max


def _pick_ego_track(scenario: Scenario, tracks, road: StaticRoad, rng) -> Track:
    """The ego's track: ``ego.track`` by id, or drawn from the seed among the fit tracks (at
    least 2 s long, not too long a vehicle, inside the road) of the scene (``"random"``) or of
    a list of ids."""
    scene = scene_of(scenario)
    wanted = ego_track_ids(scenario, scene)
    named = checked_ego_tracks(scenario, tracks, wanted, scene)
    if isinstance(wanted, str) and named:  # one id: that track, fit or not
        return next(t for t in tracks if t.track_id == wanted)
    listed = set(named) if named is not None else {t.track_id for t in tracks}
    fit = [t for t in ego_candidates(scenario, tracks, road) if t.track_id in listed]
    if not fit:
        which = "the listed tracks" if isinstance(wanted, list) else f"scene {scene!r}"
        verb = "have" if isinstance(wanted, list) else "has"
        raise DataError(f"{scenario.source}: {which} {verb} no track to use as the ego "
                        f"(of {len(listed & {t.track_id for t in tracks})}: "
                        f"{why_unfit(scenario, tracks, road, listed)})")  # fmt: skip
    return fit[int(rng.integers(len(fit)))]


def checked_ego_tracks(scenario: Scenario, tracks, wanted: str | list[str],
                       scene: str) -> list[str] | None:  # fmt: skip
    """The ids ``wanted`` (:func:`ego_track_ids`) as a list, each one of ``tracks`` (the
    scene's), or a :class:`ScenarioError` naming those that are not; None for ``"random"``."""
    if wanted == "random":
        return None
    have = {t.track_id for t in tracks}
    if isinstance(wanted, str):
        if wanted not in have:
            ids = ", ".join(t.track_id for t in tracks)
            raise ScenarioError(
                f"{scenario.source}: ego.track {wanted!r} is not in scene {scene!r}; tracks: "
                f"{ids}{_float_id_hint([wanted], have)}"
            )
        return [wanted]
    missing = sorted(set(wanted) - have)
    if missing:
        raise ScenarioError(
            f"{scenario.source}: ego.track lists {len(missing)} track(s) not in scene "
            f"{scene!r}: {', '.join(missing[:10])}{_float_id_hint(missing, have)}"
        )
    return list(wanted)


def _float_id_hint(missing: list[str], have: set[str]) -> str:
    """A hint when the ids ``missing`` are in ``have`` as floats ("381" as "381.0": a track
    file whose id column was saved as floats, by a spreadsheet or pandas)."""
    if all(f"{m}.0" in have for m in missing):
        return (
            f" (the file's ids are floats: {missing[0]!r} is there as '{missing[0]}.0'; "
            "write its id column as integers, or name the tracks as the file does)"
        )
    return ""


def ego_track_ids(scenario: Scenario, scene: str | None = None) -> str | list[str]:
    """``ego.track`` as ids of the scenario's own scene (``scene``, if already known):
    ``"random"``, one id or a list of ids, the ``SCENE/ID`` names of other scenes left out
    (a collection's scenes share one list); a :class:`ScenarioError` if it names no track of
    this scene but tracks of others."""
    wanted = scenario.config.ego.track
    if wanted == "random":
        return wanted
    scene = scene_of(scenario) if scene is None else scene
    own, foreign = ids_in_scene([wanted] if isinstance(wanted, str) else wanted, scene)
    if foreign and not own:
        raise UnselectedScene(f"{scenario.source}: ego.track names no track of scene "
                              f"{scene!r}, only of other scenes: {', '.join(foreign[:5])}"
                              + (" ..." if len(foreign) > 5 else ""))  # fmt: skip
    return own[0] if isinstance(wanted, str) else own


def why_unfit(scenario: Scenario, tracks, road: StaticRoad, listed: set[str]) -> str:
    """Why each of the ``listed`` tracks cannot be the ego, counted by reason ("3 of a vehicle
    longer than 6 m, 1 overlapping ...")."""
    mine = [t for t in tracks if t.track_id in listed]
    if not mine:
        return "none listed"
    counts = {
        why: sum(map(test, mine)) for why, test in _unfit_tests(scenario, tracks, road).items()
    }
    said = ", ".join(f"{n} {why}" for why, n in counts.items() if n)
    hint = feet_hint(tracks, "the scene's")  # not only the listed ones': feet are a file's unit
    return f"{said}; {hint}" if hint else said


def initial_steering(track: Track, params: BicycleParams) -> float:
    """Steering angle [rad] matching the curvature of the first second of ``track``."""
    n = min(len(track.t), 11)
    dist = float(np.sum(np.hypot(np.diff(track.x[:n]), np.diff(track.y[:n]))))
    if dist < 1.0:
        return 0.0
    curvature = (track.heading[n - 1] - track.heading[0]) / dist
    delta = libm.arctan(params.wheelbase * curvature)
    return float(np.clip(delta, -params.delta_max, params.delta_max))


#: An expert's recorded footprint must stay this far [m] inside the off-road tolerance, so
#: that tracking it with small errors does not count as leaving the road.
EXPERT_EDGE_MARGIN = 0.25


@lru_cache(maxsize=16)
def unfit_experts(scene: str, tracks: tuple[Track, ...], road: StaticRoad) -> frozenset[str]:
    """Tracks that cannot serve as the expert ego because of quirks of the recording: their
    footprint overlaps another's (:func:`~gridsim.world.overlaps.overlapping_tracks`), or
    comes within :data:`EXPERT_EDGE_MARGIN` of counting as off the mapped road. The reference
    must be driveable without collision or leaving it. Time and memory grow linearly with the
    scene's samples."""
    bad = {tracks[i].track_id for i in overlapping_tracks(tracks)}
    return frozenset(bad | _near_edge(tracks, road))


def _near_edge(tracks: tuple[Track, ...], road: StaticRoad) -> set[str]:
    """Tracks whose footprint reaches over a road edge by more than the world's off-road
    tolerance less :data:`EXPERT_EDGE_MARGIN`: the world's edge test (pymunk), on the
    samples whose core box comes within ``collision_kernels.APART`` of an edge (all samples
    at once: ``collision_kernels.edges_near_boxes``); the others cannot touch one."""
    tolerance = EDGE_TOLERANCE - EXPERT_EDGE_MARGIN
    checkers = [CollisionChecker(a.length, a.width, tolerance) for a in tracks]
    counts = [len(a.t) for a in tracks]
    core = np.repeat([c.core for c in checkers], counts, axis=0)
    reach = np.repeat([c.broad_phase_data()[4] for c in checkers], counts)
    x, y, psi = (np.concatenate([getattr(a, k) for a in tracks]) for k in ("x", "y", "heading"))
    segments = np.ascontiguousarray(road.boundary_segments(), np.float64)
    near = collision_kernels.edges_near_boxes(x, y, psi, 0.5 * core[:, 0], 0.5 * core[:, 1],
                                              reach, segments, collision_kernels.APART)  # fmt: skip
    first = np.concatenate([[0], np.cumsum(counts)])
    bad = set()
    no_traffic = (np.zeros(0),) * 5
    for i, (a, checker) in enumerate(zip(tracks, checkers, strict=True)):
        for k in np.flatnonzero(near[first[i] : first[i + 1]]).tolist():
            centre = np.array([a.x[k], a.y[k]])
            checker.set_boundaries(segments, road.version, centre)
            if checker.check(centre, float(a.heading[k]), no_traffic, np.zeros(0, int)).boundaries:
                bad.add(a.track_id)
                break
    return bad


FAMILY = register_family(Family(
    RecordedRoadConfig,
    build,
    # the recorded traffic's speeds (NGSIM: up to about 25 m/s)
    defaults={
        # (ego.speed: the track's; 0 here, so that a slow ego.vehicle.v_max is not refused)
        "ego": {"speed": 0.0, "vehicle": {"v_max": 25.0, "a_max": 3.0}},
        "env": {"speed_range": [0.0, 30.0]},
    },
    recorded=True,
    data_report=data_report,
    ignores=dict.fromkeys(("traffic.participants", "traffic.window", "traffic.v_min",
                           "traffic.v_max", "traffic.a_max", "ego.lane", "ego.speed"),
                          "recorded scenes take their traffic, lanes and the ego's start from "
                          "the recording")
    | dict.fromkeys(("ego.vehicle.length", "ego.vehicle.width"),
                    "the ego takes the size of the track it drives"),
))  # fmt: skip
