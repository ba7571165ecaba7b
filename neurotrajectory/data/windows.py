"""Datasets of labelled windows: what an ego saw and where the human then drove.

A window is taken at a decision time ``t`` of a GridSim-v0 episode in which the ego drives
the reference (the human trajectory: recorded on NGSIM scenes, a human profile on generated
roads). It holds the observation (``tau_i`` grids, ego state, destination), the next
``tau_o`` reference set-points (the label), the discrete command they imply
(:mod:`neurotrajectory.data.commands`), the ego's size, and the *track* it came from (an NGSIM
vehicle or a simulated episode), so that train and test sets never share a track.

On disk a dataset is a folder of shards (:mod:`neurotrajectory.data.storage`); ``record``
writes one as it records (:mod:`neurotrajectory.data.recording`).

Scenario groups (:data:`GROUPS`): ``seamless`` and ``inner_city`` are GridSim's generated
scenarios; ``highway`` (US-101) and ``urban`` (Lankershim, Peachtree) drive every recorded
NGSIM track of the shipped scenes in turn as the ego, removed from the replayed traffic.
"""

from __future__ import annotations

import difflib
import json
import math
import platform
import warnings
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from gridsim.envs.episode import run_episode
from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.errors import GridSimError, ScenarioError, UnfitEgoWarning, warn_data
from gridsim.frames import EGO_COS, EGO_SIN, EGO_SPEED, ego_heading, setpoint_times
from gridsim.outputs import counted, named
from gridsim.policies import Reference
from gridsim.scenario.checks import flawed_tracks
from gridsim.scenario.collection import (
    load_collection,
    load_usable,
    report_skipped,
    scenario_files,
)
from gridsim.scenario.families.recorded import (
    checked_ego_tracks,
    ego_candidates,
    ego_track_ids,
    outruns_ego,
    recorded_scene,
    scene_of,
    why_unfit,
)
from gridsim.scenario.family import family_of
from gridsim.scenario.loader import MISSING, deep_merge, load_scenario, value_at
from gridsim.scenario.parts import library_for
from gridsim.seeding import Salt, stream
from gridsim.traffic.track import scene_ids, track_name
from neurotrajectory.data.commands import implied_commands

FORMAT_VERSION = 1
#: How windows are taken, for an interrupted recording to go on only under the same rules
#: (2: a recorded track's episode drives on past its destination, and its windows whose
#: label starts behind the ego are left out; 1: before 2026-12-07).
WINDOW_RULES = 2

#: Scenario groups of the evaluation and the built-in scenarios they consist of.
GROUPS: dict[str, tuple[str, ...]] = {
    "seamless": ("seamless",),
    "inner_city": ("inner_city",),
    "highway": ("us101_3_3", "us101_4_1"),
    "urban": ("lankershim_1_1", "peachtree_4_8"),
}
#: Where each group's reference trajectories come from.
GROUP_SOURCE = {
    "seamless": "simulator",
    "inner_city": "simulator",
    "highway": "human (NGSIM)",
    "urban": "human (NGSIM)",
}


class DatasetError(GridSimError):
    """A dataset folder is missing, corrupt or does not fit what is asked of it."""


@dataclass
class Windows:
    """``N`` labelled windows (structure of arrays). Frames: see :mod:`gridsim.frames`."""

    grids: np.ndarray  # uint8 (N, tau_i, H, W)
    ego: np.ndarray  # float32 (N, 6): speed, steering, accel, steer rate, cos, sin heading
    destination: np.ndarray  # float32 (N, 2) [m]
    target: np.ndarray  # float32 (N, tau_o, 2) [m]: the human's next set-points
    steer: np.ndarray  # int64 (N,): implied steering class
    longitudinal: np.ndarray  # int64 (N,): implied longitudinal class
    accel: np.ndarray  # float32 (N,): implied mean acceleration [m/s^2]
    vehicle: np.ndarray  # float32 (N, 3): wheelbase, length, width [m]
    track: np.ndarray  # str (N,): "scenario/track" the window comes from
    time: np.ndarray  # float32 (N,): time in the episode [s]

    def __len__(self) -> int:
        return int(self.ego.shape[0])

    @property
    def heading(self) -> np.ndarray:
        """Ego heading [rad] in the grid frame, ``(N,)``."""
        return ego_heading(self.ego).astype(np.float64)

    @property
    def speed(self) -> np.ndarray:
        return self.ego[:, EGO_SPEED].astype(np.float64)

    def take(self, index: np.ndarray) -> Windows:
        return Windows(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    def rows(self, start: int, stop: int) -> Windows:
        """Windows ``start`` to ``stop`` (views where the arrays allow)."""
        return Windows(**{f.name: getattr(self, f.name)[start:stop] for f in fields(self)})

    def select(self, index: np.ndarray) -> Windows:
        """:meth:`take`, but the grids (nearly all the memory) are read from these windows'
        as they are indexed (:class:`GridRows`), not copied."""
        grids = self.grids
        base, rows = (grids.base, grids.rows[index]) if isinstance(grids, GridRows) else (
            grids, np.arange(len(self))[index])  # fmt: skip
        small = {f.name: getattr(self, f.name)[index] for f in fields(self) if f.name != "grids"}
        return Windows(grids=GridRows(base, rows), **small)

    @staticmethod
    def concat(parts: Iterable[Windows]) -> Windows:
        parts = [p for p in parts if len(p)]
        if not parts:
            raise DatasetError("no windows were recorded")
        return Windows(
            **{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Windows)}
        )


