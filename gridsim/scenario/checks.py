"""Plausibility checks of recorded scenes, for mistakes that load without error but make every
episode meaningless: tracks that belong to another map, time stamps in the wrong unit, and
scenes too short for the planning horizon.

Each problem is one line naming the file, the track and the numbers; ``gridsim validate``
reports them all (:func:`scenario_problems`). Thresholds are module constants.
"""

from __future__ import annotations

import numpy as np

from gridsim.road.base import StaticRoad
from gridsim.scenario.families.recorded import recorded_scene
from gridsim.scenario.loader import Scenario
from gridsim.scenario.schema import RecordedRoadConfig
from gridsim.traffic.track import Track

#: A track is on another map when more than this share of its positions is off the drivable
#: area (the shipped scenes: 0 %; maps are cropped, so a few positions may lie beyond them).
MAX_OFF_MAP = 0.2
#: Speeds implied by positions and time stamps must agree with the recorded speeds within this
#: factor (median over moving samples): time in steps of 0.1 s instead of seconds gives 0.1.
SPEED_RATIO = 2.0
#: Samples counted by the speed comparison: recorded speed above this [m/s].
MOVING = 1.0
#: Implied speeds above this [m/s] (95th percentile) are implausible for road vehicles.
MAX_SPEED = 70.0
#: Implied accelerations above this [m/s^2] (median; the shipped tracks' is at most 4.5,
#: from noisy positions) are implausible.
MAX_ACCEL = 15.0


def track_problems(track: Track, road: StaticRoad | None = None) -> list[str]:
    """Problems of one track: positions off ``road`` (if given) and time stamps that imply
    implausible speeds or accelerations, or speeds other than the recorded ones."""
    where = f"{track.source or '<tracks>'}: track {track.track_id} of scene {track.scenario_id}"
    out = []
    n = len(track.t)
    if road is not None:
        off = int(np.count_nonzero(~road.is_drivable(np.stack([track.x, track.y], axis=1))))
        if off > MAX_OFF_MAP * n:
            out.append(
                f"{where}: {off} of its {n} positions ({off / n:.0%}) are off the map's drivable "
                f"area (at most {MAX_OFF_MAP:.0%}); does the track belong to this map?"
            )
    dt = np.diff(track.t)
    implied = np.hypot(np.diff(track.x), np.diff(track.y)) / dt
    recorded = 0.5 * (track.speed[1:] + track.speed[:-1])
    moving = recorded > MOVING
    if np.count_nonzero(moving) >= 2:
        ratio = float(np.median(implied[moving] / recorded[moving]))
        if not 1.0 / SPEED_RATIO <= ratio <= SPEED_RATIO:
            out.append(
                f"{where}: positions and time stamps imply {np.median(implied[moving]):.3g} m/s "
                f"where speed_mps says {np.median(recorded[moving]):.3g} m/s (median, ratio "
                f"{ratio:.3g}); time stamps must be in seconds (time step {np.median(dt):.3g})"
            )
    fast = float(np.percentile(implied, 95))
    if fast > MAX_SPEED:
        out.append(
            f"{where}: positions and time stamps imply {fast:.3g} m/s (95th percentile; at most "
            f"{MAX_SPEED:g}); are time stamps in seconds and positions in metres?"
        )
    if n >= 3:
        accel = np.abs(np.diff(implied)) / (0.5 * (dt[1:] + dt[:-1]))
        typical = float(np.median(accel))
        if typical > MAX_ACCEL:
            out.append(
                f"{where}: positions and time stamps imply accelerations of {typical:.3g} m/s^2 "
                f"(median; at most {MAX_ACCEL:g}); are time stamps in seconds?"
            )
    return out


def scene_problems(scenario: Scenario, road: StaticRoad, tracks: list[Track]) -> list[str]:
    """Problems of a recorded scene: of its tracks, and a scene (or a chosen ego track)
    shorter than the planning horizon."""
    out = []
    for tr in tracks:
        out += track_problems(tr, road)
    env = scenario.config.env
    need = env.horizon_time
    longest = max(tracks, key=lambda t: t.duration)
    if longest.duration < need:
        out.append(
            f"{longest.source or scenario.source}: scene {longest.scenario_id} lasts "
            f"{longest.duration:.3g} s (its longest track, {longest.track_id}); the horizon "
            f"needs {need:.3g} s (env.horizon x env.setpoint_period)"
        )
    wanted = scenario.config.ego.track
    chosen = {wanted} if isinstance(wanted, str) else set(wanted)
    for tr in tracks:
        if tr.track_id in chosen and tr.duration < need:
            out.append(
                f"{scenario.source}: ego.track {tr.track_id} lasts {tr.duration:.3g} s; "
                f"the horizon needs {need:.3g} s (env.horizon x env.setpoint_period)"
            )
    return out


def scenario_problems(scenario: Scenario) -> list[str]:
    """Plausibility problems of ``scenario`` (none for generated roads)."""
    if not isinstance(scenario.config.road, RecordedRoadConfig):
        return []
    road, tracks = recorded_scene(scenario)
    return scene_problems(scenario, road, tracks)
