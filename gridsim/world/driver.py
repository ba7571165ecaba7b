"""A scripted ego driver: keeps its route (pure pursuit) and its distance (IDM)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gridsim.vehicle.control import PursuitGains, follow_path
from gridsim.vehicle.idm import IDMParams, idm_acceleration
from gridsim.vehicle.kinematics import V


@dataclass(frozen=True)
class LaneFollower:
    """Follows ``world.route`` at up to ``speed`` [m/s], braking for traffic on the route."""

    speed: float
    idm: IDMParams = IDMParams()
    gains: PursuitGains = PursuitGains()
    lookahead: float = 60.0

    def __call__(self, world) -> tuple[float, float]:
        """Inputs ``(acceleration [m/s^2], steering rate [rad/s])`` for the current state."""
        return self.inputs(world, self.speed, 0.0)

    def inputs(self, world, speed: float, offset: float) -> tuple[float, float]:
        """Inputs keeping lateral ``offset`` [m] from the route at up to ``speed`` [m/s]."""
        route = world.route
        p = world.ego_params
        accel, steer_rate = follow_path(world.ego, route, speed, p, self.gains, offset)
        gap, lead_v = self._leader(world, route)
        if np.isfinite(gap):
            v = world.ego[V]
            a_idm = idm_acceleration(
                np.array(v), np.array(speed), np.array(gap), np.array(v - lead_v), self.idm
            )
            accel = min(accel, float(a_idm))
        return float(np.clip(accel, -p.b_max, p.a_max)), steer_rate

    def _leader(self, world, route) -> tuple[float, float]:
        f = world.traffic.fleet
        c = world.ego_center()
        idx = np.flatnonzero(f.active & (np.hypot(f.x - c[0], f.y - c[1]) < self.lookahead))
        if len(idx) == 0:
            return np.inf, 0.0
        s_ego, _, _ = route.project(c[None])
        s, d, _ = route.project(np.stack([f.x[idx], f.y[idx]], axis=1))
        ahead = (s > s_ego[0]) & (np.abs(d) < 0.5 * (f.width[idx] + world.ego_params.width) + 0.3)
        if not np.any(ahead):
            return np.inf, 0.0
        k = np.argmin(np.where(ahead, s, np.inf))
        j = idx[k]
        gap = s[k] - s_ego[0] - 0.5 * (f.length[j] + world.ego_params.length)
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