class GridRows:
    """The grids ``base[rows]`` (``base`` uint8 ``(N, tau_i, H, W)``) without a copy: indexing
    reads the rows it asks for; ``np.asarray`` makes the copy."""

    def __init__(self, base: np.ndarray, rows: np.ndarray) -> None:
        self.base, self.rows = base, np.asarray(rows, dtype=np.int64)

    @property
    def shape(self) -> tuple[int, ...]:
        return (len(self.rows), *self.base.shape[1:])

    @property
    def dtype(self) -> np.dtype:
        return self.base.dtype

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, index) -> np.ndarray:
        return self.base[self.rows[index]]

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        out = self.base[self.rows]
        return out if dtype is None else out.astype(dtype)


@dataclass(frozen=True)
class Dataset:
    """Windows with their manifest (scenario group, set-point times, limits, provenance)."""

    windows: Windows
    manifest: dict

    @property
    def times(self) -> np.ndarray:
        """Set-point times [s] after the window's decision time, ``(tau_o,)``."""
        return setpoint_times(self.manifest["setpoint_period"], self.manifest["horizon"])


# -- recording ------------------------------------------------------------------------------
#: Windows are taken every decision on recorded scenes (few tracks), every fifth elsewhere.
RECORDED_STRIDE, GENERATED_STRIDE = 1, 5


@dataclass(frozen=True)
class PlannedEpisode:
    """One episode to record: the track label its windows carry, its reset seed and the
    :class:`GridSimEnv` overrides that select it (the ego track, the duration)."""

    track: str  # "scene/track_id" on recorded scenes, "scenario/seedN" on generated ones
    seed: int
    overrides: dict


#: What a recorded track's episode overrides besides its track: reaching the destination
#: does not end it, so that a window is taken wherever the reference covers the horizon (a
#: human crawling in slow traffic is within the destination's tolerance of its end point
#: for seconds). A generated human reaches its end point only at its end: its episodes keep
#: the scenario's ending.
DRIVEN_THROUGH = {"env": {"end_at_destination": False}}


def goal_overrides(goal_seconds: float | None) -> dict:
    """The scenario overrides that put the observed destination ``goal_seconds`` [s] ahead
    (``env.goal_seconds``); none for None (the scenario's own destination)."""
    return {} if goal_seconds is None else {"env": {"goal_seconds": float(goal_seconds)}}


def scenario_episodes(
    scenario: str,
    episodes: int = 0,
    seed: int = 0,
    duration: float | None = None,
    seeds: list[int] | None = None,
    tracks: Iterable[str] | None = None,
    goal_seconds: float | None = None,
) -> tuple[list[PlannedEpisode], dict]:
    """The episodes of ``scenario`` to record and their provenance. On a recorded scene, every
    track (or the ids in ``tracks``, else those the scenario's ``ego.track`` names) that lasts
    the planning horizon and is not flawed
    (:func:`gridsim.scenario.checks.flawed_tracks`: kept as traffic only) is driven once as
    the ego for its recorded duration (``episodes`` and ``seed`` do not apply); elsewhere
    ``episodes`` episodes with seeds drawn from ``seed`` (or the episode ``seeds`` given),
    ``duration`` [s] long if given. With ``goal_seconds``, every episode observes the
    destination that far ahead (``env.goal_seconds``)."""
    goal = goal_overrides(goal_seconds)
    base = load_scenario(scenario)
    if family_of(base).recorded:
        scene = scene_of(base)
        road, scene_tracks = recorded_scene(base)
        flawed = flawed_tracks(tuple(scene_tracks), road)
        named = tracks is None and (own := ego_track_ids(base, scene)) != "random"
        if named:  # the scenario's own choice: each id must be the scene's, and be driven
            tracks = checked_ego_tracks(base, scene_tracks, own, scene)
        wanted = None if tracks is None else {str(t) for t in tracks}
        need = base.config.env.horizon_time
        chosen = [t for t in scene_tracks if (wanted is None or t.track_id in wanted)
                  and t.duration >= need and t.track_id not in flawed]  # fmt: skip
        if named and len(chosen) < len(wanted):
            left = sorted(wanted - {t.track_id for t in chosen})
            warn_data(f"{base.source}: {len(left)} of the tracks ego.track names are not "
                      f"recorded: {', '.join(left[:10])} (shorter than the {need:g} s horizon, "
                      "or flawed: `gridsim validate` says which)")  # fmt: skip
        chosen = _followable(base, _cars(base, chosen))  # (those left out said on their own)
        _say_unfit_egos(base, chosen, scene_tracks, road)
        overrides = deep_merge(goal, DRIVEN_THROUGH)
        out = [PlannedEpisode(track_name(scene, t.track_id), 0,
                       {"ego": {"track": t.track_id},
                        "simulation": {"duration": max(float(t.duration), 0.1)}, **overrides})
               for t in chosen]  # fmt: skip
        return out, {"scene": scene, "tracks": len(out)}
    if seeds is None:
        if episodes < 1:
            raise DatasetError(f"episodes must be >= 1, got {episodes}")
        rng = stream(seed, Salt.RECORDED_EPISODES)
        seeds = [int(s) for s in rng.integers(0, 2**31 - 1, size=episodes)]
    overrides = ({"simulation": {"duration": duration}} if duration else {}) | goal
    out = [PlannedEpisode(f"{scenario}/seed{s}", int(s), overrides) for s in seeds]
    return out, {"episodes": len(out), "episode_seeds": [int(s) for s in seeds]}


