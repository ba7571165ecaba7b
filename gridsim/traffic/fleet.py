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
  ``resume_factor * s*`` and its speed has caught up with the profile.

Leaders are found without O(N^2) work: a k-d tree gives the pairs within ``lookahead``
metres, and a pair counts if the other vehicle lies ahead on the follower's own path: within
half the sum of both widths (plus a margin) of the path point as far ahead as the other
vehicle is along the follower's heading.
On recorded scenes, a replaying vehicle ignores replaying leaders: the recording is
collision-free among itself; only the ego and vehicles in IDM mode can be in its way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from gridsim.traffic.tables import PathBank, TableBank
from gridsim.vehicle.idm import IDMParams, desired_gap, idm_acceleration

REPLAY, IDM = 0, 1
_S, _V, _D, _H = range(4)


@dataclass(frozen=True)
class FleetParams:
    """Car-following and look-up settings."""

    idm: IDMParams = IDMParams()
    lookahead: float = 60.0
    resume_factor: float = 1.3
    resume_speed_tol: float = 0.5
    lateral_margin: float = 0.2
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
        self.p = params or FleetParams()
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

    @property
    def capacity(self) -> int:
        return len(self.active)

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
        vals, _ = self.profiles.lookup(np.array([profile]), np.array([tau]))
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

    def _update_pose(self, idx: np.ndarray) -> None:
        p, h = self.paths.frenet_to_world(self.path[idx], self.s[idx], self.d[idx])
        self.x[idx], self.y[idx] = p[:, 0], p[:, 1]
        geo = self.geometric[idx] & (self.mode[idx] == REPLAY)
        if np.any(geo):
            vals, _ = self.profiles.lookup(self.profile[idx[geo]], self.tau[idx[geo]])
            h = h.copy()
            h[geo] = vals[:, _H]
        self.psi[idx] = h

    # -- leaders ----------------------------------------------------------------------------------
    def find_leaders(self, ego: EgoPose | None) -> None:
        """Set :attr:`gap` (bumper to bumper [m], inf if none), :attr:`leader` (index, ``-2``
        for the ego, ``-1`` for none) and the leader speed along the follower's heading."""
        idx = np.flatnonzero(self.active)
        n = len(idx)
        self.gap[:] = np.inf
        self.leader[:] = -1
        self._lead_v = np.zeros(self.capacity)
        if n == 0:
            return
        px = np.append(self.x[idx], ego.x if ego else np.inf)
        py = np.append(self.y[idx], ego.y if ego else np.inf)
        psi = np.append(self.psi[idx], ego.psi if ego else 0.0)
        vel = np.append(self.v[idx], ego.v if ego else 0.0)
        length = np.append(self.length[idx], ego.length if ego else 0.0)
        width = np.append(self.width[idx], ego.width if ego else 0.0)
        m = n + 1 if ego else n
        tree = cKDTree(np.stack([px[:m], py[:m]], axis=1))
        pairs = tree.query_pairs(self.p.lookahead, output_type="ndarray")
        if len(pairs) == 0:
            return
        a = np.concatenate([pairs[:, 0], pairs[:, 1]])
        b = np.concatenate([pairs[:, 1], pairs[:, 0]])
        follower = a < n  # the ego is never a follower
        a, b = a[follower], b[follower]
        dx, dy = px[b] - px[a], py[b] - py[a]
        ahead = dx * np.cos(psi[a]) + dy * np.sin(psi[a]) > 0
        same_dir = np.cos(psi[b] - psi[a]) > 0.0
        keep = ahead & same_dir
        # On recorded scenes, replaying vehicles trust replaying recorded leaders.
        ga = self.geometric[idx[a]] & (self.mode[idx[a]] == REPLAY)
        bb = np.minimum(b, n - 1)
        gb = (b < n) & self.geometric[idx[bb]] & (self.mode[idx[bb]] == REPLAY)
        keep &= ~(ga & gb)
        a, b, dx, dy = a[keep], b[keep], dx[keep], dy[keep]
        if len(a) == 0:
            return
        dist = np.hypot(dx, dy)
        lon = dx * np.cos(psi[a]) + dy * np.sin(psi[a])
        ia = idx[a]
        q, _ = self.paths.frenet_to_world(self.path[ia], self.s[ia] + lon, self.d[ia])
        lat = np.hypot(px[b] - q[:, 0], py[b] - q[:, 1])
        on_path = lat < 0.5 * (width[a] + width[b]) + self.p.lateral_margin
        a, b, dist = a[on_path], b[on_path], dist[on_path]
        if len(a) == 0:
            return
        gap = dist - 0.5 * (length[a] + length[b])
        order = np.lexsort((gap, a))
        first = np.r_[True, a[order][1:] != a[order][:-1]]
        sel = order[first]
        fa, fb = idx[a[sel]], b[sel]
        self.gap[fa] = gap[sel]
        self.leader[fa] = np.where(fb < n, idx[np.minimum(fb, n - 1)], -2)
        self._lead_v[fa] = vel[fb] * np.cos(psi[fb] - psi[a[sel]])

    # -- the tick --------------------------------------------------------------------------------
    def tick(self, dt: float, ego: EgoPose | None) -> np.ndarray:
        """Advance all active participants by ``dt`` seconds. Returns the indices whose
        profile ran out this tick (recorded vehicles are deactivated; synthetic ones must be
        given a new profile by the caller)."""
        self.find_leaders(ego)
        idx = np.flatnonzero(self.active)
        if len(idx) == 0:
            return idx
        p = self.p
        prof, tau, k = self.profile[idx], self.tau[idx], self.k[idx]
        now, _ = self.profiles.lookup(prof, tau)
        nxt, _ = self.profiles.lookup(prof, tau + dt)
        v = self.v[idx]
        v_rep = np.minimum(k * nxt[:, _V], p.v_max)
        gap = self.gap[idx]
        dv = v - self._lead_v[idx]
        s_star = desired_gap(v, dv, p.idm)
        mode = self.mode[idx]
        to_idm = (mode == REPLAY) & (gap < s_star)
        s_star_rep = desired_gap(v_rep, v_rep - self._lead_v[idx], p.idm)
        to_replay = (
            (mode == IDM) & (gap > p.resume_factor * s_star_rep) & (v >= v_rep - p.resume_speed_tol)
        )
        mode = np.where(to_idm, IDM, np.where(to_replay, REPLAY, mode)).astype(np.int8)
        follow = mode == IDM

        # Replay: recorded scenes move by the recorded distance (exact poses); synthetic
        # participants integrate the scaled speed, rate-limited to the scenario's bounds.
        geo = self.geometric[idx]
        v_syn = np.clip(np.clip(v_rep, p.v_min, p.v_max), v - p.b_max * dt, v + p.a_max * dt)
        new_v = np.where(geo, v_rep, v_syn)
        new_s = self.s[idx] + np.where(geo, nxt[:, _S] - now[:, _S], 0.5 * (v + new_v) * dt)
        new_tau = tau + dt
        # IDM: desired speed = the profile's speed now.
        if np.any(follow):
            f = np.flatnonzero(follow)
            a = idm_acceleration(v[f], k[f] * now[f, _V], gap[f], dv[f], p.idm)
            vf = np.clip(v[f] + a * dt, 0.0, p.v_max)
            ds = 0.5 * (v[f] + vf) * dt
            new_s[f] = self.s[idx[f]] + ds
            new_v[f] = vf
            rate = np.clip(ds / np.maximum(k[f] * now[f, _V] * dt, 1e-3), 0.0, 1.0)
            new_tau[f] = tau[f] + rate * dt
        self.d_bias[idx] *= np.exp(-dt / 2.0)
        after, _ = self.profiles.lookup(prof, new_tau)
        self.s[idx], self.v[idx], self.tau[idx], self.mode[idx] = new_s, new_v, new_tau, mode
        self.d[idx] = np.where(follow, self.d[idx], after[:, _D] + self.d_bias[idx])
        self._update_pose(idx)
        _, hi = self.profiles.ranges(prof)
        ended = idx[new_tau > hi + 1e-9]
        geo_end = ended[self.geometric[ended]]
        self.deactivate(geo_end)
        return ended

    def footprints(self) -> tuple[np.ndarray, ...]:
        """``(x, y, psi, length, width)`` of the active participants (centre poses)."""
        a = self.active
        return self.x[a], self.y[a], self.psi[a], self.length[a], self.width[a]
