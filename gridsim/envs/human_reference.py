"""The human reference: where a human would drive in this episode.

On recorded scenes it is the ego track's own recorded future. On generated roads it is a
human speed and lane-offset profile replayed along the ego's route, exactly like traffic:
a shadow copy of the episode's world (same scenario, same seed) is driven by a
:class:`~gridsim.world.scripted_drivers.HumanDriver` (which keeps its distance to traffic with IDM),
and its ego states are recorded. A policy that follows the reference therefore meets the
same traffic.

The shadow world is advanced lazily (:class:`HumanReference`): a reset costs one world
build, and every step advances it only as far as the look-ahead needs. References are
cached per (scenario, seed) and shared: all individuals of a population evaluated on the
same seeds advance one shadow world.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict

import numpy as np

from gridsim.envs import human_reference_kernels as kernels
from gridsim.envs.shadow_world import ShadowWorld
from gridsim.scenario.build import build_world
from gridsim.scenario.parts import road_lane_width, synthetic_tracks
from gridsim.scenario.schema import Scenario
from gridsim.seeding import Salt, stream
from gridsim.traffic.profiles import ProfileChain, SpeedBounds, human_profiles
from gridsim.traffic.track import Track
from gridsim.vehicle.kinematics import rear_axle_of
from gridsim.world.collision import CollisionChecker
from gridsim.world.scripted_drivers import HumanDriver

_CACHE: OrderedDict[tuple[str, int], HumanReference] = OrderedDict()
_CACHE_LOCK = threading.Lock()  # (envs stepped in threads share the cache)
_CACHE_SIZE = 64
#: A destination counts as reached after driving this share of the reference's length.
REACHED_SHARE = 0.9
_ORIGIN = np.zeros(2)
_NO_END = (math.nan, math.nan, math.nan)  # never read: see ReferenceTrajectory._end


class ReferenceTrajectory:
    """Rear-axle positions ``xy`` [m, world], headings ``psi`` [rad] and speeds ``v`` [m/s] at
    times ``t`` [s] from the start of the episode. Beyond the last sample it continues at
    constant velocity."""

    def __init__(self, t: np.ndarray, xy: np.ndarray, psi: np.ndarray, v: np.ndarray) -> None:
        self.t = t
        self._xy, self._psi, self._v = xy, psi, v
        # float64 views (copies if need be) for the compiled look-up (np.interp converts so)
        self._t64, self._xy64 = np.asarray(t, np.float64), np.asarray(xy, np.float64)
        self._tail: tuple[float, float, float] | None = None
        self._ready = len(t)  # samples known so far (all of them here)
        self._destination: np.ndarray | None = None
        self._length: float | None = None
        self._reach: float | None = None

    # -- samples -------------------------------------------------------------------------------
    def _advance(self, ready: int) -> None:
        """Make the first ``ready`` samples known (all are, for a recorded trajectory)."""

    @property
    def end_time(self) -> float:
        return float(self.t[-1])

    @property
    def complete(self) -> bool:
        return self._ready == len(self.t)

    @property
    def xy(self) -> np.ndarray:
        """All positions ``(N, 2)`` (completes a lazy reference)."""
        self._advance(len(self.t))
        return self._xy

    @property
    def psi(self) -> np.ndarray:
        self._advance(len(self.t))
        return self._psi

    @property
    def v(self) -> np.ndarray:
        self._advance(len(self.t))
        return self._v

    def positions(self, times: np.ndarray) -> np.ndarray:
        """Positions ``(N, 2)`` at ``times`` [s] (interpolated; extrapolated past the end)."""
        return self.positions_in_grid(times, _ORIGIN, 0.0)[0]

    def positions_in_grid(
        self, times: np.ndarray, ego_xy: np.ndarray, rotation: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`positions` ``(N, 2)`` [m, world], and the same in the grid frame of an ego
        at ``ego_xy`` [m, world] with grid ``rotation`` [rad] (float32, see
        :func:`~gridsim.frames.world_to_grid`)."""
        times = np.asarray(times, dtype=np.float64)
        if len(times) and not self.complete:
            # Interpolation reads the two samples around each time: the one after the
            # latest must be known (np.interp on that prefix equals it on the whole).
            self._advance(int(np.searchsorted(self.t, times.max(), side="right")) + 2)
        return kernels.positions(times, self._t64, self._xy64, self._ready, self._end(),
                                 float(ego_xy[0]), float(ego_xy[1]), math.cos(rotation),
                                 math.sin(rotation))  # fmt: skip

    def _end(self) -> tuple[float, float, float]:
        """Speed [m/s] and cos, sin of the heading of the last sample, to extrapolate past
        the end (needed only once the reference is complete: a time past the end completes
        it)."""
        if self._tail is None:
            if not self.complete:
                return _NO_END
            v, psi = self._v[-1], self._psi[-1]
            self._tail = (float(v), float(np.cos(psi)), float(np.sin(psi)))
        return self._tail

    # -- the destination -----------------------------------------------------------------------
    @property
    def destination(self) -> np.ndarray:
        """The last position [m, world] (completes a lazy reference)."""
        if self._destination is None:
            self._destination = self.positions(np.array([self.end_time]))[0]
        return self._destination

    @property
    def length(self) -> float:
        """Length [m] of the whole path (completes a lazy reference)."""
        if self._length is None:
            self._length = float(np.sum(np.hypot(*np.diff(self.xy, axis=0).T)))
        return self._length

    @property
    def reach(self) -> float:
        """How far [m] the reference ever gets from its first position (completes a lazy
        reference). Unlike :attr:`length`, position noise of a standing vehicle does not add
        up in it."""
        if self._reach is None:
            self._reach = float(np.max(np.hypot(*(self.xy - self.xy[0]).T)))
        return self._reach

    def reached(self, xy: np.ndarray, travelled: float, tolerance: float) -> bool:
        """Whether a vehicle at ``xy`` [m, world] that has driven ``travelled`` metres has
        reached the destination: within ``tolerance`` [m] of the last position, having driven
        :data:`REACHED_SHARE` of the length (so that a route passing the same place twice does
        not end on the first pass). A reference that never leaves ``tolerance`` of its start
        (a human who waited the whole time) is never reached: its episode runs for its
        duration. A lazy reference is advanced only as far as needed to rule this out."""
        if not self._could_reach(travelled, tolerance):
            return False
        near_end = np.hypot(*(xy - self.destination)) <= tolerance
        return bool(
            near_end
            and travelled >= REACHED_SHARE * self.length - tolerance
            and self.reach > tolerance
        )

    def _could_reach(self, travelled: float, tolerance: float) -> bool:
        return True