def _cars(scenario, chosen: list) -> list:
    """The ``chosen`` ego tracks a car may drive: pedestrians and bicycles
    (:attr:`~gridsim.traffic.track.Track.drivable_as_ego`) stay traffic, named in a
    :class:`~gridsim.errors.DataWarning`."""
    others = [t for t in chosen if not t.drivable_as_ego]
    if others:
        shown = named([f"{t.track_id} ({t.kind})" for t in others], 8)
        warn_data(f"{scenario.source}: {len(others)} of the {len(chosen)} tracks are not cars "
                  f"and are not driven as the ego ({shown}); they stay in the traffic")  # fmt: skip
    return [t for t in chosen if t.drivable_as_ego]


def _followable(scenario, chosen: list) -> list:
    """The ``chosen`` ego tracks an ego can drive as recorded: one faster than
    ``ego.vehicle.v_max`` would fall behind the human and label its windows from the wrong
    place; those are left out, with a :class:`~gridsim.errors.DataWarning` naming them."""
    too_fast = [outruns_ego(scenario, t) for t in chosen]
    fast = [t for t, out in zip(chosen, too_fast, strict=True) if out]
    if fast:
        top = math.ceil(10 * max(float(t.speed.max()) for t in fast)) / 10  # (to cover it)
        shown = named([t.track_id for t in fast], 8)
        warn_data(f"{scenario.source}: {len(fast)} of the {len(chosen)} tracks to drive as the "
                  f"ego are faster than ego.vehicle.v_max "
                  f"{scenario.config.ego.vehicle.v_max:g} m/s (up to {top:.1f} m/s): the ego "
                  f"could not follow them, they are not recorded ({shown}); set "
                  f"ego.vehicle.v_max >= {top:.1f} to record them")  # fmt: skip
    return [t for t, out in zip(chosen, too_fast, strict=True) if not out]


def _say_unfit_egos(scenario, chosen: list, tracks: list, road) -> None:
    """One :class:`~gridsim.errors.DataWarning` naming the ``chosen`` ego tracks that a random
    ego is not drawn from (:func:`~gridsim.scenario.families.recorded.ego_candidates`): they
    are driven as the human drove them all the same (each environment's own warning, one per
    track, is not shown: :func:`drive_windows`)."""
    fit = {t.track_id for t in ego_candidates(scenario, tracks, road)}
    unfit = [t.track_id for t in chosen if t.track_id not in fit]
    if unfit:
        shown = named(unfit, 8)
        why = why_unfit(scenario, tracks, road, set(unfit))
        warn_data(
            f"{scenario.source}: {len(unfit)} of the {len(chosen)} tracks driven as the ego are "
            f"not ones a random ego is drawn from ({why}): {shown}; they are driven as "
            "recorded all the same"
        )


def episodes_of(
    windows: Windows,
    scenario: str,
    duration: float | None = None,
    goal_seconds: float | None = None,
) -> list[PlannedEpisode]:
    """The episodes of ``scenario`` that ``windows`` were recorded from (by their track
    labels, in order; windows of other scenarios are ignored), to drive them again;
    ``duration`` [s] for generated scenarios (recorded tracks keep their own), the destination
    ``goal_seconds`` ahead if given."""
    base = load_scenario(scenario)
    labels = list(dict.fromkeys(windows.track.tolist()))  # in the order they were recorded
    if family_of(base).recorded:
        ids = scene_ids(labels, scene_of(base))
        return scenario_episodes(scenario, tracks=ids, goal_seconds=goal_seconds)[0] if ids else []
    prefix = f"{scenario}/seed"
    seeds = [int(t[len(prefix) :]) for t in labels if t.startswith(prefix)]
    if not seeds:
        return []
    return scenario_episodes(scenario, seeds=seeds, duration=duration,
                             goal_seconds=goal_seconds)[0]  # fmt: skip


#: How the states a policy drove to are labelled (DAgger): ``human``, the human's next
#: set-points from there (the ego must close its whole offset from the human by the first
#: set-point); ``rejoin`` (:func:`rejoin_labels`), the human's path shifted by the ego's
#: offset from the human now, the shift fading out smoothly by the end of the horizon.
DAGGER_LABELS = ("rejoin", "human")


