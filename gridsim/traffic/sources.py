"""Where traffic comes from: recorded scenes, or recorded behaviour replayed on generated roads.

A traffic source owns a :class:`Fleet`, fills it at :meth:`reset` and keeps it populated at
every :meth:`tick` (recycling participants that fall out of range on endless roads).
"""

from __future__ import annotations

import copy
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from gridsim.road.base import Road
from gridsim.road.city import CityRoad
from gridsim.road.seamless import SeamlessRoad
from gridsim.seeding import copy_generator
from gridsim.traffic import fleet_kernels
from gridsim.traffic.fleet import EgoPose, Fleet, FleetParams
from gridsim.traffic.profile_kernels import continue_profiles
from gridsim.traffic.profiles import HumanProfiles, SpeedBounds, human_profiles
from gridsim.traffic.tables import PathBank, TableBank, checked_table
from gridsim.traffic.track import Track

_SPAWN_CLEARANCE = 6.0  # free distance [m] kept around a new participant, beyond the footprints
_NONE = np.zeros(0, np.int64)
#: free distance [m] between a participant spawned on a city street and the ego, whatever
#: their headings (between the circles around both footprints)
CITY_EGO_CLEARANCE = 5.0


def track_path(track: Track) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Path points, their arc lengths and the arc length ``S`` at every sample of ``track``."""
    pts = np.stack([track.x, track.y], axis=1)
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s_samples = np.concatenate([[0.0], np.cumsum(seg)])
    keep = np.concatenate([[True], seg > 1e-6])
    path_pts, path_s = pts[keep], s_samples[keep]
    if len(path_pts) < 2:  # a parked vehicle: a short stub along its heading
        u = np.array([np.cos(track.heading[0]), np.sin(track.heading[0])])
        path_pts, path_s = np.vstack([pts[0], pts[0] + 0.1 * u]), np.array([0.0, 0.1])
    return path_pts, path_s, s_samples


class TrafficTick(NamedTuple):
    """What a compiled tick needs to tick a fleet (its ``traffic`` argument): the fleet's
    :meth:`~gridsim.traffic.fleet.Fleet.tick_data` and the participants kept."""

    state: tuple  # the fleet's arrays (FleetState order)
    paths: tuple  # its path bank's kernel data
    profiles: tuple  # its profile tables' kernel data
    settings: tuple  # leader search, replay limits, IDM parameters
    decay: float  # the lateral bias' decay over the tick
    window: tuple  # (behind, ahead) [m] of the ego kept populated
    count: int  # participants kept
    corridors: np.ndarray  # the paths' corridor ids (Fleet.cross_data), empty: none needed
    refill: bool  # whether refill has work every tick (it places or retires participants)


class TrafficSource(ABC):
    """Populates and maintains a :class:`Fleet`."""

    fleet: Fleet

    @abstractmethod
    def reset(self, rng: np.random.Generator, ego: EgoPose) -> None:
        """Place the initial participants around the ego."""

    @abstractmethod
    def tick(self, dt: float, ego: EgoPose) -> None:
        """Advance the fleet by ``dt`` seconds and refill it."""

    def tick_data(self, dt: float, road: Road) -> TrafficTick | None:
        """What a compiled world tick on ``road`` needs to tick this traffic
        (:func:`~gridsim.world.world_kernels.follow_tick`'s ``traffic``; Python then calls
        :meth:`refill` when it has work), or None: this traffic ticks in Python only (the
        default), or not now."""
        return None

    def refill(self, ended: np.ndarray, ego: EgoPose, dt: float) -> bool:
        """The rest of a compiled tick of ``dt`` seconds (sources that offer
        :meth:`tick_data`), ``ended``: the participants whose profile ran out; returns whether
        it placed a participant (a contact test cannot then be skipped)."""
        return False

    def shared_parts(self) -> list:
        """The parts of this source that copies of a world share (never changed, the same
        for every seed; see :func:`~gridsim.scenario.build.build_world`): none by default."""
        return []


@dataclass(frozen=True, eq=False)
class SceneTables:
    """A recorded scene's tracks as every world of the scene replays them (made once per
    scene, shared read-only): the path and profile tables of all its tracks, slot ``k`` the
    scene's track ``k``, and each track's id, first time [s] and duration [s]."""

    paths: PathBank  # arc length [m] -> points [m, world]
    profiles: TableBank  # time [s] from the track's start -> arc length, speed, 0, heading
    ids: np.ndarray  # the track ids (object)
    t0: np.ndarray
    duration: np.ndarray


@lru_cache(maxsize=8)
def scene_tables(tracks: tuple[Track, ...]) -> SceneTables:
    """The :class:`SceneTables` of the recorded scene ``tracks``, checked, made once per
    scene: every world of a scene (one per ego track when a scene is recorded) looks its
    tracks up in the same flat tables, so that a world costs the tracks it replays, not the
    scene's (and a track replays the same bits whichever world replays it)."""
    paths, profiles = PathBank(), TableBank(width=4)
    path_tables, profile_tables = [], []
    for tr in tracks:
        path_pts, path_s, s_samples = track_path(tr)
        path_tables.append(checked_table(path_s, path_pts, 2))
        prof = np.stack([s_samples, tr.speed, np.zeros_like(tr.t), tr.heading], axis=1)
        profile_tables.append(checked_table(tr.t - tr.t[0], prof, 4))
    paths.extend_paths(path_tables)
    profiles.extend(profile_tables)
    ids = np.array([tr.track_id for tr in tracks], dtype=object)
    t0 = np.array([tr.t[0] for tr in tracks], dtype=np.float64)
    duration = np.array([tr.duration for tr in tracks], dtype=np.float64)
    return SceneTables(paths, profiles, ids, t0, duration)