#: How far back [s] a collision found in the shadow world revises the reference: from there
#: on, the human driver gives way to the vehicle it would have hit. The shadow world runs this
#: far ahead of the samples handed out, so that a revision never changes one of them.
REVISION_WINDOW = 3.0
#: How long [s] after the foreseen collision the driver keeps giving way (it costs nothing
#: once the vehicle is clear: the driver then drives as it would).
YIELD_AFTER = 6.0
#: The shadow world runs in blocks of this many seconds of ticks, ending at fixed ticks, and
#: hands out what a block made sure of only when the block is done: what it hands out, and so
#: how far back a revision may reach, depends on the tick alone, never on the order or the
#: reach of the requests (which differ between planners sharing a reference, and between
#: backends). A block's ticks go to the compiled batch in one call.
BLOCK_SECONDS = 2.0
#: At most this many revisions per reference (a collision left after them stays).
MAX_REVISIONS = 12
#: A near miss is a collision too: the shadow ego's footprint is tested grown by this much
#: [m] at each end and each side, so that a policy that follows the reference with small
#: tracking errors keeps clear as well.
NEAR_MISS_AHEAD, NEAR_MISS_SIDE = 0.5, 0.15
#: Whether shadow worlds tick in compiled batches where they can (:mod:`gridsim.envs.shadow_world`;
#: the same samples either way, the tests compare them).
COMPILED_SHADOW = True


