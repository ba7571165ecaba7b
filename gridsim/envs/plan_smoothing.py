"""Plan smoothing: follow a blend of each new trajectory plan and the one before it.

A planner that re-plans every decision period from changing inputs (a learned planner reading
occupancy grids) commands set-points that jitter from one plan to the next, and pure pursuit
turns every jitter into steering. :class:`PlanSmoother` is a first-order low-pass filter on
the plan: each new plan is blended, in the world frame, with the previous (blended) plan
re-timed to the new set-point times,

    followed(t + t_i) = keep * previous(t + t_i) + (1 - keep) * new(t + t_i),

where ``previous`` is interpolated linearly in time through the ego's position when it was
planned and its set-points, and extrapolated along its last segment past its horizon.
``keep = 0`` follows every plan as given. The smoother holds state across steps (the previous
plan), so a smoothed policy is not a function of the observation alone; it starts afresh on
every new episode.
"""

from __future__ import annotations

import math

import numpy as np


def check_keep(keep: float, name: str = "plan smoothing") -> float:
    """``keep`` as a float, or ValueError naming ``name`` unless it is a number in [0, 1)."""
    if isinstance(keep, bool) or not isinstance(keep, int | float | np.number):
        raise ValueError(f"{name} (the share of the previous plan kept) must be a number in "
                         f"[0, 1), got {keep!r}")  # fmt: skip
    if not (math.isfinite(keep) and 0 <= keep < 1):
        raise ValueError(f"{name} (the share of the previous plan kept) must be in [0, 1), "
                         f"got {keep}")  # fmt: skip
    return float(keep)


def retime(times: np.ndarray, points: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Positions ``(len(at), 2)`` [m] at times ``at`` [s] on the path through ``points``
    ``(N, 2)`` at increasing ``times`` ``(N,)``: linear in time between them, extrapolated
    along the last segment after the last time (held before the first)."""
    out = np.stack([np.interp(at, times, points[:, 0]), np.interp(at, times, points[:, 1])], 1)
    beyond = at > times[-1]
    if beyond.any():
        velocity = (points[-1] - points[-2]) / (times[-1] - times[-2])
        out[beyond] = points[-1] + (at[beyond] - times[-1])[:, None] * velocity
    return out


class PlanSmoother:
    """Blends the trajectory actions of one GridSim-v0 environment (see the module docstring).

    Call it with the environment (or a wrapper of it) and a planner's action, set-points
    ``(tau_o, 2)`` [m, grid frame], before stepping with its result (the same shape, float32).
    It recognises a new episode by the environment's new world."""

    def __init__(self, keep: float) -> None:
        self.keep = check_keep(keep)
        self._world = None
        self._times: np.ndarray | None = None  # [s], episode time: the plan's start, set-points
        self._points: np.ndarray | None = None  # (1 + tau_o, 2) [m, world]: the ego, set-points

    def __call__(self, env, action) -> np.ndarray:
        e = env.unwrapped
        box = e.action_space
        a = np.asarray(action, dtype=np.float64)
        if a.shape != box.shape:
            raise ValueError(f"trajectory action must have shape {box.shape}, got {a.shape}")
        world = e.world
        plan = e.to_world(np.clip(a, box.low, box.high))
        times = world.time + e.cfg.env.setpoint_times
        if self._world is world and self.keep > 0:
            plan = self.keep * retime(self._times, self._points, times) + (1 - self.keep) * plan
        self._world = world
        self._times = np.concatenate(([world.time], times))
        self._points = np.vstack((world.ego[:2], plan))
        return e.to_grid(plan).astype(np.float32)
