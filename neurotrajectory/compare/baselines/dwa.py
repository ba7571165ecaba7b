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
destination at the end of the horizon (a goal beyond the horizon: the share of the straight
way to it a steady drive covers by then), heading error, obstacle proximity, speed deficit,
lateral acceleration and steering change. If no rollout is admissible (``feasible`` false),
the test is relaxed step by step and the least-cost rollout of the first step that leaves
any is taken (``Plan.level``): without the braking check (:data:`NO_BRAKING_CHECK`; a
snapshot cannot tell a queue moving at the ego's speed from a stopped one), then checking
only the first ``dt`` (:data:`FIRST_STEP`), then any rollout within ``fallback_tolerance``
of the most clearance (:data:`MOST_CLEARANCE`). Before issue 10 (``fallback="clearance"``)
the first rollout of most clearance was taken outright; as samples are ordered by speed,
that was the hardest braking one among equal clearances, so the ego braked from highway
speed behind a queue moving at its own speed.

The prediction is the winning rollout at the set-point times (grid frame, rear axle).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from gridsim import libm
from gridsim.frames import EGO_SPEED, EGO_STEERING, ego_heading, grid_to_pixel
from gridsim.sensors.occupancy import FREE, OCCUPIED
from gridsim.vehicle.kinematics import PSI, V, step_bicycle
from neurotrajectory.compare.predictors import Setting
from neurotrajectory.data.windows import Windows


@dataclass(frozen=True)
class DWAConfig:
    """Sampling, safety and cost weights (dimensionless weights on normalised terms).

    The margin, horizons, weights and fallback tolerance were chosen on 2026-11-23 by
    ``experiments/tune_dwa.py`` on the train splits of the four evaluation groups only
    (``python experiments/tune_dwa.py --data /tmp/dwa-data --samples 300 --passes 6
    --seed 0``; see docs/evaluation.md, "DWA tuning"). The safety settings are bounded in
    the search (margin >= 0, both horizons >= 0.3 s); the old values are
    ``BEFORE_ISSUE_10`` there."""

    speed_samples: int = 7
    steer_samples: int = 15
    control_period: float = 0.5  # s: the dynamic window is what this much time reaches
    dt: float = 0.1  # s: rollout step
    disks: int = 5  # footprint disks along the body
    margin: float = 0.0476  # m of extra clearance around the footprint disks
    #: s of each rollout checked for collisions: a grid is a snapshot, and over the whole
    #: horizon a rollout that follows a moving car would run into where that car is now.
    collision_horizon: float = 0.3
    headway: float = 0.3  # s: the braking check looks at most speed * headway ahead
    unknown: str = "occupied"  # or "penalise"
    max_lateral_accel: float = 4.0  # m/s^2
    w_goal: float = 1.0
    w_heading: float = 0.00143
    w_clearance: float = 0.00932
    w_speed: float = 0.00356
    w_lateral: float = 0.00142
    w_steer_change: float = 0.00474
    w_unknown: float = 0.3
    #: cost per share of the rollout after ``collision_horizon`` that would hit an obstacle
    #: were it static (moving traffic may have left by then, so it only costs)
    w_late_collision: float = 0.0132
    #: when no rollout is admissible: "relax" the test step by step (module docstring);
    #: "clearance" (before issue 10) takes the first rollout of most clearance
    fallback: str = "relax"
    #: m: the last relaxation keeps the rollouts this close to the most clearance
    fallback_tolerance: float = 0.778

    def __post_init__(self) -> None:
        if self.unknown not in ("occupied", "penalise"):
            raise ValueError(f"unknown must be 'occupied' or 'penalise', got {self.unknown!r}")
        if self.fallback not in ("relax", "clearance"):
            raise ValueError(f"fallback must be 'relax' or 'clearance', got {self.fallback!r}")
        if self.speed_samples < 1 or self.steer_samples < 1 or self.disks < 1:
            raise ValueError("speed_samples, steer_samples and disks must be >= 1")
        if not 0 < self.dt <= self.control_period:
            raise ValueError(f"need 0 < dt <= control_period, got {self.dt}, {self.control_period}")


#: Plan.level: how the rollout was chosen (see the module docstring)
ADMISSIBLE, NO_BRAKING_CHECK, FIRST_STEP, MOST_CLEARANCE = range(4)


@dataclass(frozen=True)
class Plan:
    """Chosen rollouts of ``N`` windows: ``states`` ``(N, K + 1, 5)`` every ``dt`` from the
    start (grid frame: x, y [m], heading [rad], speed [m/s], steering [rad]), set-points
    ``(N, tau_o, 2)`` [m], whether any rollout was admissible ``(N,)``, how many ``(N,)``
    and the fallback ``level`` ``(N,)`` the rollout was chosen at (:data:`ADMISSIBLE` when
    one was admissible). Indexing with ``[i]`` gives one window's plan."""

    states: np.ndarray
    setpoints: np.ndarray
    feasible: np.ndarray
    admissible: np.ndarray
    level: np.ndarray

    def __getitem__(self, i: int) -> Plan:
        return Plan(self.states[i], self.setpoints[i], bool(self.feasible[i]),
                    int(self.admissible[i]), int(self.level[i]))  # fmt: skip


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

    #: windows planned together (memory: ~100 KB per window)
    CHUNK = 64

    def predict(self, batch: Windows) -> np.ndarray:
        parts = []
        for start in range(0, len(batch), self.CHUNK):
            index = np.arange(start, min(start + self.CHUNK, len(batch)))
            parts.append(self.plan_many(batch.take(index)).setpoints)
        return np.concatenate(parts)

    def plan(self, batch: Windows, i: int) -> Plan:
        """The plan of window ``i`` alone."""
        return self.plan_many(batch.take(np.array([i])))[0]

    def plan_many(self, batch: Windows) -> Plan:
        """Plan every window of ``batch`` at once (all samples of all windows in one
        rollout)."""
        cfg, s = self.config, self.setting
        n = len(batch)
        wheelbase, length, width = (batch.vehicle[:, k].astype(np.float64) for k in range(3))
        ego = batch.ego.astype(np.float64)
        v0, d0 = ego[:, EGO_SPEED], ego[:, EGO_STEERING]
        v_t, d_t, valid = self._window(v0, d0, wheelbase)  # (n, S)
        samples = v_t.shape[1]
        rows = lambda a: np.repeat(a, samples)  # noqa: E731  per-window values per sample
        params = replace(s.params, wheelbase=rows(wheelbase), length=rows(length),
                         width=rows(width), center_offset=rows(0.5 * wheelbase))  # fmt: skip
        state = np.zeros((n * samples, 5))
        state[:, PSI] = rows(ego_heading(ego))
        state[:, V], state[:, 4] = rows(v0), rows(d0)
        accel = (v_t - v0[:, None]).ravel() / cfg.control_period
        rate = (d_t - d0[:, None]).ravel() / cfg.control_period
        hold = np.zeros((n, samples))
        hold[:, -1] = -s.params.b_max  # the last sample brakes to a full stop
        hold = hold.ravel()
        accel = np.where(hold < 0, hold, accel)
        k_ctrl = int(round(cfg.control_period / cfg.dt))
        states = [state]
        for k in range(int(self._setpoint_steps[-1])):
            on = k < k_ctrl
            state = step_bicycle(state, accel if on else hold, rate if on else 0.0, params,
                                 cfg.dt).state  # fmt: skip
            states.append(state)
        traj = np.stack(states, axis=1).reshape(n, samples, -1, 5)  # (n, S, K + 1, 5)
        grids = batch.grids[:, -1]
        clearance, unknown = self._clearance(grids)
        disks = [footprint_disks(a, b, c, cfg.disks) for a, b, c in zip(length, width, wheelbase,
                                                                         strict=True)]  # fmt: skip
        offsets = np.array([d[0] for d in disks])  # (n, D)
        radius = np.array([d[1] for d in disks])[:, None]  # (n, 1)
        k_check = max(1, min(int(round(cfg.collision_horizon / cfg.dt)), traj.shape[2] - 1))
        last = traj[:, :, k_check]
        stop = np.minimum(last[..., V] ** 2 / (2.0 * s.params.b_max), last[..., V] * cfg.headway)
        ahead = stop[..., None] * np.array([1 / 3, 2 / 3, 1.0])
        heading = np.repeat(last[..., None, PSI], 3, axis=-1)
        bx = last[..., None, 0] + ahead * np.cos(heading)
        by = last[..., None, 1] + ahead * np.sin(heading)
        brake = np.stack([bx, by, heading], axis=-1)
        poses = np.concatenate([traj[:, :, 1 : k_check + 1, :3], brake], axis=2)
        gap, unseen = self._sample(clearance, unknown, poses, offsets)
        pose_gap = gap.min(axis=3) - radius[..., None]  # (n, S, k_check + 3)
        min_gap = pose_gap.min(axis=2)
        # An ego that starts closer than the margin (the disks overestimate the box) may go
        # on as long as it gets no closer.
        start_gap = self._sample(clearance, unknown, traj[:, :1, :1, :3], offsets)[0]
        start_gap = start_gap.min(axis=(1, 2, 3))[:, None] - radius
        clear = pose_gap >= np.minimum(cfg.margin, start_gap)[..., None]
        # the admissibility test, then its relaxations: without the braking check, then
        # only the first rollout step
        tests = [clear.all(axis=2), clear[..., :k_check].all(axis=2), clear[..., 0]]
        cost = self._cost(traj, self._goal(batch), min_gap, unseen, d0, wheelbase)
        if cfg.w_late_collision and k_check + 1 < traj.shape[2]:
            late_gap, _ = self._sample(clearance, unknown, traj[:, :, k_check + 1 :, :3], offsets)
            late_hits = np.mean(late_gap.min(axis=3) - radius[..., None] < 0.0, axis=2)
            cost = cost + cfg.w_late_collision * late_hits
        best, level = self._choose([valid & t for t in tests], valid, cost, min_gap)
        chosen = traj[np.arange(n), best]
        return Plan(chosen, chosen[:, self._setpoint_steps, :2].copy(), level == 0,
                    (valid & tests[0]).sum(axis=1), level)  # fmt: skip

    def _choose(self, tests, valid, cost, min_gap) -> tuple[np.ndarray, np.ndarray]:
        """The chosen rollout ``(n,)`` and the level it was chosen at ``(n,)``, given which
        rollouts ``(n, S)`` pass the admissibility test and each of its relaxations
        (``tests``, in :class:`Plan` level order), their cost and least clearance [m]."""
        cfg = self.config
        first_of_most_clearance = np.argmax(np.where(valid, min_gap, -np.inf), axis=1)
        if cfg.fallback == "clearance":
            level = np.where(tests[ADMISSIBLE].any(axis=1), ADMISSIBLE, MOST_CLEARANCE)
            least_cost = np.argmin(np.where(tests[ADMISSIBLE], cost, np.inf), axis=1)
            return np.where(level == ADMISSIBLE, least_cost, first_of_most_clearance), level
        most = min_gap[np.arange(len(cost)), first_of_most_clearance][:, None]
        tiers = np.stack([*tests, valid & (min_gap >= most - cfg.fallback_tolerance)])
        level = np.argmax(tiers.any(axis=2), axis=0)  # the first tier that leaves any
        candidates = tiers[level, np.arange(len(cost))]
        return np.argmin(np.where(candidates, cost, np.inf), axis=1), level

    def _window(self, v0: np.ndarray, d0: np.ndarray, wheelbase: np.ndarray):
        """Target speeds and steering angles ``(n, S)`` reachable within one control period,
        plus (last) a full stop on the current wheel angle, and which of them keep to the
        lateral-acceleration limit ``(n, S)``."""
        cfg, p = self.config, self.setting.params
        tc = cfg.control_period
        v_lo = np.maximum(p.v_min, v0 - p.b_max * tc)
        v_hi = np.maximum(v_lo, np.minimum(p.v_max, v0 + p.a_max * tc))
        d_lo = np.maximum(-p.delta_max, d0 - p.v_delta_max * tc)
        d_hi = np.maximum(d_lo, np.minimum(p.delta_max, d0 + p.v_delta_max * tc))
        fv = np.linspace(0.0, 1.0, cfg.speed_samples)[None, :, None]
        fd = np.linspace(0.0, 1.0, cfg.steer_samples)[None, None, :]
        speeds = v_lo[:, None, None] + fv * (v_hi - v_lo)[:, None, None]
        steers = d_lo[:, None, None] + fd * (d_hi - d_lo)[:, None, None]
        speeds, steers = np.broadcast_arrays(speeds, steers)
        n = len(v0)
        v_t = np.concatenate([speeds.reshape(n, -1), v_lo[:, None]], axis=1)
        d_t = np.concatenate([steers.reshape(n, -1), d0[:, None]], axis=1)
        lateral = v_t**2 * np.abs(libm.tan(d_t)) / wheelbase[:, None]
        valid = lateral <= cfg.max_lateral_accel
        valid[:, -1] = True
        return v_t, d_t, valid

    def _clearance(self, grids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance [m] from each cell centre to the nearest blocking cell's edge, and the
        unknown mask, for grids ``(n, H, W)``."""
        blocking = (grids != FREE) if self.config.unknown == "occupied" else (grids == OCCUPIED)
        free = (~blocking).astype(np.uint8)
        dist = np.stack([cv2.distanceTransform(f, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
                         for f in free])  # fmt: skip
        return (dist - 0.5) * self.setting.cell_size, (grids != FREE) & (grids != OCCUPIED)

    def _sample(self, clearance, unknown, poses, offsets):
        """Clearance [m] ``(n, S, P, D)`` at the ``D`` footprint disks of ``poses``
        ``(n, S, P, 3)`` (``offsets`` ``(n, D)``), and the share of disk samples on unknown
        cells or beyond the grid ``(n, S)``."""
        s = self.setting
        _, rows, cols = clearance.shape
        off = offsets[:, None, None, :]
        c, sn = np.cos(poses[..., 2])[..., None], np.sin(poses[..., 2])[..., None]
        centres = np.stack([poses[..., 0:1] + off * c, poses[..., 1:2] + off * sn], -1)
        uv = np.rint(grid_to_pixel(centres, rows, cols, s.cell_size, s.orientation)).astype(int)
        inside = (uv[..., 0] >= 0) & (uv[..., 0] < cols) & (uv[..., 1] >= 0) & (uv[..., 1] < rows)
        u = np.clip(uv[..., 0], 0, cols - 1)
        v = np.clip(uv[..., 1], 0, rows - 1)
        w = np.arange(len(clearance))[:, None, None, None]
        gap = np.where(inside, clearance[w, v, u], np.inf)
        unseen = np.mean(~inside | unknown[w, v, u], axis=(2, 3))
        return gap, unseen

    def _goal(self, batch) -> np.ndarray:
        """Where the rollouts should end ``(n, 2)`` [m, grid frame]: the destination; for a goal
        beyond the horizon, the point on the straight line to it that a steady drive passes at
        the horizon's end (the share horizon / goal time of the way)."""
        goal = batch.destination.astype(np.float64)
        s = self.setting
        return goal * (float(s.times[-1]) / s.goal_time) if s.far_goal else goal

    def _cost(self, traj, destination, min_gap, unseen, d0, wheelbase) -> np.ndarray:
        """Weighted cost ``(n, S)`` of rollouts ``traj`` ``(n, S, K + 1, 5)``."""
        cfg, p = self.config, self.setting.params
        end = traj[:, :, -1]
        dx = destination[:, None, 0] - end[..., 0]
        dy = destination[:, None, 1] - end[..., 1]
        horizon = float(self.setting.times[-1])
        goal = np.hypot(dx, dy) / max(p.v_max * horizon, 1.0)
        error = np.abs((end[..., PSI] - libm.arctan2(dy, dx) + np.pi) % (2 * np.pi) - np.pi)
        heading = np.where(np.hypot(dx, dy) < 1.0, 0.0, error)
        proximity = 1.0 / (1.0 + np.maximum(min_gap, 0.0))
        speed = (p.v_max - end[..., V]) / max(p.v_max, 1e-6)
        lateral = np.max(traj[..., V] ** 2 * np.abs(libm.tan(traj[..., 4])), axis=2) / (
            wheelbase[:, None] * cfg.max_lateral_accel
        )
        steer = np.abs(end[..., 4] - d0[:, None]) / max(p.v_delta_max * cfg.control_period, 1e-6)
        cost = (cfg.w_goal * goal + cfg.w_heading * heading / np.pi
                + cfg.w_clearance * proximity + cfg.w_speed * speed + cfg.w_lateral * lateral
                + cfg.w_steer_change * steer)  # fmt: skip
        if cfg.unknown == "penalise":
            cost = cost + cfg.w_unknown * unseen
        return cost