class HumanReference(ReferenceTrajectory):
    """The reference of a generated scene, produced on demand: a human profile
    (:class:`~gridsim.traffic.profiles.ProfileChain`) driven in a shadow world.

    A human keeps its distance: when the shadow world's ego collides (or nearly: see
    :data:`NEAR_MISS_AHEAD`) at sample ``k``, the
    world is rebuilt and replayed to ``k - REVISION_WINDOW`` and driven on giving way to the
    vehicle hit (:func:`~gridsim.world.scripted_drivers.conflict_free_accel`) until
    ``k + YIELD_AFTER``.
    A reference that never collides is exactly today's human drive. The shadow world runs in
    blocks of :data:`BLOCK_SECONDS` ending at fixed ticks and hands samples out only once a
    block is done and no revision can reach them (a revision found while one is replayed is
    cut short there): the samples depend on the seed alone, never on the order or reach of
    the requests."""

    def __init__(self, scenario: Scenario, seed: int, duration: float) -> None:
        cfg = scenario.config
        self._scenario, self._seed = scenario, int(seed)
        lo, hi = cfg.speed_range
        bounds = SpeedBounds(lo, min(hi, cfg.ego.vehicle.v_max), cfg.ego.vehicle.a_max)
        profiles = human_profiles(
            tuple(synthetic_tracks(scenario)), bounds, road_lane_width(scenario)
        )
        rng = stream(seed, Salt.HUMAN_PROFILE)
        self._chain = ProfileChain(profiles, rng, duration, cfg.simulation.dt, cfg.ego.speed)
        n = len(self._chain.times)
        super().__init__(self._chain.times, np.empty((n, 2)), np.empty(n), np.empty(n))
        self._lag = round(REVISION_WINDOW / cfg.simulation.dt)
        self._after = round(YIELD_AFTER / cfg.simulation.dt)
        self._block = max(1, round(BLOCK_SECONDS / cfg.simulation.dt))
        #: Revisions: (first tick, last tick, fleet indices to give way to).
        self.revisions: list[tuple[int, int, tuple[int, ...]]] = []
        #: Samples whose (near) collision no revision could avoid.
        self.collisions: list[int] = []
        self._yielding = np.zeros(n + 1, bool)  # per tick: whether some revision covers it
        #: One thread at a time drives the shadow world (envs in threads share a reference:
        #: two advancing it at once broke it for the rest of the process)
        self._lock = threading.RLock()
        self._restart()
        self._ready = 0
        self._known_length = 0.0  # running sum of the final path's length [m]

    def __getstate__(self) -> dict:
        """Copies and pickles (a copied or pickled env's) leave the lock out; each gets its own.
        A copy is taken of the state as it is while the copy walks it: copy an env from the
        thread that steps it, not while another thread advances a reference it shares."""
        return {k: v for k, v in self.__dict__.items() if k != "_lock"}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = threading.RLock()

    def _restart(self) -> None:
        """A fresh shadow world at time 0 (sample 0 recorded)."""
        self._world = w = build_world(self._scenario, self._seed)
        self._driver = HumanDriver(self._chain, yield_to=self._yield_to)
        p = w.ego_params
        self._near = CollisionChecker(p.length + 2 * NEAR_MISS_AHEAD, p.width + 2 * NEAR_MISS_SIDE)
        self._shadow = ShadowWorld(w, self._driver, self._near, (self._xy, self._psi, self._v),
                                   compiled=COMPILED_SHADOW)  # fmt: skip
        self._xy[0], self._psi[0], self._v[0] = w.ego[:2], w.ego[2], w.ego[3]
        self._front = 1  # samples simulated (the last ``_lag`` of them may still be revised)

    def _yield_to(self, tick: int) -> tuple[int, ...]:
        """Fleet indices the driver gives way to at ``tick`` (sorted)."""
        return tuple(sorted({j for a, b, js in self.revisions if a <= tick <= b for j in js}))

    def _simulate(self, front: int) -> None:
        """Simulate up to ``front`` samples, revising after collisions."""
        while self._front < front:
            self._front, check = self._shadow.advance(self._front, front, self._yielding)
            if check:  # the near-miss test (no road edges loaded: vehicles only)
                near = self._world.contacts(self._near)
                if near.vehicles:
                    self._revise(self._front - 1, near.vehicles)

    def _revise(self, k: int, vehicles) -> None:
        """Revise from before sample ``k`` giving way to ``vehicles``; a contact with a vehicle
        already given way to (or one past :data:`MAX_REVISIONS`) is left as it is."""
        culprits = {int(j) for j in vehicles} - set(self._yield_to(k - 1))
        if not culprits or len(self.revisions) >= MAX_REVISIONS:
            self.collisions.append(k)
            return
        start = max(k - self._lag, self._ready, 1)
        self.collisions = [c for c in self.collisions if c <= start]  # to be driven again
        self.revisions.append((start, k + self._after, tuple(sorted(culprits))))
        self._yielding[start : k + self._after + 1] = True
        self._restart()
        # replay: the same ticks as before up to ``start``
        self._front, _ = self._shadow.advance(self._front, start, self._yielding, record=False)

    def _advance(self, ready: int) -> None:
        with self._lock:
            n = len(self.t)
            ready = min(ready, n)
            while self._ready < ready:  # whole blocks, each ending at a fixed tick
                self._simulate(min((self._front - 1) // self._block * self._block + self._block + 1,
                                   n))  # fmt: skip
                final = n if self._front == n else self._front - self._lag
                for k in range(max(self._ready, 1), final):
                    self._known_length += float(np.hypot(*(self._xy[k] - self._xy[k - 1])))
                self._ready = max(self._ready, final)
            if self.complete:
                self._world = self._driver = self._shadow = None  # free the shadow world

    def _could_reach(self, travelled: float, tolerance: float) -> bool:
        """False when ``travelled`` is short of the reached share of the part known so far
        (with a margin for rounding): the whole path is at least as long. Otherwise the
        shadow world runs ahead until that rules it out, or to the end."""

        def short() -> bool:
            return travelled < REACHED_SHARE * self._known_length - tolerance - 1e-6

        with self._lock:
            while not self.complete and not short():
                self._advance(self._ready + 1)
            return self.complete or not short()


def reference_from_track(track: Track, center_offset: float) -> ReferenceTrajectory:
    """The recorded future of ``track`` (footprint centres) as rear-axle positions."""
    xy = rear_axle_of(np.stack([track.x, track.y], axis=1), track.heading, center_offset)
    return ReferenceTrajectory(track.t - track.t[0], xy, track.heading.copy(), track.speed.copy())


def human_reference(scenario: Scenario, seed: int, duration: float) -> HumanReference:
    """The (shared, lazily advanced) reference of a generated scene for ``seed``."""
    key = (scenario.config.model_dump_json() + f"|{duration}", int(seed))
    with _CACHE_LOCK:
        ref = _CACHE.get(key)
        if ref is not None:
            _CACHE.move_to_end(key)
            return ref
        ref = _CACHE[key] = HumanReference(scenario, seed, duration)
        if len(_CACHE) > _CACHE_SIZE:
            _CACHE.popitem(last=False)
        return ref
