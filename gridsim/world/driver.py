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
        route = world.route
        accel, steer_rate = follow_path(world.ego, route, self.speed, world.ego_params, self.gains)
        gap, lead_v = self._leader(world, route)
        if np.isfinite(gap):
            v = world.ego[V]
            a_idm = float(
                idm_acceleration(
                    np.array(v), np.array(self.speed), np.array(gap), np.array(v - lead_v), self.idm
                )
            )
            accel = min(accel, a_idm)
        p = world.ego_params
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