#: s: a clock that adds its ticks up from a start time far from 0 (a recording timed from
#: 100 s: 102.99999999999983 after 30 ticks) still places a track at the tick it starts.
TIME_TOLERANCE = 1e-9
#: s: a world replaying a time span (``until``) keeps the tracks recorded within this much of
#: it as well (kept tracks cost a little memory, never a different result).
SPAN_MARGIN = 1.0


class RecordedSceneTraffic(TrafficSource):
    """Replays the tracks of a recorded scene in their own geometry (exact poses, 10 Hz data
    interpolated at the simulation rate). ``exclude`` removes one track (the expert ego).
    With ``until`` [s], the world replays the span from ``start_time`` to ``until`` (an ego
    track's episode): only the tracks recorded in it are kept, so that a world of a scene of
    thousands of vehicles holds the few hundred it meets; ticked past it, it takes in the
    rest of the scene (the same bits as keeping it all along). Participant ``i`` replays the
    scene's track ``slots[i]`` (its tables' slot)."""

    def __init__(
        self,
        tracks: list[Track],
        exclude: str | None = None,
        start_time: float = 0.0,
        params: FleetParams | None = None,
        until: float | None = None,
    ) -> None:
        self._scene = tuple(tracks)
        self._exclude, self.start_time, self.until = exclude, start_time, until
        self.time = start_time
        self.slots, self._done = np.zeros(0, np.int64), np.zeros(0, bool)  # none kept yet
        self._keep(Fleet(1, params))

    def _keep(self, fleet: Fleet) -> None:
        """Keep the scene's tracks (but the excluded one) recorded in the span, or all of them
        without ``until``; the participants of ``fleet`` stay where their tracks are."""
        scene = scene_tables(self._scene)
        keep = scene.ids != self._exclude
        if self.until is not None:
            keep &= (scene.t0 <= self.until + SPAN_MARGIN) & (
                scene.t0 + scene.duration >= self.start_time - SPAN_MARGIN
            )
        slots = np.flatnonzero(keep)
        where = np.searchsorted(slots, self.slots)  # (the slots kept before are kept again)
        self.fleet = fleet.relaid(max(1, len(slots)), where)
        self.fleet.paths, self.fleet.profiles = scene.paths, scene.profiles
        done = np.zeros(len(slots), bool)
        done[where] = self._done
        self.slots, self._done = slots, done
        self.tracks = [self._scene[i] for i in slots]
        #: each track's first time [s] and duration [s], to find the ones due at once
        self._t0, self._duration = scene.t0[slots], scene.duration[slots]

    def reset(self, rng: np.random.Generator, ego: EgoPose) -> None:
        self.fleet.deactivate(np.arange(self.fleet.capacity))
        self.time = self.start_time
        self._done[:] = False
        self._activate_due()

    def _activate_due(self) -> bool:
        """Place the tracks whose recording covers now and that are neither active nor done
        (one vectorised test a tick: a scene may hold thousands of tracks); whether any."""
        n = len(self.tracks)
        taus = self.time - self._t0
        early, late = taus < -TIME_TOLERANCE, taus > self._duration + TIME_TOLERANCE
        due = np.flatnonzero(~(self.fleet.active[:n] | self._done | early | late))
        for i in due:
            tr, tau, slot = self.tracks[i], taus[i], int(self.slots[i])
            vals = self.fleet.profiles.lookup(np.array([slot]), np.array([tau]))
            self.fleet.place(
                i,
                path=slot,
                s=float(vals[0, 0]),
                profile=slot,
                tau=tau,
                geometric=True,
                length=tr.length,
                width=tr.width,
            )
        return len(due) > 0

    def tick(self, dt: float, ego: EgoPose) -> None:
        self.refill(self.fleet.tick(dt, ego), ego, dt)

    def shared_parts(self) -> list:
        """The tracks, their times and the fleet's paths and profiles: made from the
        recording, never changed (a scene of thousands of tracks is not copied per episode)."""
        f = self.fleet
        return [self._scene, self.tracks, self.slots, self._t0, self._duration, f.paths,
                f.profiles]  # fmt: skip

    def tick_data(self, dt: float, road: Road) -> TrafficTick:
        """:meth:`Fleet.tick_data` for :meth:`tick` (no window: a recording keeps its tracks
        wherever the ego is); :meth:`refill` has work every tick (the clock)."""
        return TrafficTick(*self.fleet.tick_data(dt), 0, self.fleet.cross_data(), True)

    def refill(self, ended: np.ndarray, ego: EgoPose, dt: float) -> bool:
        """The rest of :meth:`tick` after the fleet's: the clock advances by the tick,
        tracks whose recording ended are done, those whose recording begins are placed."""
        self.time += dt
        self._done[ended] = True
        if self.until is not None and self.time > self.until + SPAN_MARGIN / 2:
            self.until = None  # ticked past its span: the whole scene from now on
            # (well before a track kept no longer could be due: they start after the margin)
            self._keep(self.fleet)
        return self._activate_due()