def rejoin_labels(target: np.ndarray, offset: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Set-points ``(N, tau_o, 2)`` that lead from the ego back onto the human's path:
    ``target`` (the human's next set-points, grid frame) minus ``offset`` ``(N, 2)`` (where
    the human is now, same frame) times ``1 - b(t / t_end)`` at set-point ``times`` [s], with
    the smooth step ``b(s) = 3 s^2 - 2 s^3``: the label starts at the ego, keeps its offset
    at first and merges with the human's path at the end of the horizon (the destination).
    With the ego on the human's path (offset 0) it is the human's set-points."""
    s = np.asarray(times, np.float64) / times[-1]
    remaining = 1.0 - s * s * (3.0 - 2.0 * s)
    shift = remaining[None, :, None] * np.asarray(offset, np.float64)[:, None, :]
    return (target - shift).astype(target.dtype)


def drive_windows(
    scenario: str,
    episodes: list[PlannedEpisode],
    stride: int,
    policy=None,
    progress: Callable[[int], None] | None = None,
    labels: str = "rejoin",
) -> Windows | None:
    """The windows of ``episodes`` of ``scenario`` together (:func:`iter_windows`), ``None``
    if no window was taken."""
    driven = iter_windows(scenario, episodes, stride, policy, progress, labels)
    parts = [w for w in driven if w is not None]
    return Windows.concat(parts) if parts else None


def iter_windows(
    scenario: str,
    episodes: list[PlannedEpisode],
    stride: int,
    policy=None,
    progress: Callable[[int], None] | None = None,
    labels: str = "rejoin",
    endings: dict | None = None,
) -> Iterator[Windows | None]:
    """The windows of each episode of ``episodes`` of ``scenario`` in turn (None for an
    episode that gives none), one every ``stride`` decisions while the reference covers the
    whole horizon. The ego drives the reference, or follows ``policy`` (a trajectory-action
    policy ``(env, obs, info) -> set-points``), as in DAgger; the label is the reference's
    next set-points from the ego's pose, with a policy as ``labels`` says
    (:data:`DAGGER_LABELS`). ``progress(1)`` after each episode; ``endings`` counts the
    episodes that end early (:func:`_episode_windows`)."""
    if stride < 1:
        raise DatasetError(f"stride must be >= 1, got {stride}")
    if labels not in DAGGER_LABELS:
        raise DatasetError(f"labels must be one of {DAGGER_LABELS}, got {labels!r}")
    if policy is not None and getattr(policy, "action_type", "trajectory") != "trajectory":
        raise DatasetError(f"windows are driven with trajectory actions, got a policy with "
                           f"action_type {policy.action_type!r}")  # fmt: skip
    # one environment while the overrides stay the same (a generated scenario's episodes);
    # a recorded scene's differ per ego track: each environment holds the whole scene's
    # traffic, so it is let go before the next (keeping them all grew with the tracks squared)
    env, key = None, None
    for episode in episodes:
        with warnings.catch_warnings():  # an unfit ego track: said once (_say_unfit_egos)
            warnings.simplefilter("ignore", UnfitEgoWarning)
            wanted = json.dumps(episode.overrides, sort_keys=True)
            if wanted != key:
                env = None  # (released before the next is built)
                env, key = GridSimEnv(scenario, **episode.overrides), wanted
            windows = _episode_windows(env, episode.seed, stride, episode.track, policy, labels,
                                       endings)  # fmt: skip
        if progress:
            progress(1)
        yield windows


#: m: a window whose first set-point lies farther than this behind the ego (along its
#: heading) is not taken while the ego drives the human's own track: the ego overshot a stop
#: the human made harder than it can brake (a recording's 20 m/s^2), and the label asks a
#: car that cannot reverse to go back.
BEHIND = 0.1


class _WindowTaker:
    """Drives ``policy`` and, every ``stride`` decisions while the reference covers the whole
    horizon, takes a window: the observation, the label (with ``rejoin``, the
    :func:`rejoin_labels` of the reference's set-points) and the time. Driving a recorded
    human's own track (``policy`` None on a recorded scene), a window whose label starts
    :data:`BEHIND` the ego is not taken (counted in ``behind``)."""

    def __init__(self, stride: int, policy, rejoin: bool) -> None:
        self.stride, self.policy, self.rejoin = stride, policy or Reference(), rejoin
        self.driven_by_reference = policy is None
        self.rows: list[tuple] = []
        self.behind = 0

    def reset(self, env: GridSimEnv, info: dict) -> None:
        self.decisions, self.end = 0, env.reference.end_time
        self.own_track = self.driven_by_reference and env.world.ego_track is not None

    def __call__(self, env: GridSimEnv, obs: dict, info: dict):
        t, times = env.world.time, env.cfg.env.setpoint_times
        if self.decisions % self.stride == 0 and t + times[-1] <= self.end + 1e-6:
            label = info["reference_setpoints"]
            if self.rejoin:
                label = rejoin_labels(label[None], env.reference_in_grid([t]), times)[0]
            ego = obs["ego"]
            ahead = label[0, 0] * ego[EGO_COS] + label[0, 1] * ego[EGO_SIN]
            if self.own_track and ahead < -BEHIND:
                self.behind += 1
            else:
                self.rows.append((obs, label, t))
        self.decisions += 1
        return self.policy(env, obs, info)

    def missed(self, env: GridSimEnv) -> int:
        """The windows the episode would still have given from now on, had it not ended: at
        the decisions before its time limit (none is taken at the last observation) whose
        horizon the reference covers."""
        period, horizon = env.cfg.env.decision_period, env.cfg.env.setpoint_times[-1]
        t, k, count = env.world.time, self.decisions, 0
        while t + horizon <= self.end + 1e-6 and t < env.time_limit - 1e-9:
            count += k % self.stride == 0
            t, k = t + period, k + 1
        return count


#: What ends an episode before its reference does (``Episode.ended_by``): the windows the
#: rest of the reference would have given are not taken (counted in ``endings``). Reaching
#: the destination does not end a recorded track's episode (:data:`DRIVEN_THROUGH`).
EARLY_ENDINGS = ("collision", "off road")


#: How many of the episodes that ended early a recording names (the first ones).
NAMED_ENDINGS = 5


def _ending(env: GridSimEnv, episode, track: str) -> str:
    """How the episode of ``track`` (its windows' label) ended early, for a user to look up:
    ``"us101_4_1/427: collision at 0.1 s with track 900002"`` (on a recorded scene the
    tracks hit by their ids)."""
    said = f"{track}: {episode.ended_by} at {float(episode.last['time']):.1f} s"
    hit = episode.last.get("collided_with") or []
    if hit:
        replayed = getattr(env.world.traffic, "tracks", None)
        names = [f"track {replayed[i].track_id}" if replayed is not None and i < len(replayed)
                 else f"vehicle {i}" for i in hit]  # fmt: skip
        said += f" with {', '.join(names)}"
    return said


def _episode_windows(
    env: GridSimEnv, seed: int, stride: int, track: str, policy=None, labels: str = "rejoin",
    endings: dict | None = None,
) -> Windows | None:  # fmt: skip
    """One episode of :func:`drive_windows`; an episode that ends early (:data:`EARLY_ENDINGS`)
    before windows it would have given is counted in ``endings`` (by how it ended, and the
    windows not taken)."""
    taker = _WindowTaker(stride, policy, policy is not None and labels == "rejoin")
    episode = run_episode(env, taker, seed=seed, on_reset=taker.reset)
    missed = taker.missed(env) if episode.ended_by in EARLY_ENDINGS else 0
    if endings is not None and missed:
        endings[episode.ended_by] = endings.get(episode.ended_by, 0) + 1
        endings["windows_not_taken"] = endings.get("windows_not_taken", 0) + missed
        named = endings.setdefault("first", [])
        if len(named) < NAMED_ENDINGS:
            named.append(_ending(env, episode, track))
    if endings is not None and taker.behind:
        endings["windows_behind"] = endings.get("windows_behind", 0) + taker.behind
    rows, times, p = taker.rows, env.cfg.env.setpoint_times, env.world.ego_params
    if not rows:
        return None
    ego = np.stack([r[0]["ego"] for r in rows]).astype(np.float32)
    target = np.stack([r[1] for r in rows]).astype(np.float32)
    heading = ego_heading(ego).astype(np.float64)
    steer, longitudinal, accel = implied_commands(target, ego[:, EGO_SPEED], heading, times)
    n = len(rows)
    return Windows(
        grids=np.stack([r[0]["grids"] for r in rows]),
        ego=ego,
        destination=np.stack([r[0]["destination"] for r in rows]).astype(np.float32),
        target=target,
        steer=steer,
        longitudinal=longitudinal,
        accel=accel.astype(np.float32),
        vehicle=np.tile(np.array([p.wheelbase, p.length, p.width], np.float32), (n, 1)),
        track=np.array([track] * n),
        time=np.array([r[2] for r in rows], np.float32),
    )


def is_recorded(name: str) -> bool:
    """Whether scenario ``name`` (built-in, YAML or XML path; of a folder or glob, every
    file) replays a recorded scene."""
    return all(family_of(sc).recorded for sc in load_collection(name))


def has_recorded(name: str) -> bool:
    """Whether scenario ``name`` (one, or a collection: any of its files) replays a recorded
    scene (a collection may mix recorded and generated scenes)."""
    return any(family_of(sc).recorded for sc in load_collection(name))


def record_scenario(
    scenario: str,
    episodes: int,
    seed: int = 0,
    stride: int = GENERATED_STRIDE,
    duration: float | None = None,
    progress: Callable[[int], None] | None = None,
    seeds: list[int] | None = None,
    goal_seconds: float | None = None,
    planned: Callable[[int], None] | None = None,
) -> tuple[Windows, dict]:
    """Windows of one scenario (the ego drives the reference; see :func:`scenario_episodes`
    for the episodes, ``goal_seconds`` for the destination) and their provenance;
    ``planned(n)`` is told how many episodes it will drive, ``progress(1)`` after each."""
    sink = _Collected()
    meta = _record_scenario_into(sink, scenario, episodes, seed, stride, duration, progress,
                                 seeds, goal_seconds, planned)  # fmt: skip
    return Windows.concat(sink.parts), meta


def _record_scenario_into(
    sink,
    scenario: str,
    episodes: int,
    seed: int,
    stride: int,
    duration: float | None,
    progress: Callable[[int], None] | None,
    seeds: list[int] | None,
    goal_seconds: float | None,
    planned: Callable[[int], None] | None,
    resume: tuple[int, int] = (0, 0),
    recorded: Callable[[int, int], None] | None = None,
    endings: dict | None = None,
) -> dict:
    """:func:`record_scenario`, each episode's windows given to ``sink.add`` as they come;
    returns the provenance. ``resume`` ``(episode, windows)``: the episodes before
    ``episode``, which gave ``windows`` windows, were recorded before (by an interrupted
    :func:`~neurotrajectory.data.recording.record_dataset`); ``recorded(next episode,
    windows so far)`` after each episode. ``endings``: the episodes ended early so far (those
    before ``resume``), counted on (:func:`_episode_windows`); in the provenance's
    ``ended_early`` when there are any."""
    endings = {} if endings is None else endings
    plan, source = scenario_episodes(scenario, episodes, seed, duration, seeds,
                                     goal_seconds=goal_seconds)  # fmt: skip
    first, count = resume
    if planned is not None:
        planned(len(plan))
    if first and progress is not None:  # gone on with part-way: the bar counts those done
        progress(first)
    driven = iter_windows(scenario, plan[first:], stride, progress=progress, endings=endings)
    for k, windows in enumerate(driven, first + 1):
        if windows is not None:
            sink.add(windows)
            count += len(windows)
        if recorded is not None:
            recorded(k, count)
    if not count:
        raise DatasetError("no windows were recorded")
    cfg = load_scenario(scenario).config
    goal = cfg.env.goal_seconds if goal_seconds is None else float(goal_seconds)
    return {"scenario": scenario, **source, **recording_settings(cfg), "stride": stride,
            **({"goal_seconds": goal} if goal is not None else {}),
            **({"ended_early": _early(endings)} if endings else {})}  # fmt: skip


def recording_settings(cfg) -> dict:
    """The settings of the scenario config ``cfg`` that windows recorded in it carry (a
    manifest's ``horizon``, ``history``, periods [s], ``sensor`` and ``vehicle``): what
    :func:`recording_mismatch` compares with a run's before anything is recorded."""
    return {"horizon": cfg.env.horizon, "history": cfg.env.history,
            "setpoint_period": cfg.env.setpoint_period,
            "decision_period": cfg.env.decision_period,
            "sensor": {"rows": cfg.sensor.rows, "cols": cfg.sensor.cols,
                       "cell_size": cfg.sensor.cell_size, "orientation": cfg.sensor.orientation},
            "vehicle": cfg.ego.vehicle.model_dump()}  # fmt: skip


class _Collected:
    """Windows kept in memory as they are recorded (the sink of :func:`record_group`; see
    :class:`~neurotrajectory.data.storage.ShardWriter` for the one that writes them)."""

    def __init__(self) -> None:
        self.parts: list[Windows] = []

    def add(self, windows: Windows) -> None:
        self.parts.append(windows)

    def mark(self) -> int:
        return len(self.parts)

    def rollback(self, mark: int) -> None:
        del self.parts[mark:]


def group_scenarios(name: str, source: str | None = None) -> tuple[str, ...]:
    """The scenarios of group ``name``: the usable files of ``source`` (a folder or glob;
    the others are named in a warning; they must agree as a collection's do:
    :func:`gridsim.scenario.collection.load_usable`)
    if given; else a group of :data:`GROUPS`, the usable files of ``name`` if it is a folder
    or glob, or the one scenario ``name`` (built-in name, YAML or CommonRoad XML path)."""
    return group_files(name, source)[0]


def check_group(name: str) -> None:
    """A :class:`~gridsim.errors.ScenarioError` naming the groups too, before anything is
    recorded or written, when ``name`` is no group of :data:`GROUPS`, folder, glob or list of
    scenarios, nor one scenario (the loader's message, and the group it may be a misspelling
    of)."""
    if name in GROUPS or scenario_files(name) is not None:
        return
    try:
        load_scenario(name)
    except ScenarioError as exc:
        close = difflib.get_close_matches(name, list(GROUPS), n=1, cutoff=0.6)
        hint = f" (did you mean the group {close[0]!r}?)" if close else ""
        raise ScenarioError(f"{exc}; or a group: {', '.join(GROUPS)}{hint}") from None


def group_files(
    name: str, source: str | None = None
) -> tuple[tuple[str, ...], list[tuple[Path, str]]]:
    """:func:`group_scenarios`, and the files of the folder or glob left out because they
    do not load (``(file, reason)``; named in a warning already)."""
    if source is None and name in GROUPS:
        return GROUPS[name], []
    ref = name if source is None else source
    if scenario_files(ref) is None:
        return (ref,), []
    usable, skipped = load_usable(ref)
    return tuple(sc.source for _, sc in usable), skipped


def bar_callbacks(bar) -> dict:
    """``progress``, ``planned`` and ``files`` for :func:`record_group` and
    :func:`~neurotrajectory.data.recording.record_dataset` that drive the progress bar ``bar``
    (tqdm): one step per episode; its total (the episodes of every file) is shown once the
    last file is planned, and until then how many files are still to plan (a total that grew
    file by file made the percentage go back: 87 % 20/23, then 79 % 23/29)."""
    known = {"episodes": 0, "files": None}  # planned so far; files still to plan (None: ?)

    def show() -> None:
        left = known["files"]
        bar.total = known["episodes"] if not left else None
        bar.set_postfix_str(f"{counted(left, 'file')} still to plan" if left else "")

    def planned(count: int) -> None:
        known["episodes"] += count
        if known["files"]:
            known["files"] -= 1
        show()

    def files(count: int) -> None:
        known["files"] = count
        show()

    return {"progress": bar.update, "planned": planned, "files": files}


def record_group(
    name: str,
    episodes: int,
    seed: int = 0,
    stride: int | None = None,
    duration: float | None = None,
    progress: Callable[[int], None] | None = None,
    source: str | None = None,
    goal_seconds: float | None = None,
    planned: Callable[[int], None] | None = None,
    files: Callable[[int], None] | None = None,
) -> Dataset:
    """Windows of a scenario group (see :func:`group_scenarios`: of :data:`GROUPS`, or the
    usable files of the folder or glob ``source``), or of one scenario, in memory
    (:func:`~neurotrajectory.data.recording.record_dataset` writes them as they come).
    ``stride`` defaults to every decision on recorded scenes, every fifth elsewhere. Of a
    group of several files, a file that gives no window is skipped and named in a warning;
    it and the files that do not load are listed in the manifest's ``skipped``; the group
    fails only when none gives any. ``planned(n)``: a file's ``n`` episodes are planned (0
    for a file skipped before); ``files(n)``: ``n`` files are to plan, once at the start."""
    sink = _Collected()
    manifest = record_group_into(sink, name, episodes, seed, stride, duration, progress,
                                  source, goal_seconds, planned, files=files)  # fmt: skip
    return Dataset(Windows.concat(sink.parts), manifest)


@dataclass
class GroupProgress:
    """How far :func:`record_group_into` is: the scenarios done (``metas``: their
    provenance; ``skipped``: ``[file, reason]`` of those skipped), the next scenario, its next
    episode and the windows its episodes before gave (to go on from there)."""

    scenario: int = 0
    episode: int = 0
    windows: int = 0
    metas: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    #: the sink's mark at the start of the scenario under way (to roll it back if it fails)
    mark: object = None
    #: the episodes of the scenarios done, planned and driven (for a progress bar that goes
    #: on where it was; they differ for a file that failed)
    episodes_planned: int = 0
    episodes_done: int = 0
    #: the episodes of the scenario under way that ended early (see :func:`_episode_windows`)
    endings: dict = field(default_factory=dict)


def record_group_into(
    sink,
    name: str,
    episodes: int,
    seed: int,
    stride: int | None,
    duration: float | None,
    progress: Callable[[int], None] | None,
    source: str | None,
    goal_seconds: float | None,
    planned: Callable[[int], None] | None,
    state: GroupProgress | None = None,
    recorded: Callable[[bool], None] | None = None,
    files: Callable[[int], None] | None = None,
) -> dict:
    """:func:`record_group`, each episode's windows given to ``sink`` as they come (a failed
    file's rolled back: ``sink.mark()``, ``sink.rollback(mark)``); returns the manifest.
    ``state`` is updated after each episode, then ``recorded(False)`` is called (``True``
    after a rollback); given, the group goes on from where it says."""
    scenarios, unloaded = group_files(name, source)
    replays = {scenario: is_recorded(scenario) for scenario in scenarios}
    state = GroupProgress() if state is None else state
    if planned is not None and state.episodes_planned:  # gone on with: the bar counts the
        planned(state.episodes_planned)  # scenarios done
    if progress is not None and state.episodes_done:
        progress(state.episodes_done)
    if files is not None:
        files(len(scenarios) - state.scenario)
    for i, scenario in enumerate(scenarios[state.scenario :], state.scenario):
        s = stride or (RECORDED_STRIDE if replays[scenario] else GENERATED_STRIDE)
        if state.mark is None:  # the file begins now (not one gone on with part-way)
            state.mark = sink.mark()

        def episode_done(episode: int, windows: int, i: int = i) -> None:
            state.scenario, state.episode, state.windows = i, episode, windows
            if recorded is not None:
                recorded(False)

        plan = [0, False]  # the file's episodes, as planned, and whether they were

        def planned_file(count: int, plan: list = plan) -> None:
            plan[0], plan[1] = count, True
            if planned is not None:
                planned(count)

        try:
            meta = _record_scenario_into(sink, scenario, episodes, seed, s, duration, progress,
                                         None, goal_seconds, planned_file,
                                         (state.episode, state.windows), episode_done,
                                         state.endings)  # fmt: skip
        except GridSimError as exc:
            sink.rollback(state.mark)
            if len(scenarios) == 1:
                raise
            state.skipped.append([scenario, str(exc)])
            if not plan[1] and planned is not None:  # (skipped before its plan: none)
                planned(0)
        else:
            state.metas.append(meta)
        state.episodes_planned += plan[0]
        state.episodes_done += state.episode
        state.scenario, state.episode, state.windows, state.mark = i + 1, 0, 0, None
        state.endings = {}
        if recorded is not None:
            recorded(True)
    metas, skipped = state.metas, [(Path(f), reason) for f, reason in state.skipped]
    report_skipped(f"group {name!r}", skipped, len(scenarios), bool(metas),
                   ("gave a window", "gave no window"), DatasetError)  # fmt: skip
    first = metas[0]
    for m in metas[1:]:
        for key in ("horizon", "history", "setpoint_period", "sensor", "goal_seconds"):
            if m.get(key) != first.get(key):
                raise DatasetError(f"group {name!r}: scenarios differ in {key}")
    same = ("horizon", "history", "setpoint_period", "decision_period", "sensor", "vehicle")
    unused = unloaded + skipped + _library_files_skipped([m["scenario"] for m in metas])
    return {
        "format": FORMAT_VERSION,
        "group": name,
        "source": (GROUP_SOURCE.get(name) if source is None else None) or _source(replays),
        "seed": seed,
        **{k: first[k] for k in same},
        **({"goal_seconds": first["goal_seconds"]} if "goal_seconds" in first else {}),
        "scenarios": metas,
        **({"ended_early": early} if (early := ended_early(metas)) else {}),
        **({"skipped": [{"file": str(f), "reason": r} for f, r in unused]} if unused else {}),
        "versions": package_versions(),
    }


def _early(endings: dict[str, int]) -> dict:
    """``endings`` (episodes by how they ended, ``windows_not_taken`` and ``windows_behind``,
    flat: as they are counted and kept across an interruption) as the manifest says them."""
    episodes = {k: endings[k] for k in EARLY_ENDINGS if endings.get(k)}
    behind, first = endings.get("windows_behind", 0), endings.get("first", [])
    return {"episodes": episodes, "windows_not_taken": endings.get("windows_not_taken", 0),
            **({"windows_behind": behind} if behind else {}),
            **({"first": first[:NAMED_ENDINGS]} if first else {})}  # fmt: skip


def ended_early(metas: list[dict]) -> dict:
    """The episodes of the scenarios ``metas`` (their provenance) that ended early, summed
    by how they ended, the windows not taken and those whose label lay behind the ego (as
    each scenario's ``ended_early``); empty when there are none."""
    flat: dict = {}  # (as _episode_windows counts them; "first": the episodes named)
    for meta in metas:
        early = meta.get("ended_early", {})
        counts = {**early.get("episodes", {}),
                  **{k: v for k, v in early.items() if k != "episodes"}}  # fmt: skip
        for key, n in counts.items():
            flat[key] = flat.get(key, [] if key == "first" else 0) + n
    return _early(flat) if flat else {}


#: What a network's windows depend on besides their array sizes (``manifest key``, ``scenario
#: key``): the set-points' spacing in time, the grids' (a decision each), the cells' size and
#: the grid's orientation.
TIMING_KEYS = (("setpoint_period", "env.setpoint_period"),
               ("decision_period", "env.decision_period"),
               ("sensor.cell_size", "sensor.cell_size"),
               ("sensor.orientation", "sensor.orientation"))  # fmt: skip


def recording_mismatch(manifest: dict, cfg) -> str | None:
    """Why windows recorded as ``manifest`` says do not fit a network of the scenario config
    ``cfg`` (:data:`TIMING_KEYS` that differ), or None (a key the manifest lacks is not
    compared). Their sizes: :func:`~neurotrajectory.model.size_mismatch`."""
    run = cfg.model_dump()
    pairs = [(mine, value_at(manifest, key), value_at(run, mine)) for key, mine in TIMING_KEYS]
    differ = [f"{mine} {got!r} (the run's {want!r})" for mine, got, want in pairs
              if got is not MISSING and got != want]  # fmt: skip
    if not differ:
        return None
    return (f"its windows were recorded with {', '.join(differ)}: the network's set-points and "
            "grids would mean other times and places; record them from a scenario of the "
            "run's settings")  # fmt: skip


def early_note(early: dict) -> str:
    """What :func:`ended_early`'s counts mean, for a user."""
    said = []
    if early["episodes"]:
        kinds = ", ".join(f"{n} {k}" for k, n in early["episodes"].items())
        episodes = sum(early["episodes"].values())
        first = early.get("first", [])
        they = "they" if len(first) == episodes else "the first"
        which = f"; {they}: {'; '.join(first)}" if first else ""
        said.append(f"{episodes} episode(s) ended before their reference did ({kinds}): the "
                    f"{early['windows_not_taken']} window(s) the rest would have given were "
                    "not taken (with the ego driving the human's own track, a collision or "
                    f"leaving the road is the recording's{which})")  # fmt: skip
    if early.get("windows_behind"):
        said.append(f"{early['windows_behind']} window(s) whose human set-points start behind "
                    "the ego were not taken (the ego overshot a stop the human made harder "
                    "than it can brake; a car cannot follow them back)")  # fmt: skip
    return "; ".join(said) + " (manifest.json: ended_early)"


def _library_files_skipped(scenarios: list[str]) -> list[tuple[Path, str]]:
    """``(file, reason)`` of the ``traffic.library`` files of ``scenarios`` that were left
    out because they cannot be read (each once)."""
    out: dict[str, str] = {}
    for scenario in scenarios:
        for file, reason in library_for(load_scenario(scenario)).skipped:
            out.setdefault(file, f"a traffic.library file that cannot be read: {reason}")
    return [(Path(f), reason) for f, reason in out.items()]


def _source(replays: dict[str, bool]) -> str:
    """Who drove a group's windows, by whether each of its scenarios replays recorded tracks:
    "human (NGSIM)" for the shipped recorded scenes, "human (recorded)" for a user's,
    "simulator" for generated ones, or both."""
    from gridsim.scenario.loader import builtin_scenarios

    recorded = [s for s, replay in replays.items() if replay]
    if not recorded:
        return "simulator"
    shipped = builtin_scenarios()
    human = "human (NGSIM)" if all(s in shipped for s in recorded) else "human (recorded)"
    return human if len(recorded) == len(replays) else f"{human} and simulator"


def package_versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version(), "numpy": np.__version__}
    try:
        out["gridsim"] = version("gridsim")
    except PackageNotFoundError:
        out["gridsim"] = "unknown"
    return out


# -- splits ---------------------------------------------------------------------------------
def split_by_track(
    windows: Windows, test_fraction: float = 0.3, seed: int = 0
) -> tuple[Windows, Windows]:
    """``(train, test)``: whole tracks go to one side; about ``test_fraction`` of the tracks
    (at least one on each side) are held out."""
    train, test = split_rows(windows, test_fraction, seed)
    return windows.take(train), windows.take(test)


def split_rows(
    windows: Windows, test_fraction: float = 0.3, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """The row indices ``(train, test)`` of :func:`split_by_track`, in order."""
    held_out = np.isin(windows.track, held_out_tracks(windows.track, test_fraction, seed))
    return np.flatnonzero(~held_out), np.flatnonzero(held_out)


def check_test_fraction(test_fraction: float) -> None:
    """A :class:`DatasetError` unless ``test_fraction`` (a split's test share) is in (0, 1)."""
    if not 0 < test_fraction < 1:
        raise DatasetError(f"test_fraction must be in (0, 1), got {test_fraction}")


def held_out_tracks(tracks: np.ndarray, test_fraction: float, seed: int) -> np.ndarray:
    """The test side's tracks of :func:`split_by_track` among the track labels ``tracks``."""
    check_test_fraction(test_fraction)
    tracks = np.unique(tracks)
    if len(tracks) < 2:
        raise DatasetError(f"need windows from >= 2 tracks to split, got {len(tracks)}")
    order = stream(seed, Salt.TRACK_SPLIT).permutation(len(tracks))
    n_test = min(max(1, int(round(test_fraction * len(tracks)))), len(tracks) - 1)
    return tracks[order[:n_test]]


#: Names that lived here before the dataset folder got its own module, and where they are now.
_MOVED = {"load_dataset": "storage", "save_dataset": "storage", "check_new_folder": "storage",
          "SHARD_SIZE": "storage", "dataset_manifest": "storage", "load_split": "storage",
          "ShardWriter": "storage", "record_dataset": "recording"}  # fmt: skip


def __getattr__(name: str):
    """The names of :data:`_MOVED`, from their new module, with a DeprecationWarning."""
    if name not in _MOVED:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    module = importlib.import_module(f"neurotrajectory.data.{_MOVED[name]}")
    warnings.warn(f"{__name__}.{name} moved to {module.__name__}.{name}", DeprecationWarning,
                  stacklevel=2)  # fmt: skip
    return getattr(module, name)
