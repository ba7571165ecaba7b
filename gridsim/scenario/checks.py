"""Plausibility checks of recorded scenes, for mistakes that load without error but make every
episode meaningless: tracks that belong to another map, time stamps in the wrong unit, and
scenes too short for the planning horizon.

A track with such a flaw (:func:`track_problems`) is a **warning**: it stays in the scene as
traffic but is not offered as the ego. When most of a scene's tracks have one
(:data:`MAX_FLAWED_SHARE`), the file is wrong as a whole (tracks of another map, time in
steps): that is a **problem**, and the scene is refused by ``gym.make``, ``record``, ``train``,
``evaluate`` and ``gridsim validate`` alike. Each line names the file, the track and the
numbers. Thresholds are module constants. (Impossible data, such as non-finite values or
jumps no vehicle can make, is dealt with earlier, when the tracks are read:
:func:`gridsim.traffic.track.track_data_problem`; a CSV's impossible tracks are left out,
or the file refused when most are: :data:`gridsim.traffic.track.MAX_IMPOSSIBLE_SHARE`.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from gridsim.outputs import counted
from gridsim.road.base import StaticRoad
from gridsim.scenario.schema import Scenario
from gridsim.traffic.track import Track, ids_in_scene

#: A track is on another map when more than this share of its positions is off the drivable
#: area (the shipped scenes: 0 %; maps are cropped, so a few positions may lie beyond them).
MAX_OFF_MAP = 0.2
#: A scene whose tracks are flawed in more than this share is refused (below it, the flawed
#: tracks are kept as traffic and not offered as the ego).
MAX_FLAWED_SHARE = 0.5
#: A file of a scene of several is refused on its own (most of its tracks flawed) only with
#: at least this many flawed tracks: one odd track in a file of its own is kept as traffic.
MIN_FLAWED_FILE = 3
#: Speeds implied by positions and time stamps must agree with the recorded speeds within this
#: factor (median over moving samples): time in steps of 0.1 s instead of seconds gives 0.1.
SPEED_RATIO = 2.0
#: Samples counted by the speed comparison: recorded speed above this [m/s].
MOVING = 1.0
#: The direction of travel must agree with the recorded heading within this angle [deg]
#: (median over moving samples): headings in degrees, or another convention, do not.
MAX_HEADING_ERROR = 45.0
#: A heading the same at every sample is a column left unfilled (zeros, say) where the
#: direction of travel is farther off than this [deg] (median): on a road at 43 degrees a
#: heading of 0 passes :data:`MAX_HEADING_ERROR`.
CONSTANT_HEADING_ERROR = 15.0
#: Implied speeds above this [m/s] (95th percentile) are implausible for road vehicles.
MAX_SPEED = 70.0
#: Implied accelerations above this [m/s^2] (median; the shipped tracks' is at most 4.5,
#: from noisy positions) are implausible.
MAX_ACCEL = 15.0
#: A position is a glitch when the velocity turns by more than this [m/s^2] at it (the
#: shipped tracks' largest, from position noise, is 48) ...
GLITCH_ACCEL = 100.0
#: ... and it lies more than this [m] off the line between its neighbours (shipped: 0.24).
GLITCH_OFFSET = 0.5


def track_problems(track: Track, road: StaticRoad | None = None) -> list[str]:
    """Flaws of one track: positions off ``road`` (if given), time stamps that imply
    implausible speeds or accelerations, or speeds other than the recorded ones, and
    positions that leap off their neighbours (glitches)."""
    where = track.where
    out = []
    n = len(track.t)
    if road is not None:
        off = int(np.count_nonzero(~road.is_drivable(np.stack([track.x, track.y], axis=1))))
        if off > MAX_OFF_MAP * n:
            out.append(
                f"{where}: {off} of its {n} positions ({off / n:.0%}) are off the map's drivable "
                f"area (at most {MAX_OFF_MAP:.0%})"
            )
    if track.width > track.length:
        out.append(f"{where}: it is {track.width:.3g} m wide and {track.length:.3g} m long: are "
                   "its length and width swapped?")  # fmt: skip
    dt = np.diff(track.t)
    implied = np.hypot(np.diff(track.x), np.diff(track.y)) / dt
    recorded = 0.5 * (track.speed[1:] + track.speed[:-1])
    moving = recorded > MOVING
    if np.count_nonzero(moving) >= 2:
        ratio = float(np.median(implied[moving] / recorded[moving]))
        if not 1.0 / SPEED_RATIO <= ratio <= SPEED_RATIO:
            why = _unit_hint(ratio) or (
                f"time stamps must be in seconds (its time step is {np.median(dt):.3g} s: "
                "a CSV's time column, a CommonRoad file's timeStepSize)"
            )
            out.append(
                f"{where}: positions and time stamps imply {np.median(implied[moving]):.3g} m/s "
                f"where its recorded speeds say {np.median(recorded[moving]):.3g} m/s (median, "
                f"ratio {ratio:.3g}); {why}"
            )
    by_position = implied > MOVING  # (a speed column of zeros, or left empty as 0)
    if np.count_nonzero(by_position) >= 5 and float(np.median(recorded[by_position])) < 0.5 * (
        float(np.median(implied[by_position]))
    ):
        out.append(
            f"{where}: its positions move at {np.median(implied[by_position]):.3g} m/s (median) "
            f"where its recorded speeds say {np.median(recorded[by_position]):.3g} m/s; is its "
            "speed column in m/s, and filled in?"
        )
    if np.count_nonzero(moving) >= 2:
        travel = np.arctan2(np.diff(track.y), np.diff(track.x))[moving]
        heading = 0.5 * (track.heading[1:] + track.heading[:-1])[moving]
        error = _degrees_off(travel, heading)
        constant = np.ptp(track.heading) == 0  # one value throughout: a column left unfilled?
        if error > MAX_HEADING_ERROR:
            # the direction of the same motion with x and y swapped
            error_swapped = _degrees_off(np.pi / 2 - travel, heading)
            hint = (" (or are its x and y swapped? with them swapped it drives "
                    f"{error_swapped:.0f} degrees off)" if error_swapped < MAX_HEADING_ERROR
                    else "")  # fmt: skip
            if constant:
                hint += (
                    f" (it is {track.heading[0]:.3g} rad at every sample: is its heading "
                    "column filled in?)"
                )
            out.append(
                f"{where}: it drives {error:.0f} degrees off its recorded heading (median; at "
                f"most {MAX_HEADING_ERROR:g}); headings must be in radians, counter-clockwise "
                f"from +x{hint}"
            )
        elif error > CONSTANT_HEADING_ERROR and constant:
            out.append(
                f"{where}: its recorded heading is {track.heading[0]:.3g} rad at every sample "
                f"while it drives {error:.0f} degrees off it (median); is its heading column "
                "filled in?"
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
        else:
            out += _glitches(track)
    return out


#: m: tracks whose median vehicle is longer and wider than these are in feet, not metres (a
#: car is about 4.5 x 1.8 m, 15 x 6 ft; a truck in metres is not 3 m wide)
FEET_LENGTH, FEET_WIDTH = 9.0, 3.0


def feet_hint(tracks: list[Track], whose: str = "the") -> str:
    """A hint that the sizes (and so the positions) of ``tracks`` are in feet, if their median
    size says so; "" if not. ``whose`` starts it ("the scene's median vehicle length ...")."""
    lengths, widths = [t.length for t in tracks], [t.width for t in tracks]
    if lengths and np.median(lengths) > FEET_LENGTH and np.median(widths) > FEET_WIDTH:
        return (
            f"{whose} median vehicle length is {np.median(lengths):.3g} m: are sizes and "
            "positions in metres (not feet)?"
        )
    return ""


#: Implied over recorded speed, when a unit is wrong, and what to say: speeds in km/h or
#: mph, positions in feet (with speeds in m/s).
_UNIT_RATIOS = (
    (1 / 3.6, "its speeds must be in m/s (km/h / 3.6)"),
    (0.3048, "its speeds must be in m/s (ft/s x 0.3048)"),
    (0.44704, "its speeds must be in m/s (mph x 0.44704)"),
    (1 / 0.3048, "its positions must be in metres (feet x 0.3048)"),
)


def _unit_hint(ratio: float) -> str | None:
    """What a ratio of implied over recorded speed says about the units: the nearest of
    :data:`_UNIT_RATIOS` within 10 % (km/h and ft/s lie 10 % apart), if any."""
    off, why = min((abs(math.log(ratio / r)), why) for r, why in _UNIT_RATIOS)
    return why if off < math.log(1.1) else None


def _degrees_off(direction: np.ndarray, heading: np.ndarray) -> float:
    """The median angle [deg] between two arrays of directions [rad], wrapped to [0, 180]."""
    return float(np.degrees(np.median(np.abs(np.angle(np.exp(1j * (direction - heading)))))))


def _glitches(track: Track) -> list[str]:
    """A flaw naming the positions that leap off their neighbours and back (or jump and stay:
    both ends are found): a turn of the velocity faster than :data:`GLITCH_ACCEL`, at a
    position more than :data:`GLITCH_OFFSET` off the line between its neighbours."""
    t, x, y = track.t, track.x, track.y
    dt = np.diff(t)
    vx, vy = np.diff(x) / dt, np.diff(y) / dt
    turn = np.hypot(np.diff(vx), np.diff(vy)) / (0.5 * (dt[1:] + dt[:-1]))
    w = dt[:-1] / (dt[:-1] + dt[1:])  # where each inner sample falls between its neighbours
    off = np.hypot(x[1:-1] - (x[:-2] + w * (x[2:] - x[:-2])),
                   y[1:-1] - (y[:-2] + w * (y[2:] - y[:-2])))  # fmt: skip
    bad = np.flatnonzero((turn > GLITCH_ACCEL) & (off > GLITCH_OFFSET)) + 1
    if not len(bad):
        return []
    k = int(bad[np.argmax(off[bad - 1])])
    more = f", and {len(bad) - 1} other position(s) beside it or elsewhere" if len(bad) > 1 else ""
    return [f"{track.where}: its position at t = {t[k]:.6g} s leaps {off[k - 1]:.3g} m off the "
            f"line between its neighbours (the velocity turns at {turn[k - 1]:.3g} m/s^2 there; "
            f"at most {GLITCH_ACCEL:g}){more}: a glitch in the recording?"]  # fmt: skip


@lru_cache(maxsize=16)
def flawed_tracks(
    tracks: tuple[Track, ...], road: StaticRoad | None = None
) -> dict[str, list[str]]:
    """The flaws of each flawed track of a scene (on ``road``'s map, if given), by track id
    (cached per scene)."""
    out = {}
    for tr in tracks:
        problems = track_problems(tr, road)
        if problems:
            out[tr.track_id] = problems
    return out


@dataclass(frozen=True)
class SceneReport:
    """What the checks found in a recorded scene: ``problems`` refuse it; ``warnings`` name
    the flawed tracks kept as traffic only (``flawed``: their ids)."""

    problems: tuple[str, ...]
    warnings: tuple[str, ...]
    flawed: frozenset[str]
    #: what was checked, as the refusal names it
    checked: str = "recorded scene"

    def refusal(self, source: str) -> str:
        """The error message refusing the scene of ``source`` for its :attr:`problems`."""
        lines = "\n".join(f"  - {p}" for p in self.problems)
        found = counted(len(self.problems), "problem")
        return f"{source}: implausible {self.checked} ({found}):\n{lines}"


def _alone_in_time(tracks: list[Track], source: str) -> list[str]:
    """A warning when most tracks of a scene of several share no moment with any other (as
    the ego, such a track meets no traffic: recordings with different time origins put in
    one scene?)."""
    if len(tracks) < 2:
        return []
    order = np.argsort([t.t[0] for t in tracks], kind="stable")
    start = np.array([tracks[k].t[0] for k in order])
    end = np.array([tracks[k].t[-1] for k in order])
    # by start time, a track meets an earlier one iff the latest end before it reaches its
    # start, and a later one iff the next start comes before its end (n log n, not n^2)
    before = np.concatenate(([-np.inf], np.maximum.accumulate(end)[:-1]))
    after = np.concatenate((start[1:], [np.inf]))
    alone = np.sort(order[(before < start) & (after > end)])
    if len(alone) <= MAX_FLAWED_SHARE * len(tracks):
        return []
    named = ", ".join(tracks[k].track_id for k in alone[:5]) + (", ..." if len(alone) > 5 else "")
    return [f"{source}: {len(alone)} of the {len(tracks)} tracks of scene "
            f"{tracks[0].scenario_id} share no moment with any other ({named}): as the ego they "
            "meet no traffic; are their time stamps from one clock?"]  # fmt: skip


#: s: a scene sampled this coarsely (the median of its tracks' median time steps) is asked
#: whether its time column counts frames (recordings of vehicles run at 10-30 Hz).
COARSE_STEP = 0.5


def _coarse_time(tracks: list[Track], source: str) -> list[str]:
    """A warning when the tracks are sampled every :data:`COARSE_STEP` seconds or more: time
    in frame numbers with speeds per frame passes every other check (positions and speeds
    agree), and would replay the scene that many times too slowly."""
    steps = [float(np.median(np.diff(t.t))) for t in tracks if len(t.t) > 1]
    step = float(np.median(steps)) if steps else 0.0
    if step < COARSE_STEP:
        return []
    return [f"{source}: its tracks are sampled every {step:.3g} s (median): is the time "
            "column in seconds, not frame numbers? (vehicle recordings run at 10-30 Hz: "
            "NGSIM 10, highD 25); the data is used as given"]  # fmt: skip


#: A track's time stamps jitter when a step differs from its median step by more than
#: JITTER[0] seconds (rounding of a 10-30 Hz clock's stamps is far below) and by less than
#: JITTER[1] of that step (more: a gap or another rate, other checks' matter).
JITTER = (5e-4, 0.25)


def _jittered_time(tracks: list[Track], source: str) -> list[str]:
    """A warning when tracks' time stamps jitter around their step (a logger's clock): a
    vehicle comes in and goes at the first tick at or after its first and last stamps, so a
    few milliseconds move it a tick (a jitter of 3 ms on US-101 changed up to 10,355 cells
    of a window's grids and 5 of its 663 windows, silently)."""
    worst, jittery, step_of = 0.0, 0, 0.0
    for t in tracks:
        if len(t.t) < 3:
            continue
        steps = np.diff(t.t)
        step = float(np.median(steps))
        off = np.abs(steps - step)
        off = off[off < JITTER[1] * step]
        if len(off) and off.max() > JITTER[0]:
            jittery += 1
            if off.max() > worst:
                worst, step_of = float(off.max()), step
    if not jittery:
        return []
    return [f"{source}: the time stamps of {jittery} of its {len(tracks)} tracks jitter by up "
            f"to {1000 * worst:.3g} ms around their {step_of:.2g} s step (a logger's clock?): a "
            "vehicle comes in and goes at the first tick at or after its first and last "
            "stamps, so such jitter moves it a tick; the data is used as given (round the "
            "stamps to the recording's step to replay it on the clock)"]  # fmt: skip


def _verdict(
    flawed: dict[str, list[str]], total: int, source: str, what: str, kept: str
) -> tuple[list[str], list[str]]:
    """``(problems, warnings)`` of ``flawed`` tracks among ``total``: one problem listing
    them when most are (``what`` they are), else a warning per flaw (what is done with the
    track: ``kept``)."""
    lines = [p for problems in flawed.values() for p in problems]
    if len(flawed) > MAX_FLAWED_SHARE * total:
        more = [f"... and {len(lines) - 10} more"] if len(lines) > 10 else []
        return ["\n    ".join([f"{source}: {len(flawed)} of its {total} tracks are {what}:",
                               *lines[:10], *more])], []  # fmt: skip
    return [], [f"{line}; {kept}" for line in lines]


def library_report(tracks: list[Track], source: str) -> SceneReport:
    """Checks of the library tracks a generated road draws its traffic's and human's speed
    profiles from (``source``: the scenario): their flaws without a map (time stamps and
    speeds in other units, headings in degrees, glitches). A problem when most tracks have
    one, else a warning per flawed track, which is not used."""
    flawed = flawed_tracks(tuple(tracks))
    problems, warnings = _verdict(flawed, len(tracks), source,
                                  "implausible or in the wrong units (are time stamps in "
                                  "seconds, speeds in m/s and headings in radians?)",
                                  "not used as a speed profile")  # fmt: skip
    warnings += _coarse_time(tracks, source)
    return SceneReport(tuple(problems), tuple(warnings), frozenset(flawed),
                       "traffic.library (its tracks give the speed profiles)")  # fmt: skip


def scene_report(scenario: Scenario, road: StaticRoad, tracks: list[Track]) -> SceneReport:
    """Checks of a recorded scene: its tracks' flaws (a problem when most tracks have one,
    else warnings), a scene (or the one track named as ``ego.track``) shorter than the
    planning horizon, and a named ego track that is flawed."""
    need = scenario.config.env.horizon_time
    scene = _scene_checks(tuple(tracks), road, tracks[0].source or scenario.source, need)
    problems, warnings, flawed = list(scene.problems), list(scene.warnings), scene.flawed
    wanted = scenario.config.ego.track  # one named track must be usable (a list is filtered)
    if isinstance(wanted, str):  # its id in this scene (SCENE/ID names another's: no check)
        wanted = next(iter(ids_in_scene([wanted], tracks[0].scenario_id)[0]), None)
    named = scene.by_id.get(wanted) if isinstance(wanted, str) else None
    if named is not None and named.duration < need:
        problems.append(
            f"{scenario.source}: ego.track {wanted} lasts {named.duration:.3g} s; "
            f"the horizon needs {need:.3g} s (env.horizon x env.setpoint_period)"
        )
    elif named is not None and wanted in flawed:
        problems.append(f"{scenario.source}: ego.track {wanted} cannot be the ego: "
                        f"{flawed[wanted][0]}")  # fmt: skip
    return SceneReport(tuple(problems), tuple(warnings), frozenset(flawed))


class _SceneChecks(NamedTuple):
    problems: tuple[str, ...]
    warnings: tuple[str, ...]
    flawed: dict  # track id -> its flaws
    by_id: dict  # track id -> track


@lru_cache(maxsize=16)
def _scene_checks(tracks: tuple[Track, ...], road: StaticRoad, source: str,
                  need: float) -> _SceneChecks:  # fmt: skip
    """The checks of :func:`scene_report` that do not depend on the ego track, made once per
    scene (``record`` builds a world per ego track: a scene of N tracks checked per world
    cost N^2); ``need``: the planning horizon [s]."""
    flawed = flawed_tracks(tracks, road)
    what = ("implausible for this map or in the wrong units (does the map belong to the "
            "tracks? are time stamps in seconds and positions in metres?)")  # fmt: skip
    problems, warnings = _verdict(flawed, len(tracks), source, what,
                                  "kept as traffic, not offered as the ego")  # fmt: skip
    files: dict[str, list[Track]] = {}  # a file of another map beside good ones: refused
    for t in tracks:  # too, not diluted by their tracks (a few flawed tracks of a small file
        files.setdefault(t.source or source, []).append(t)  # are kept as traffic)
    for file, mine in files.items() if not problems and len(files) > 1 else ():
        ids = {t.track_id for t in mine}
        own = {k: v for k, v in flawed.items() if k in ids}
        if len(own) >= MIN_FLAWED_FILE:
            problems += _verdict(own, len(mine), file, what, "")[0]
    if problems:  # (the tracks' lines are in the refusal)
        warnings = []
    longest = max(tracks, key=lambda t: t.duration)
    if longest.duration < need:
        problems.append(
            f"{longest.source or source}: scene {longest.scenario_id} lasts "
            f"{longest.duration:.3g} s (its longest track, {longest.track_id}); the horizon "
            f"needs {need:.3g} s (env.horizon x env.setpoint_period)"
        )
    warnings += _alone_in_time(list(tracks), source) + _coarse_time(list(tracks), source)
    warnings += _jittered_time(list(tracks), source)
    by_id: dict = {}
    for t in tracks:  # (the first of an id, as a search would find)
        by_id.setdefault(t.track_id, t)
    return _SceneChecks(tuple(problems), tuple(warnings), flawed, by_id)
