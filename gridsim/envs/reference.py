"""Reference trajectories: where a human would drive in this episode.

On recorded scenes it is the ego track's own recorded future. On generated roads it is a
human speed and lane-offset profile replayed along the ego's route, exactly like traffic:
a shadow copy of the episode's world (same scenario, same seed) is driven by a
:class:`~gridsim.world.driver.HumanDriver` (which keeps its distance to traffic with IDM),
and its ego states are recorded. A policy that follows the reference therefore meets the
same traffic. References are cached per (scenario, seed): all individuals of a population
evaluated on the same seeds share them.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from gridsim.scenario.build import build_world, road_lane_width, synthetic_tracks
from gridsim.scenario.loader import Scenario
from gridsim.traffic.library import Track
from gridsim.traffic.profiles import HumanProfiles, SpeedBounds
from gridsim.world.driver import HumanDriver

_CACHE: OrderedDict[tuple[str, int], ReferenceTrajectory] = OrderedDict()
_CACHE_SIZE = 64


@dataclass(frozen=True)
class ReferenceTrajectory:
    """Rear-axle positions ``xy`` [m, world], headings [rad] and speeds [m/s] at times ``t``
    [s] from the start of the episode. Beyond the last sample it continues at constant
    velocity."""

    t: np.ndarray
    xy: np.ndarray
    psi: np.ndarray
    v: np.ndarray

    @property
    def end_time(self) -> float:
        return float(self.t[-1])

    def positions(self, times: np.ndarray) -> np.ndarray:
        """Positions ``(N, 2)`` at ``times`` [s] (interpolated; extrapolated past the end)."""
        times = np.asarray(times, dtype=np.float64)
        x = np.interp(times, self.t, self.xy[:, 0])
        y = np.interp(times, self.t, self.xy[:, 1])
        late = times > self.t[-1]
        if np.any(late):
            extra = times[late] - self.t[-1]
            x[late] += extra * self.v[-1] * np.cos(self.psi[-1])
            y[late] += extra * self.v[-1] * np.sin(self.psi[-1])
        return np.stack([x, y], axis=1)


def reference_from_track(track: Track, center_offset: float) -> ReferenceTrajectory:
    """The recorded future of ``track`` (footprint centres) as rear-axle positions."""
    u = np.stack([np.cos(track.heading), np.sin(track.heading)], axis=1)
    xy = np.stack([track.x, track.y], axis=1) - center_offset * u
    return ReferenceTrajectory(track.t - track.t[0], xy, track.heading.copy(), track.speed.copy())


def human_reference(scenario: Scenario, seed: int, duration: float) -> ReferenceTrajectory:
    """The reference of a generated scene: a human profile driven in a shadow world."""
    key = (scenario.config.model_dump_json() + f"|{duration}", int(seed))
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit
    cfg = scenario.config
    world = build_world(scenario, seed)
    lo, hi = cfg.speed_range
    bounds = SpeedBounds(lo, min(hi, cfg.ego.vehicle.v_max), cfg.ego.vehicle.a_max)
    profiles = HumanProfiles(synthetic_tracks(scenario), bounds, road_lane_width(scenario))
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5EF]))
    dt = world.dt
    times, speeds, offsets = profiles.chain(rng, duration, dt, float(world.ego[3]))
    driver = HumanDriver(times, speeds, offsets)
    n = len(times)
    xy, psi, v = np.empty((n, 2)), np.empty(n), np.empty(n)
    xy[0], psi[0], v[0] = world.ego[:2], world.ego[2], world.ego[3]
    for k in range(1, n):
        world.tick(*driver(world))
        xy[k], psi[k], v[k] = world.ego[:2], world.ego[2], world.ego[3]
    ref = ReferenceTrajectory(times, xy, psi, v)
    _CACHE[key] = ref
    if len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return ref
