"""Human driving profiles: recorded speed and lateral wander, scaled into scenario bounds.

Used by synthetic traffic (one profile per participant, chained when it runs out) and by the
human reference driver of generated scenes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from gridsim.traffic.profile_kernels import chain_at, chain_samples, start_scale
from gridsim.traffic.track import Track

#: Samples computed beyond those :meth:`ProfileChain.at` needs, so that it extends the chain
#: once a second rather than every tick.
_AHEAD = 10


@dataclass(frozen=True)
class SpeedBounds:
    """Scenario bounds for replayed profiles: speeds [m/s] and acceleration [m/s^2]."""

    v_min: float
    v_max: float
    a_max: float


class HumanProfiles:
    """Profiles of library tracks: time ``t`` [s] from 0, travelled distance ``dist`` [m],
    smoothed speed ``v`` [m/s] and lateral offset ``d`` [m] (clipped to stay in a lane of
    ``lane_width`` metres). A profile is replayed with a speed scale ``k``."""

    def __init__(self, tracks: list[Track], bounds: SpeedBounds, lane_width: float) -> None:
        if not tracks:
            raise ValueError("human profiles need at least one library track")
        self.bounds = bounds
        self.t, self.dist, self.v, self.d = [], [], [], []
        for tr in tracks:
            v = tr.smoothed_speed()
            t = tr.t - tr.t[0]
            d_max = max(0.0, 0.5 * (lane_width - tr.width) - 0.2)
            self.t.append(t)
            self.v.append(v)
            self.dist.append(
                np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
            )
            self.d.append(np.clip(tr.lateral_offset(), -d_max, d_max))
        self.sizes = np.array([(tr.length, tr.width) for tr in tracks])
        self._v_lo = np.array([max(v.min(), 0.1) for v in self.v])
        self._v_hi = np.array([max(v.max(), 0.1) for v in self.v])
        self._firsts: tuple[np.ndarray, ...] | None = None

    def __len__(self) -> int:
        return len(self.t)

    def scale_range(self, i: int) -> tuple[float, float]:
        """Speed scales keeping profile ``i`` inside ``[v_min, v_max]`` (when both bounds
        cannot hold, the upper one wins; replay clips the rest)."""
        hi = self.bounds.v_max / self._v_hi[i]
        return min(self.bounds.v_min / self._v_lo[i], hi), hi

    def scale_for(self, i: int, v_mean: float) -> float:
        """The feasible scale closest to giving profile ``i`` a mean speed of ``v_mean``."""
        k = v_mean / (0.5 * (self._v_lo[i] + self._v_hi[i]))
        lo, hi = self.scale_range(i)
        return float(min(max(k, lo), hi))  # np.clip's bits, without its call overhead

    def draw(self, rng: np.random.Generator) -> tuple[int, float]:
        """A random profile and scale, for a random mean speed within the bounds."""
        i = int(rng.integers(len(self)))
        return i, self.scale_for(i, rng.uniform(self.bounds.v_min, self.bounds.v_max))

    def continue_from(self, rng: np.random.Generator, v_now: float) -> tuple[int, float]:
        """A random profile and the scale that starts it at (about) ``v_now``."""
        i = int(rng.integers(len(self)))
        b = self.bounds
        return i, start_scale(v_now, self.v[i][0], self._v_lo[i], self._v_hi[i], b.v_min, b.v_max)

    @property
    def firsts(self) -> tuple[np.ndarray, ...]:
        """Per profile: first speed [m/s] and offset [m], lowest and highest speed [m/s] (as
        :meth:`continue_from` floors them), for
        :func:`~gridsim.traffic.profile_kernels.continue_profiles`."""
        if self._firsts is None:
            v0 = np.array([v[0] for v in self.v])
            d0 = np.array([d[0] for d in self.d])
            self._firsts = (v0, d0, self._v_lo, self._v_hi)
        return self._firsts


@lru_cache(maxsize=16)
def human_profiles(tracks: tuple[Track, ...], bounds: SpeedBounds, lane_width: float):
    """The :class:`HumanProfiles` of ``tracks``, built once per process (they do not depend on
    the episode seed; smoothing every track costs ~0.1 s)."""
    return HumanProfiles(list(tracks), bounds, lane_width)


class ProfileChain:
    """Profiles chained end to end for ``duration`` seconds, sampled every ``dt`` [s], produced
    on demand: :meth:`extend` computes samples up to an index, so that a consumer pays only
    for the time it reaches. ``times`` is complete from the start; ``speeds`` [m/s] (scaled,
    clipped to the bounds, rate-limited to ``a_max`` from ``v_start``) and ``offsets`` [m]
    (each new profile's offset jump decays with a 2 s time constant) are valid up to
    :attr:`ready`. The samples do not depend on how the work is split into calls."""

    def __init__(
        self,
        profiles: HumanProfiles,
        rng: np.random.Generator,
        duration: float,
        dt: float,
        v_start: float,
    ) -> None:
        self.profiles, self.rng, self.dt = profiles, rng, dt
        self.times = np.arange(0.0, duration + dt / 2, dt)
        self.speeds = np.empty_like(self.times)
        self.offsets = np.empty_like(self.times)
        self.ready = 0
        self._i, self._k = profiles.continue_from(rng, v_start)
        self._start, self._v_prev, self._d_bias = 0.0, v_start, -profiles.d[self._i][0]

    def at(self, t: float) -> tuple[float, float]:
        """Speed [m/s] and offset [m] at time ``t`` [s], interpolated between the samples
        around it (computed first if needed)."""
        n = int(t / self.dt) + 3  # up to the sample after t
        if self.ready < n:
            self.extend(n + _AHEAD)
        return chain_at(t, self.times, self.speeds, self.offsets, self.ready)

    def extend(self, n: int) -> None:
        """Compute the samples up to index ``n`` (exclusive; capped at the end)."""
        hp, b, dt = self.profiles, self.profiles.bounds, self.dt
        i, k, start, v_prev, d_bias = self._i, self._k, self._start, self._v_prev, self._d_bias
        out, limits = (self.times, self.speeds, self.offsets), (b.v_min, b.v_max, b.a_max, dt)
        m, end = self.ready, min(n, len(self.times))
        while m < end:
            m, v_prev = chain_samples(out, m, end, (hp.t[i], hp.v[i], hp.d[i]),
                                      (k, start, d_bias, v_prev), limits)  # fmt: skip
            if m < end:  # the profile ran out before sample m: chain the next one
                v_end, d_end = self.speeds[m - 1], self.offsets[m - 1]
                i, k = hp.continue_from(self.rng, v_end)
                start = float(self.times[m])
                d_bias = d_end - hp.d[i][0]
        self.ready = max(self.ready, end)
        self._i, self._k, self._start, self._v_prev, self._d_bias = i, k, start, v_prev, d_bias
