"""Traffic as structure-of-arrays: recorded replay with hand-over to IDM car following.

Every participant moves along a *path* (a polyline in a :class:`PathBank`) at arc length ``s``
with lateral offset ``d``, driven by a recorded *profile* (a table over profile time ``tau`` of
cumulative distance ``S``, speed ``V``, lateral offset ``D`` and heading ``H``):

- *replay*: ``tau += dt``, ``v = k V(tau')``, ``d = D(tau')``. On recorded scenes the path is
  the vehicle's own track, ``k = 1`` and ``s += S(tau') - S(tau)``: the pose is exact. On
  generated roads ``k`` scales the profile into the scenario's speed range, ``v`` is also
  rate-limited to its acceleration bounds, and ``s`` integrates ``v``.
- *IDM*: when replay would close in on the vehicle ahead (gap below the IDM desired gap
  ``s*``), the vehicle follows the IDM with the replay speed as desired speed, and its profile
  time advances in proportion to its progress. It hands back to replay once the gap exceeds
  ``resume_factor * s*`` (at the faster of its speed and the replay speed) and its speed has
  caught up with the profile. A recorded vehicle
  keeps the recorded heading at its profile time in both modes (never the tangent of its
  recorded path, which is position noise where it stood still).

Leaders are found without O(N^2) work (see :meth:`Fleet.find_leaders`): the next vehicle on
the same path, the ego, and for vehicles outside lane corridors, k-d tree pairs whose other
vehicle lies ahead on the follower's own path. On recorded scenes, a replaying vehicle ignores
replaying leaders: the recording is collision-free among itself; only the ego and vehicles in
IDM mode can be in its way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial import cKDTree

from gridsim import libm
from gridsim.traffic import fleet_kernels as kernels
from gridsim.traffic.fleet_kernels import IDM as IDM  # the modes, re-exported
from gridsim.traffic.fleet_kernels import REPLAY
from gridsim.traffic.tables import PathBank, TableBank
from gridsim.vehicle.idm import IDMParams

_V, _D = 1, 2
_NO_CANDIDATES = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
_NO_CORRIDORS = np.zeros(0, np.int64)
_NO_EGO = (False, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
_EVERYWHERE = (np.inf, np.inf)


@dataclass(frozen=True)
class FleetParams:
    """Car-following and look-up settings."""

    idm: IDMParams = IDMParams()
    lookahead: float = 50.0
    resume_factor: float = 1.3
    resume_speed_tol: float = 0.5
    lateral_margin: float = 0.2
    #: s: an ego crossing a synthetic participant's path (or coming the other way) is its
    #: leader once the participant would reach it within this time; also how far ahead in
    #: time both are swept to find a conflict before it (see ``ego_ahead``, ``swept_conflict``)
    crossing_horizon: float = 2.0
    #: Bounds applied to synthetic (non-recorded) participants in replay.
    v_min: float = 0.0
    v_max: float = np.inf
    a_max: float = np.inf
    b_max: float = np.inf


@dataclass
class EgoPose:
    """The ego as seen by traffic: footprint centre [m], heading [rad], speed [m/s], size [m]."""

    x: float
    y: float
    psi: float
    v: float
    length: float
    width: float


class Fleet:
    """All traffic participants of a world, as arrays of length ``capacity``."""

    def __init__(self, capacity: int, params: FleetParams | None = None) -> None:
        self.p = p = params or FleetParams()
        #: The compiled tick's settings: leader search, replay limits, IDM parameters.
        self._settings = (
            (p.lookahead, p.lateral_margin, p.crossing_horizon),
            (p.v_min, p.v_max, p.a_max, p.b_max, p.resume_factor, p.resume_speed_tol),
            p.idm.values,
        )
        self.paths = PathBank()
        self.profiles = TableBank(width=4)
        n = capacity
        self.active = np.zeros(n, bool)
        self.geometric = np.zeros(n, bool)
        self.mode = np.zeros(n, np.int8)
        self.path = np.zeros(n, np.int64)
        self.profile = np.zeros(n, np.int64)
        self.s = np.zeros(n)
        self.d = np.zeros(n)
        self.v = np.zeros(n)
        self.tau = np.zeros(n)
        self.k = np.ones(n)
        self.d_bias = np.zeros(n)
        self.length = np.full(n, 4.5)
        self.width = np.full(n, 1.8)
        self.x = np.zeros(n)
        self.y = np.zeros(n)
        self.psi = np.zeros(n)
        self.gap = np.full(n, np.inf)
        self.leader = np.full(n, -1, np.int64)
        self.lead_v = np.zeros(n)

    @property
    def capacity(self) -> int:
        return len(self.active)

    def relaid(self, capacity: int, where: np.ndarray) -> Fleet:
        """A fleet of ``capacity`` participants (sharing the paths and profiles) whose
        participant ``where[i]`` is this one's ``i``, leaders renumbered; the others
        inactive. ``where`` increasing: the participants keep their order."""
        new = Fleet(capacity, self.p)
        new.paths, new.profiles = self.paths, self.profiles
        for mine, theirs in zip(self.state, new.state, strict=True):
            theirs[where] = mine[: len(where)]
        new.leader[where] = np.where(self.leader[: len(where)] >= 0,
                                     where[np.maximum(self.leader[: len(where)], 0)],
                                     self.leader[: len(where)])  # fmt: skip
        return new

    @property
    def state(self) -> tuple[np.ndarray, ...]:
        """The arrays in :class:`~gridsim.traffic.fleet_kernels.FleetState` order, for the
        compiled tick."""
        return (self.active, self.geometric, self.mode, self.path, self.profile, self.s, self.d,
                self.v, self.tau, self.k, self.d_bias, self.length, self.width, self.x, self.y,
                self.psi, self.gap, self.leader, self.lead_v)  # fmt: skip

    # -- set-up ---------------------------------------------------------------------------------
    def place(
        self,
        i: int,
        *,
        path: int,
        s: float,
        profile: int,
        tau: float,
        k: float = 1.0,
        d_bias: float = 0.0,
        geometric: bool = False,
        length: float = 4.5,
        width: float = 1.8,
    ) -> None:
        """Put participant ``i`` on ``path`` at arc length ``s``, replaying ``profile`` from
        ``tau``; its speed and offset come from the profile."""
        vals = self.profiles.lookup(np.array([profile]), np.array([tau]))
        self.active[i] = True
        self.geometric[i] = geometric
        self.mode[i] = REPLAY
        self.path[i], self.s[i], self.profile[i], self.tau[i] = path, s, profile, tau
        self.k[i], self.d_bias[i] = k, d_bias
        self.v[i] = k * vals[0, _V]
        self.d[i] = vals[0, _D] + d_bias
        self.length[i], self.width[i] = length, width
        self._update_pose(np.array([i]))

    def deactivate(self, idx: np.ndarray) -> None:
        self.active[idx] = False
        self.gap[idx] = np.inf
        self.leader[idx] = -1

    def occupied(self, x, y, heading, length, width, ego: EgoPose, along, side) -> bool:
        """Whether an active participant or the ego overlaps a ``length`` x ``width`` [m]
        box at ``(x, y)`` [m] with ``heading`` [rad], grown by ``along`` [m] at both ends and
        by ``side`` [m] at both sides (beyond the footprints)."""
        pose = (float(ego.x), float(ego.y), float(ego.length), float(ego.width))
        return kernels.occupied(self.state, pose, x, y, heading, length, width, along, side)

    def _update_pose(self, idx: np.ndarray) -> None:
        kernels.update_poses(idx, self.state, self.paths.kernel_data(), self.profiles.kernel_data())

    # -- leaders ----------------------------------------------------------------------------------
    def find_leaders(self, ego: EgoPose | None) -> None:
        """Set :attr:`gap` (bumper to bumper [m], inf if none), :attr:`leader` (index, ``-2``
        for the ego, ``-1`` for none) and :attr:`lead_v`, the leader speed along the
        follower's heading [m/s].

        Candidates come from three sources, none of them O(N^2): the next vehicle on the same
        path (a sort by arc length); the ego (one vectorised test); and, for vehicles outside
        a lane corridor (city routes, recorded tracks), pairs from a k-d tree. Vehicles in a
        corridor keep their lane, so their leader is the next vehicle on their own lane.
        """
        kernels.leaders(self.state, _ego(ego), self._cross_candidates(), self.paths.kernel_data(),
                        *self._settings[0])  # fmt: skip

    def _cross_candidates(self, crossings: bool = True) -> tuple[np.ndarray, ...]:
        """Leader candidates ``(a, b, gap, lead_v)`` on other paths for the vehicles outside
        lane corridors: kept if the other vehicle lies on the follower's path as far ahead as
        it is (:func:`~gridsim.traffic.fleet_kernels.cross_path`), then (with ``crossings``)
        those of generated vehicles giving way where their paths cross
        (:func:`~gridsim.traffic.fleet_kernels.crossing_candidates`); none when all are in
        a corridor. Pairs come from all pairs when few vehicles are active (as the compiled
        world tick finds them: :func:`~gridsim.traffic.fleet_kernels.all_pairs_candidates`),
        else from a k-d tree. Pairs inside one corridor are left to
        :func:`~gridsim.traffic.fleet_kernels.same_path`."""
        if self.paths.all_in_corridors:
            return _NO_CANDIDATES
        idx = np.flatnonzero(self.active)
        paths = self.paths.kernel_data()
        if len(idx) <= kernels.ALL_PAIRS_MAX:
            return kernels.all_pairs_candidates(self.state, idx, self.paths.corridor_ids, paths,
                                                self._settings[0], crossings)  # fmt: skip
        corridor = self.paths.corridors(self.path[idx])
        if np.all(corridor >= 0):
            return _NO_CANDIDATES
        pts = np.stack([self.x[idx], self.y[idx]], axis=1)
        pairs = cKDTree(pts).query_pairs(self.p.lookahead, output_type="ndarray")
        c, sn = np.cos(self.psi[idx]), np.sin(self.psi[idx])
        p = self.p
        found = kernels.cross_path(idx, corridor, c, sn, pairs[:, 0], pairs[:, 1], False,
                                   self.state, paths, p.lookahead, p.lateral_margin)  # fmt: skip
        if not crossings:
            return found
        reach = 2.0 * kernels.longest_reach(self.state, idx, p.crossing_horizon) + p.lateral_margin
        if reach > p.lookahead:  # pairs near enough to meet at a crossing (near_pair)
            pairs = cKDTree(pts).query_pairs(reach, output_type="ndarray")
        crossing = kernels.crossing_candidates(idx, pairs[:, 0], pairs[:, 1], self.state, paths,
                                               p.lateral_margin, p.crossing_horizon)  # fmt: skip
        return kernels.joined(found, crossing)

    # -- the tick --------------------------------------------------------------------------------
    def tick(
        self, dt: float, ego: EgoPose | None, window: tuple[float, float] = _EVERYWHERE
    ) -> np.ndarray:
        """Advance all active participants by ``dt`` seconds; then deactivate those more
        than ``window = (behind, ahead)`` metres behind or ahead of the ego, measured along
        its heading. Returns the indices whose profile ran out this tick (recorded vehicles
        are deactivated; synthetic ones must be given a new profile by the caller)."""
        state, paths, profiles, settings, decay, window = self.tick_data(dt, window)
        return kernels.tick(state, _ego(ego), self._cross_candidates(), paths, profiles,
                            *settings, dt, decay, window)  # fmt: skip

    def tick_data(self, dt: float, window: tuple[float, float] = _EVERYWHERE) -> tuple:
        """The arguments of the compiled tick but the ego and the cross-path candidates:
        ``(state, paths, profiles, settings, decay, (lo, hi))``."""
        return (self.state, self.paths.kernel_data(), self.profiles.kernel_data(),
                self._settings, _decay(dt), (-window[0], window[1]))  # fmt: skip

    def cross_data(self) -> np.ndarray:
        """The paths' corridor ids (by path slot, ``-1`` for none), for a compiled leader
        search on other paths (:meth:`_cross_candidates`); empty when every path keeps to a
        corridor (no search)."""
        return _NO_CORRIDORS if self.paths.all_in_corridors else self.paths.corridor_ids

    def footprints(self) -> tuple[np.ndarray, ...]:
        """``(x, y, psi, length, width)`` of the active participants (centre poses)."""
        a = self.active
        return self.x[a], self.y[a], self.psi[a], self.length[a], self.width[a]


@lru_cache(maxsize=8)
def _decay(dt: float) -> float:
    """The factor by which a lateral bias decays over ``dt`` [s] (time constant 2 s)."""
    return libm.exp(-dt / 2.0)


def _ego(ego: EgoPose | None) -> tuple:
    """The ego for the leader search: ``(present, x, y, v, length, width, cos psi, sin
    psi)``."""
    if ego is None:
        return _NO_EGO
    return (True, float(ego.x), float(ego.y), float(ego.v), float(ego.length),
            float(ego.width), math.cos(ego.psi), math.sin(ego.psi))  # fmt: skip
