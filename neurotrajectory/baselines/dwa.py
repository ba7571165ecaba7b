"""Dynamic Window Approach for a car-like vehicle on an occupancy grid.

For each window: sample target speeds and steering angles reachable within one
``control_period`` (acceleration, braking and steering-rate limits; steering also capped by
the lateral-acceleration limit), drive towards each target for ``control_period`` and hold it
afterwards, rolling all samples out together with the bicycle model
(:func:`~gridsim.vehicle.kinematics.step_bicycle`, vectorised over samples) over the
set-point horizon; one more sample brakes to a full stop.

The footprint is ``disks`` disks along the body. A rollout is **rejected** if within its first
``collision_horizon`` seconds any disk comes closer to a non-free cell than its radius plus
``margin`` (clearances come from one distance transform of the free space per window), or if
the ego could not then brake to a stop along its heading inside free space (looking at most
``headway`` seconds ahead). An ego that already starts closer than the margin may keep any
rollout that gets no closer. The grid is a snapshot: obstacles are taken as static, which is
why only the near future rejects; later overlaps only cost (``w_late_collision``). Unknown
cells count as obstacles (``unknown="occupied"``, the default) or only add cost
(``"penalise"``); points beyond the grid are unknown but never reject.

Among the admissible rollouts the one of least weighted cost wins: distance to the
destination at the end of the horizon, heading error, obstacle proximity, speed deficit,
lateral acceleration and steering change. If no rollout is admissible, the one that keeps
the most clearance is returned (``feasible`` false).

The prediction is the winning rollout at the set-point times (grid frame, rear axle).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from gridsim.envs.frames import grid_to_pixel
from gridsim.sensors.occupancy import FREE, OCCUPIED
from gridsim.vehicle.kinematics import PSI, V, step_bicycle
from neurotrajectory.predictors import Setting
from neurotrajectory.windows import Windows


@dataclass(frozen=True)
class DWAConfig:
    """Sampling, safety and cost weights (dimensionless weights on normalised terms). The
    defaults were chosen on the train splits of the four evaluation groups."""

    speed_samples: int = 7
    steer_samples: int = 15
    control_period: float = 0.5  # s: the dynamic window is what this much time reaches
    dt: float = 0.1  # s: rollout step
    disks: int = 5  # footprint disks along the body
    margin: float = 0.05  # m of extra clearance around the footprint disks
    #: s of each rollout checked for collisions: a grid is a snapshot, and over the whole
    #: horizon a rollout that follows a moving car would run into where that car is now.
    collision_horizon: float = 0.5
    headway: float = 0.5  # s: the braking check looks at most speed * headway ahead
    unknown: str = "occupied"  # or "penalise"
    max_lateral_accel: float = 4.0  # m/s^2
    w_goal: float = 1.0
    w_heading: float = 0.02
    w_clearance: float = 0.02
    w_speed: float = 0.02
    w_lateral: float = 0.05
    w_steer_change: float = 0.05
    w_unknown: float = 0.3
    #: cost per share of the rollout after ``collision_horizon`` that would hit an obstacle
    #: were it static (moving traffic may have left by then, so it only costs)
    w_late_collision: float = 0.1

    def __post_init__(self) -> None:
        if self.unknown not in ("occupied", "penalise"):
            raise ValueError(f"unknown must be 'occupied' or 'penalise', got {self.unknown!r}")
        if self.speed_samples < 1 or self.steer_samples < 1 or self.disks < 1:
            raise ValueError("speed_samples, steer_samples and disks must be >= 1")
        if not 0 < self.dt <= self.control_period:
            raise ValueError(f"need 0 < dt <= control_period, got {self.dt}, {self.control_period}")


@dataclass(frozen=True)
class Plan:
    """The chosen rollout: ``states`` ``(K + 1, 5)`` every ``dt`` from the start (grid frame:
    x, y [m], heading [rad], speed [m/s], steering [rad]), its set-points ``(tau_o, 2)``, and
    whether any rollout was admissible."""

    states: np.ndarray
    setpoints: np.ndarray
    feasible: bool
    admissible: int


def footprint_disks(
    length: float, width: float, wheelbase: float, count: int = 5
) -> tuple[np.ndarray, float]:
    """Offsets [m] ahead of the rear axle of ``count`` disk centres, and their common radius
    [m], covering a ``length`` x ``width`` rectangle centred half a wheelbase ahead."""
    centre = 0.5 * wheelbase
    offsets = centre + (np.arange(count) - (count - 1) / 2) * length / count
    return offsets, float(np.hypot(length / (2 * count), width / 2.0))


class DWA:
    """The DWA baseline as a predictor (see the module docstring)."""

    name = "DWA"

    def __init__(self, setting: Setting, config: DWAConfig | None = None) -> None:
        self.setting = setting
        self.config = config or DWAConfig()
        steps = setting.times / self.config.dt
        if np.any(np.abs(steps - np.rint(steps)) > 1e-6):
            raise ValueError(
                f"set-point times {setting.times.tolist()} must be multiples of dt {self.config.dt}"
            )
        self._setpoint_steps = np.rint(steps).astype(int)

    def predict(self, batch: Windows) -> np.ndarray:
        return np.stack([self.plan(batch, i).setpoints for i in range(len(batch))])

    # -- one window -----------------------------------------------------------------------------
    def plan(self, batch: Windows, i: int) -> Plan:
        cfg, s = self.config, self.setting
        wheelbase, length, width = (float(v) for v in batch.vehicle[i])
        params = replace(s.params, wheelbase=wheelbase, length=length, width=width,
                         center_offset=0.5 * wheelbase)  # fmt: skip
        grid = batch.grids[i, -1]
        clearance, unknown = self._clearance(grid)
        ego = batch.ego[i].astype(np.float64)
        v0, d0 = float(ego[0]), float(ego[1])
        heading = float(np.arctan2(ego[5], ego[4]))
        v_t, d_t = self._window(v0, d0, params)
        n = v_t.size
        state = np.tile([0.0, 0.0, heading, v0, d0], (n, 1))
        k_ctrl = int(round(cfg.control_period / cfg.dt))
        accel = (v_t - v0) / cfg.control_period
        rate = (d_t - d0) / cfg.control_period
        hold = np.zeros(n)
        hold[-1] = accel[-1] = -params.b_max  # the last sample brakes to a full stop
        states = [state]
        for k in range(int(self._setpoint_steps[-1])):
            on = k < k_ctrl
            state = step_bicycle(state, accel if on else hold, rate if on else 0.0, params,
                                 cfg.dt).state  # fmt: skip
            states.append(state)
        traj = np.stack(states, axis=1)  # (n, K + 1, 5)
        offsets, radius = footprint_disks(length, width, wheelbase, cfg.disks)
        k_check = max(1, min(int(round(cfg.collision_horizon / cfg.dt)), traj.shape[1] - 1))
        last = traj[:, k_check]
        stop = np.minimum(last[:, V] ** 2 / (2.0 * params.b_max), last[:, V] * cfg.headway)
        ahead = stop[:, None] * np.array([1 / 3, 2 / 3, 1.0])[None, :]
        brake = np.stack(
            [last[:, None, 0] + ahead * np.cos(last[:, None, PSI]),
             last[:, None, 1] + ahead * np.sin(last[:, None, PSI])], axis=2,
        )  # fmt: skip
        brake_poses = np.concatenate([brake, np.repeat(last[:, None, PSI : PSI + 1], 3, 1)], 2)
        poses = np.concatenate([traj[:, 1 : k_check + 1, :3], brake_poses], axis=1)
        gap, unseen = self._sample(clearance, unknown, poses, offsets)
        min_gap = gap.min(axis=(1, 2)) - radius
        # An ego that starts closer than the margin (the disks overestimate the box) may go
        # on as long as it gets no closer.
        start_gap = self._sample(clearance, unknown, traj[:1, :1, :3], offsets)[0].min() - radius
        admissible = min_gap >= min(cfg.margin, start_gap)
        cost = self._cost(traj, batch.destination[i], min_gap, unseen, v0, d0, params)
        if cfg.w_late_collision and k_check + 1 < traj.shape[1]:
            late_gap, _ = self._sample(clearance, unknown, traj[:, k_check + 1 :, :3], offsets)
            late_hits = np.mean(late_gap.min(axis=2) - radius < 0.0, axis=1)
            cost = cost + cfg.w_late_collision * late_hits
        if np.any(admissible):
            best = int(np.argmin(np.where(admissible, cost, np.inf)))
        else:
            best = int(np.argmax(min_gap))
        chosen = traj[best]
        return Plan(chosen, chosen[self._setpoint_steps, :2].copy(), bool(np.any(admissible)),
                    int(admissible.sum()))  # fmt: skip

    def _window(self, v0: float, d0: float, p) -> tuple[np.ndarray, np.ndarray]:
        """Target (speed, steering) pairs reachable within one control period, plus (last) a
        full stop on the current wheel angle; steering capped by the lateral-acceleration
        limit."""
        cfg = self.config
        tc = cfg.control_period
        v_lo = max(p.v_min, v0 - p.b_max * tc)
        v_hi = min(p.v_max, v0 + p.a_max * tc)
        speeds = np.linspace(v_lo, max(v_lo, v_hi), cfg.speed_samples)
        d_lo = max(-p.delta_max, d0 - p.v_delta_max * tc)
        d_hi = min(p.delta_max, d0 + p.v_delta_max * tc)
        steers = np.linspace(d_lo, max(d_lo, d_hi), cfg.steer_samples)
        v_t, d_t = (a.ravel() for a in np.meshgrid(speeds, steers, indexing="ij"))
        lateral = v_t**2 * np.abs(np.tan(d_t)) / p.wheelbase
        keep = lateral <= cfg.max_lateral_accel
        v_t, d_t = v_t[keep], d_t[keep]
        return np.append(v_t, v_lo), np.append(d_t, d0)

    def _clearance(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance [m] from each cell centre to the nearest blocking cell's edge, and the
        unknown mask."""
        blocking = (grid != FREE) if self.config.unknown == "occupied" else (grid == OCCUPIED)
        free = (~blocking).astype(np.uint8)
        dist = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        cell = self.setting.cell_size
        return (dist - 0.5) * cell, (grid != FREE) & (grid != OCCUPIED)

    def _sample(self, clearance, unknown, poses, offsets):
        """Clearance [m] ``(n, P, disks)`` at the footprint disks of ``poses`` ``(n, P, 3)``, and
        the share of disk samples on unknown cells or beyond the grid ``(n,)``."""
        s = self.setting
        rows, cols = clearance.shape
        c, sn = np.cos(poses[..., 2])[..., None], np.sin(poses[..., 2])[..., None]
        centres = np.stack([poses[..., 0:1] + offsets * c, poses[..., 1:2] + offsets * sn], -1)
        uv = np.rint(grid_to_pixel(centres, rows, cols, s.cell_size, s.orientation)).astype(int)
        inside = (uv[..., 0] >= 0) & (uv[..., 0] < cols) & (uv[..., 1] >= 0) & (uv[..., 1] < rows)
        u = np.clip(uv[..., 0], 0, cols - 1)
        v = np.clip(uv[..., 1], 0, rows - 1)
        gap = np.where(inside, clearance[v, u], np.inf)
        unseen = np.mean(~inside | unknown[v, u], axis=(1, 2))
        return gap, unseen

    def _cost(self, traj, destination, min_gap, unseen, v0, d0, p) -> np.ndarray:
        cfg = self.config
        end = traj[:, -1]
        dest = np.asarray(destination, float)
        horizon = float(self.setting.times[-1])
        scale = max(p.v_max * horizon, 1.0)
        goal = np.hypot(end[:, 0] - dest[0], end[:, 1] - dest[1]) / scale
        bearing = np.arctan2(dest[1] - end[:, 1], dest[0] - end[:, 0])
        near = np.hypot(*(dest - end[:, :2]).T) < 1.0
        heading = np.where(near, 0.0, np.abs((end[:, PSI] - bearing + np.pi) % (2 * np.pi) - np.pi))
        proximity = 1.0 / (1.0 + np.maximum(min_gap, 0.0))
        speed = (p.v_max - end[:, V]) / max(p.v_max, 1e-6)
        lateral = np.max(traj[:, :, V] ** 2 * np.abs(np.tan(traj[:, :, 4])), axis=1) / (
            p.wheelbase * cfg.max_lateral_accel
        )
        steer = np.abs(traj[:, -1, 4] - d0) / max(p.v_delta_max * cfg.control_period, 1e-6)
        cost = (cfg.w_goal * goal + cfg.w_heading * heading / np.pi
                + cfg.w_clearance * proximity + cfg.w_speed * speed + cfg.w_lateral * lateral
                + cfg.w_steer_change * steer)  # fmt: skip
        if cfg.unknown == "penalise":
            cost = cost + cfg.w_unknown * unseen
        return cost
