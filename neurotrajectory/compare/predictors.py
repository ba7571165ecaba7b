"""What every trajectory predictor shares: the setting it predicts in, the batch it reads,
and the adapter that lets it drive GridSim-v0.

A predictor maps a batch of :class:`~neurotrajectory.data.windows.Windows` (only the observation
fields are read) to set-points ``(N, tau_o, 2)`` [m] in the grid frame at the set-point times
of its :class:`Setting`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from gridsim.envs.plan_smoothing import PlanSmoother, check_keep
from gridsim.frames import setpoint_times
from gridsim.scenario.parts import vehicle_params
from gridsim.scenario.schema import VehicleConfig
from gridsim.vehicle.kinematics import BicycleParams
from neurotrajectory.data.windows import Windows


@dataclass(frozen=True)
class Setting:
    """Set-point ``times`` ``(tau_o,)`` [s], the grid's cell size [m] and orientation, the
    ego's limits (``params``: geometry is taken per window from ``Windows.vehicle``) and
    ``goal_time`` [s]: how far ahead the destination lies (None: at the last set-point)."""

    times: np.ndarray
    cell_size: float
    orientation: str
    params: BicycleParams
    goal_time: float | None = None

    @classmethod
    def from_manifest(cls, manifest: dict) -> Setting:
        times = setpoint_times(manifest["setpoint_period"], manifest["horizon"])
        s = manifest["sensor"]
        params = vehicle_params(VehicleConfig(**manifest["vehicle"]))
        return cls(times, float(s["cell_size"]), s["orientation"], params,
                   manifest.get("goal_seconds"))  # fmt: skip

    @classmethod
    def from_env(cls, env) -> Setting:
        cfg = env.unwrapped.cfg
        times = cfg.env.setpoint_times
        params = env.unwrapped.action_kind.params
        return cls(times, cfg.sensor.cell_size, cfg.sensor.orientation, params,
                   cfg.env.goal_seconds)  # fmt: skip

    @property
    def far_goal(self) -> bool:
        """The destination lies beyond the last set-point."""
        return self.goal_time is not None and self.goal_time > float(self.times[-1]) + 1e-9


class Predictor(Protocol):
    name: str

    def predict(self, batch: Windows) -> np.ndarray:
        """Set-points ``(N, tau_o, 2)`` [m, grid frame]."""


def observation_batch(obs: dict, env) -> Windows:
    """A one-window batch from a GridSim-v0 observation (labels zero)."""
    p = env.unwrapped.world.ego_params
    horizon = env.unwrapped.cfg.env.horizon
    zero = np.zeros(1, np.int64)
    return Windows(
        grids=obs["grids"][None],
        ego=obs["ego"][None].astype(np.float32),
        destination=obs["destination"][None].astype(np.float32),
        target=np.zeros((1, horizon, 2), np.float32),
        steer=zero,
        longitudinal=zero,
        accel=np.zeros(1, np.float32),
        vehicle=np.array([[p.wheelbase, p.length, p.width]], np.float32),
        track=np.array(["closed-loop"]),
        time=np.array([env.unwrapped.world.time], np.float32),
    )


class TrajectoryPolicy:
    """A predictor driving GridSim-v0 through the trajectory action, its plans smoothed by
    ``smoothing`` (the share of the previous plan kept, see :class:`PlanSmoother`; 0: none).
    One policy drives one environment at a time."""

    action_type = "trajectory"

    def __init__(self, predictor: Predictor, smoothing: float = 0.0) -> None:
        self.predictor = predictor
        self.smoother = PlanSmoother(smoothing) if check_keep(smoothing) > 0 else None

    def __call__(self, env, obs, info) -> np.ndarray:
        plan = self.predictor.predict(observation_batch(obs, env))[0].astype(np.float32)
        return plan if self.smoother is None else self.smoother(env, plan)