@lru_cache(maxsize=16)
def _profile_tables(profiles: HumanProfiles) -> TableBank:
    """The fleet's profile tables ``(dist, v, d, 0)`` over time for ``profiles``, built once and
    shared read-only by every fleet replaying them (they do not depend on the episode)."""
    bank = TableBank(width=4)
    for t, dist, v, d in zip(profiles.t, profiles.dist, profiles.v, profiles.d, strict=True):
        bank.add(t, np.stack([dist, v, d, np.zeros_like(t)], axis=1))
    bank.ranges(np.zeros(1, np.int64))  # build the flat arrays now, once
    return bank


class SyntheticTraffic(TrafficSource):
    """Recorded human speed and lateral-offset profiles (:class:`HumanProfiles`) replayed
    along the lanes of a generated road. Each participant gets a random profile scaled into
    ``[v_min, v_max]`` (the fleet also rate-limits it to ``a_max``); when it runs out, the
    participant continues with another one, scaled to keep its speed continuous.
    """

    def __init__(
        self,
        tracks: list[Track],
        count: int,
        bounds: SpeedBounds,
        lane_width: float,
        params: FleetParams | None = None,
    ) -> None:
        self.count = count
        self.profiles = human_profiles(tuple(tracks), bounds, lane_width)
        fp = params or FleetParams()
        limits = {
            "v_min": bounds.v_min,
            "v_max": bounds.v_max,
            "a_max": bounds.a_max,
            "b_max": max(bounds.a_max, fp.idm.b),
        }
        self.fleet = Fleet(max(1, count), FleetParams(**{**fp.__dict__, **limits}))
        self.fleet.profiles = _profile_tables(self.profiles)
        self._sizes = self.profiles.sizes
        self.rng = np.random.default_rng(0)

    def shared_parts(self) -> list:
        """The profile tables: drawn from, never changed."""
        return [self.profiles, self.fleet.profiles]

    def __deepcopy__(self, memo) -> SyntheticTraffic:
        """A deep copy whose random stream is copied through its state
        (:func:`~gridsim.seeding.copy_generator`)."""
        new = copy.copy(self)
        memo[id(self)] = new
        memo.setdefault(id(self.rng), copy_generator(self.rng))
        for name, value in vars(self).items():
            setattr(new, name, copy.deepcopy(value, memo))
        return new

    # -- helpers shared by the road-specific sources ------------------------------------------
    def _clear(
        self, x: float, y: float, heading: float, length: float, width: float, ego: EgoPose
    ) -> bool:
        """Whether a ``length`` x ``width`` vehicle at ``(x, y, heading)`` keeps
        :data:`_SPAWN_CLEARANCE` metres ahead and behind from everyone in its lane."""
        return not self.fleet.occupied(x, y, heading, length, width, ego, _SPAWN_CLEARANCE, 0.5)

    @property
    def spacing(self) -> float:
        """Length of lane [m] each participant is given (at reset, and in :attr:`capacity`)."""
        return float(self._sizes[:, 0].max()) + _SPAWN_CLEARANCE + 2.0

    def _draw(self) -> tuple[int, float, float]:
        """A fresh profile, its speed scale and a start time in its first half."""
        prof, k = self.profiles.draw(self.rng)
        return prof, k, float(self.rng.uniform(*self.fleet.profiles.x_range(prof)) * 0.5)

    def _spawn(
        self,
        i: int,
        path: int,
        s: float,
        ego: EgoPose,
        drawn: tuple[int, float, float] | None = None,
    ) -> bool:
        """Place participant ``i`` at ``(path, s)`` with a fresh profile if the spot is free."""
        prof, k, tau = drawn or self._draw()
        length, width = self._sizes[prof]
        x, y, h = self.fleet.paths.point(path, s, 0.0)
        if not self._clear(x, y, h, length, width, ego):
            return False
        self.fleet.place(i, path=path, s=s, profile=prof, tau=tau, k=k, length=length, width=width)
        return True

    def _chain_profiles(self, ended: np.ndarray) -> None:
        """Give participants whose profile ran out a new one, keeping speed and offset
        (``HumanProfiles.continue_from`` each, in turn: ``integers(n, size=m)`` draws what
        ``m`` calls of ``integers(n)`` draw)."""
        if len(ended):
            draws = self.rng.integers(len(self.profiles), size=len(ended))
            continue_profiles(ended, draws, *self.continuation()[1:])

    def continuation(self, ahead: int = 0) -> tuple:
        """What :func:`~gridsim.traffic.profile_kernels.continue_profiles` takes after the
        ended participants: the next ``ahead`` profile draws (from a copy of the random
        stream: :meth:`drew` then takes the ones used), the profiles' first values, the speed
        bounds, the fleet's arrays."""
        f, b = self.fleet, self.profiles.bounds
        draws = _NONE
        if ahead:
            draws = copy_generator(self.rng).integers(len(self.profiles), size=ahead)
        return (draws, self.profiles.firsts, (b.v_min, b.v_max),
                (f.profile, f.tau, f.k, f.d_bias, f.v, f.d))  # fmt: skip

    def drew(self, used: int) -> None:
        """Advance the random stream past ``used`` draws of :meth:`continuation`."""
        if used:
            self.rng.integers(len(self.profiles), size=used)


