"""A scripted ego driver: keeps its route (pure pursuit) and its distance (IDM)."""

from __future__ import annotations

import numpy as np

from gridsim.vehicle.control import PursuitGains, follow_path
from gridsim.vehicle.idm import IDMParams, idm_acceleration
from gridsim.vehicle.kinematics import V


class LaneFollower:
    """Follows ``world.route`` at up to ``speed`` [m/s], braking for traffic on the route.

    It tracks its position along the route from call to call (a few segments of walking
    instead of a projection onto the whole route).
    """

    def __init__(
        self,
        speed: float,
        idm: IDMParams | None = None,
        gains: PursuitGains | None = None,
        lookahead: float = 60.0,
    ) -> None:
        self.speed, self.lookahead = speed, lookahead
        self.idm = idm or IDMParams()
        self.gains = gains or PursuitGains()
        self._route_id: int | None = None
        self._hint = 0

    def __call__(self, world) -> tuple[float, float]:
        """Inputs ``(acceleration [m/s^2], steering rate [rad/s])`` for the current state."""
        return self.inputs(world, self.speed, 0.0)

    def _track(self, route, xy: np.ndarray) -> float:
        if id(route) != self._route_id:  # a new (or regenerated) route: search all of it
            _, _, seg = route.project(xy[None])
            self._route_id, self._hint = id(route), int(seg[0])
        s, _, self._hint = route.track(float(xy[0]), float(xy[1]), self._hint)
        return s

    def inputs(self, world, speed: float, offset: float) -> tuple[float, float]:
        """Inputs keeping lateral ``offset`` [m] from the route at up to ``speed`` [m/s]."""
        route = world.route
        p = world.ego_params
        s_rear = self._track(route, world.ego[:2])
        accel, steer_rate = follow_path(world.ego, route, speed, p, self.gains, offset, s_rear)
        gap, lead_v = self._leader(world, route, s_rear)
        if np.isfinite(gap):
            v = world.ego[V]
            a_idm = idm_acceleration(
                np.array(v), np.array(speed), np.array(gap), np.array(v - lead_v), self.idm
            )
            accel = min(accel, float(a_idm))
        return float(np.clip(accel, -p.b_max, p.a_max)), steer_rate

    def _leader(self, world, route, s_rear: float) -> tuple[float, float]:
        f = world.traffic.fleet
        ego_p = world.ego_params
        x, y, psi = world.ego[0], world.ego[1], world.ego[2]
        lon = (f.x - x) * np.cos(psi) + (f.y - y) * np.sin(psi)
        near = f.active & (lon > 0) & (np.hypot(f.x - x, f.y - y) < self.lookahead)
        idx = np.flatnonzero(near)
        if len(idx) == 0:
            return np.inf, 0.0
        s, d, _ = route.project(np.stack([f.x[idx], f.y[idx]], axis=1), hint=self._hint, window=96)
        ahead = (s > s_rear) & (np.abs(d) < 0.5 * (f.width[idx] + ego_p.width) + 0.3)
        if not np.any(ahead):
            return np.inf, 0.0
        k = np.argmin(np.where(ahead, s, np.inf))
        j = idx[k]
        # Centre to centre along the route, less half of both lengths (the ego's centre is
        # center_offset ahead of its rear axle).
        gap = s[k] - (s_rear + ego_p.center_offset) - 0.5 * (f.length[j] + ego_p.length)
        return float(gap), float(f.v[j])


class HumanDriver:
    """Drives the route with a human speed and lateral-offset profile (arrays over time from
    the start of the episode), keeping its distance to traffic like :class:`LaneFollower`."""

    def __init__(
        self,
        times: np.ndarray,
        speeds: np.ndarray,
        offsets: np.ndarray,
        follower: LaneFollower | None = None,
    ) -> None:
        self.times, self.speeds, self.offsets = times, speeds, offsets
        self.follower = follower or LaneFollower(speed=float(np.max(speeds)))

    def __call__(self, world) -> tuple[float, float]:
        t = world.time
        speed = float(np.interp(t, self.times, self.speeds))
        offset = float(np.interp(t, self.times, self.offsets))
        return self.follower.inputs(world, speed, offset)