class SeamlessTraffic(SyntheticTraffic):
    """Synthetic traffic on a :class:`SeamlessRoad`: ``count`` participants kept within
    ``[-behind, ahead]`` metres of the ego along the road, recycled to the far end."""

    def __init__(
        self,
        road: SeamlessRoad,
        tracks: list[Track],
        count: int,
        bounds: SpeedBounds,
        behind: float = 80.0,
        ahead: float = 160.0,
        params: FleetParams | None = None,
    ):
        super().__init__(tracks, count, bounds, road.p.lane_width, params)
        self.road = road
        self.behind, self.ahead = behind, ahead
        self._lane_slots = [
            self.fleet.paths.add_path(ln.centre.points, ln.centre.s, corridor=0)
            for ln in road.lanes
        ]
        self._version = road.version

    def _sync_lanes(self) -> None:
        if self.road.version != self._version:
            for slot, ln in zip(self._lane_slots, self.road.lanes, strict=True):
                self.fleet.paths.set(slot, ln.centre.s, ln.centre.points)
            self._version = self.road.version

    @property
    def capacity(self) -> int:
        """The most participants that fit in the window at reset: one per :attr:`spacing` of
        each lane, but for the (at most two) slots the ego takes."""
        return int((self.behind + self.ahead) // self.spacing) * len(self._lane_slots) - 2

    def reset(self, rng: np.random.Generator, ego: EgoPose) -> None:
        self.rng = rng
        self._sync_lanes()
        f = self.fleet
        f.deactivate(np.arange(f.capacity))
        # Shuffle evenly spaced slots over all lanes of the window, so that even a dense
        # fleet fills without overlaps; each slot is jittered within its free margin.
        spacing = self.spacing
        per_lane = int((self.behind + self.ahead) // spacing)
        n_lanes = len(self._lane_slots)
        slots = rng.permutation(per_lane * n_lanes)
        abreast = [self.road.lane_s_near_ego(lane) for lane in range(n_lanes)]
        i = 0
        for slot in slots:
            if i == self.count:
                break
            lane, k = divmod(int(slot), per_lane)
            s = abreast[lane] - self.behind + (k + 0.5) * spacing
            s += rng.uniform(-1.0, 1.0)
            if self._spawn(i, self._lane_slots[lane], s, ego):
                i += 1

    def tick(self, dt: float, ego: EgoPose) -> None:
        self._sync_lanes()
        self.refill(self.fleet.tick(dt, ego, (self.behind, self.ahead)), ego, dt)

    def tick_data(self, dt: float, road: Road) -> TrafficTick | None:
        """:meth:`Fleet.tick_data` for :meth:`tick`, and the participants kept: for a compiled
        tick that leaves :meth:`refill` to Python whenever it has work. None on another road
        than this traffic's, and while the fleet's lanes are not the road's or some path has
        no lane corridor (then :meth:`tick` ticks it: the reference's shadow world does not
        search leaders on other paths)."""
        if (
            road is not self.road
            or self.road.version != self._version
            or not self.fleet.paths.all_in_corridors
        ):
            return None
        return TrafficTick(*self.fleet.tick_data(dt, (self.behind, self.ahead)), self.count,
                           self.fleet.cross_data(), False)  # fmt: skip

    def refill(self, ended: np.ndarray, ego: EgoPose, dt: float) -> bool:
        """The rest of :meth:`tick` after the fleet's: participants whose profile ran out
        (``ended``) continue with a new one; one idle participant may respawn."""
        f = self.fleet
        self._chain_profiles(ended)  # out: recycled
        kept = f.active[: self.count]
        if np.count_nonzero(kept) == len(kept):  # all active (cheaper than .all())
            return False
        idle = np.flatnonzero(~f.active[: self.count])
        # One attempt per tick, out of the sensor's sight: ahead if it
        # starts slower than the ego (the ego will catch up), behind if faster. A blocked spot
        # is retried on a later tick.
        n_lanes = len(self._lane_slots)
        for i in idle[:1]:
            drawn = self._draw()
            prof, k, tau = drawn
            v0 = k * self.fleet.profiles.lookup(np.array([prof]), np.array([tau]))[0, 1]
            band = self.rng.uniform(5.0, 40.0)
            edge = self.ahead - band if v0 <= ego.v else -self.behind + band
            lane = int(self.rng.integers(n_lanes))
            s = self.road.lane_s_near_ego(lane) + edge
            return self._spawn(int(i), self._lane_slots[lane], s, ego, drawn)
        return False


class CityTraffic(SyntheticTraffic):
    """Synthetic traffic on a :class:`CityRoad`: each participant drives its own random route;
    participants farther than ``radius`` from the ego or near their route end are respawned."""

    def __init__(
        self,
        road: CityRoad,
        tracks: list[Track],
        count: int,
        bounds: SpeedBounds,
        radius: float = 150.0,
        params: FleetParams | None = None,
    ):
        super().__init__(tracks, count, bounds, road.params.lane_width, params)
        self.road = road
        self.radius = radius
        self._route_len = 4 * radius
        self._slots = [-1] * max(1, count)

    @property
    def capacity(self) -> int:
        """About the most participants the streets within ``radius`` of the ego hold, one per
        :attr:`spacing` of lane: the map's lane length times the share of its area inside
        that circle (at most all of it)."""
        p = self.road.params
        a, b = self.road.nodes[self.road.edges[:, 0]], self.road.nodes[self.road.edges[:, 1]]
        lane_length = float(np.hypot(*(b - a).T).sum()) * 2 * p.lanes_per_direction
        span = self.road.nodes.max(axis=0) - self.road.nodes.min(axis=0) + p.block_size
        share = min(1.0, math.pi * self.radius**2 / float(np.prod(span)))
        return int(lane_length * share // self.spacing)

    def _spawn_near(self, i: int, ego: EgoPose) -> None:
        d = np.hypot(*(self.road.nodes - np.array([ego.x, ego.y])).T)
        candidates = np.flatnonzero(d < self.radius)
        if len(candidates) == 0:
            candidates = np.argsort(d)[:4]
        node = int(candidates[self.rng.integers(len(candidates))])
        lane = int(self.rng.integers(self.road.params.lanes_per_direction))
        route = self.road.random_route(self.rng, self._route_len, start_node=node, lane=lane)
        if self._slots[i] < 0:
            self._slots[i] = self.fleet.paths.add_path(route.points, route.s)
        else:
            self.fleet.paths.set(self._slots[i], route.s, route.points)
        self._spawn(i, self._slots[i], float(self.rng.uniform(0.0, 40.0)), ego)

    def reset(self, rng: np.random.Generator, ego: EgoPose) -> None:
        self.rng = rng
        self.fleet.deactivate(np.arange(self.fleet.capacity))
        for i in range(self.count):
            self._spawn_near(i, ego)

    def _clear(self, x, y, heading, length, width, ego: EgoPose) -> bool:
        """As for any traffic, and :data:`CITY_EGO_CLEARANCE` from the ego: on city streets a
        participant may spawn crossing or merging into the ego's path, where the lane-aligned
        test of :meth:`Fleet.occupied` does not see the ego's footprint turned against it."""
        reach = 0.5 * (math.hypot(length, width) + math.hypot(ego.length, ego.width))
        if math.hypot(x - ego.x, y - ego.y) < reach + CITY_EGO_CLEARANCE:
            return False
        return super()._clear(x, y, heading, length, width, ego)

    def _spawn(self, i: int, path: int, s: float, ego: EgoPose, drawn=None) -> bool:
        """As for any traffic, refused where the new participant and another would meet
        where their paths cross, one in the other's way already and the other unable to stop
        short of it at the IDM's comfortable deceleration
        (:func:`~gridsim.traffic.fleet_kernels.blocked`)."""
        if not super()._spawn(i, path, s, ego, drawn):
            return False
        f = self.fleet
        if fleet_kernels.blocked(f.state, f.paths.kernel_data(), i, f.p.lateral_margin,
                                 f.p.crossing_horizon, f.p.idm.b):  # fmt: skip
            f.deactivate(np.array([i]))
            return False
        return True

    def tick(self, dt: float, ego: EgoPose) -> None:
        self.refill(self.fleet.tick(dt, ego), ego, dt)

    def tick_data(self, dt: float, road: Road) -> TrafficTick | None:
        """:meth:`Fleet.tick_data` for :meth:`tick` (no window: participants leave by
        distance, in :meth:`refill`, which has work every tick); None on another road than
        this traffic's."""
        if road is not self.road:
            return None
        return TrafficTick(*self.fleet.tick_data(dt), 0, self.fleet.cross_data(), True)

    def refill(self, ended: np.ndarray, ego: EgoPose, dt: float) -> bool:
        """The rest of :meth:`tick` after the fleet's: participants whose profile ran out
        continue with a new one; those far from the ego or near their route's end are
        respawned near it."""
        f = self.fleet
        if not self.count:  # the ego alone in the city
            return False
        self._chain_profiles(ended)
        far = np.hypot(f.x - ego.x, f.y - ego.y) > self.radius * 1.5
        _, ends = f.paths.ranges(f.path)
        near_end = f.s > ends - 30.0
        f.deactivate(np.flatnonzero(f.active & (far | near_end)))
        idle = np.flatnonzero(~f.active[: self.count])
        for i in idle:
            self._spawn_near(int(i), ego)
        return len(idle) > 0
