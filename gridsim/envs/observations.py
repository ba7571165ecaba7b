"""Observation types of GridSim-v0, pluggable by name (:data:`OBSERVATION_TYPES`).

Each type defines its space from the scenario (built once per environment) and reads the
observation off the environment after every reset and step, from its building blocks
(:meth:`~gridsim.envs.gridsim_env.GridSimEnv.grid_history`,
:meth:`~gridsim.envs.gridsim_env.GridSimEnv.newest_grid`,
:meth:`~gridsim.envs.gridsim_env.GridSimEnv.ego_features`,
:meth:`~gridsim.envs.gridsim_env.GridSimEnv.destination` and the world). Positions are in
the ego's grid frame (rear axle at the origin, axes as ``sensor.orientation`` says), in
metres. A new type is a subclass registered in :data:`OBSERVATION_TYPES`; then
``gym.make("GridSim-v0", observation_type=NAME)``.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from gymnasium import spaces

from gridsim.frames import EGO_FEATURES, grid_rotation
from gridsim.scenario.schema import ScenarioConfig
from gridsim.vehicle.kinematics import PSI, V

if TYPE_CHECKING:
    from gridsim.envs.gridsim_env import GridSimEnv

#: Bound of the unbounded float observations (metres, metres per second).
BIG = np.float32(1e4)


def _vector(size: int) -> spaces.Box:
    return spaces.Box(-BIG, BIG, (size,), np.float32)


class ObservationType(ABC):
    """What the agent observes of the environment after each reset and step. A type whose
    observations need no occupancy grid says so (``needs_grids = False``): the environment
    then renders none (unless it renders frames), which saves most of a step's time."""

    needs_grids: ClassVar[bool] = True

    def __init__(self, cfg: ScenarioConfig) -> None:
        self.cfg = cfg
        self.space = self._make_space()

    @abstractmethod
    def _make_space(self) -> spaces.Space:
        """The observation space (built once)."""

    @abstractmethod
    def observe(self, env: GridSimEnv) -> Any:
        """The observation of ``env`` now (an element of :attr:`space`)."""


class GridsObservation(ObservationType):
    """The paper's input: ``{"grids": (history, rows, cols) uint8, oldest first (0 free,
    128 unknown, 255 occupied), "ego": (6,) float32 (:data:`~gridsim.frames.EGO_FEATURES`),
    "destination": (2,) float32 [m, grid frame]}``."""

    key = "grids"  #: the grids' key

    def _grid_shape(self) -> tuple[int, ...]:
        e, s = self.cfg.env, self.cfg.sensor
        return (e.history, s.rows, s.cols)

    def _grids(self, env: GridSimEnv) -> np.ndarray:
        return env.grid_history()

    def _make_space(self) -> spaces.Dict:
        return spaces.Dict({
            self.key: spaces.Box(0, 255, self._grid_shape(), np.uint8),
            "ego": _vector(len(EGO_FEATURES)),
            "destination": _vector(2),
        })  # fmt: skip

    def observe(self, env: GridSimEnv) -> dict[str, np.ndarray]:
        return {self.key: self._grids(env), "ego": env.ego_features(),
                "destination": env.destination()}  # fmt: skip


class NewestGridObservation(GridsObservation):
    """:class:`GridsObservation` with the newest grid only, ``"grid"``: ``(rows, cols)`` uint8,
    for an agent that keeps its own history (a recurrent policy; NeuroTrajectory's rollouts,
    which keep each frame's CNN features). After a reset the history it stands for is that
    grid ``history`` times; each step adds one."""

    key = "grid"

    def _grid_shape(self) -> tuple[int, ...]:
        return (self.cfg.sensor.rows, self.cfg.sensor.cols)

    def _grids(self, env: GridSimEnv) -> np.ndarray:
        return env.newest_grid()


class KinematicsObservation(ObservationType):
    """No grids, for policies that read numbers (highway-env's ``Kinematics``): ``{"ego",
    "destination"}`` as :class:`GridsObservation`'s, and ``"vehicles"``: ``(VEHICLES, 7)``
    float32, the nearest traffic participants within the sensor's ``max_range``, nearest
    first: ``presence`` (1; rows without a vehicle are all 0), ``x, y`` [m] of its footprint
    centre and ``vx, vy`` [m/s] of its velocity relative to the ego's, both in the grid frame,
    ``cos_h, sin_h`` of its heading in the grid frame. It sees through occlusions: the grid is
    what a sensor sees, this is what the world holds."""

    VEHICLES = 8
    FEATURES = ("presence", "x", "y", "vx", "vy", "cos_h", "sin_h")
    needs_grids = False

    def _make_space(self) -> spaces.Dict:
        vehicles = spaces.Box(-BIG, BIG, (self.VEHICLES, len(self.FEATURES)), np.float32)
        return spaces.Dict({"ego": _vector(len(EGO_FEATURES)), "destination": _vector(2),
                            "vehicles": vehicles})  # fmt: skip

    def observe(self, env: GridSimEnv) -> dict[str, np.ndarray]:
        return {"ego": env.ego_features(), "destination": env.destination(),
                "vehicles": self.vehicles(env)}  # fmt: skip

    def vehicles(self, env: GridSimEnv) -> np.ndarray:
        """The ``vehicles`` rows of ``env`` now."""
        w = env.world
        fleet = w.traffic.fleet
        idx = np.flatnonzero(fleet.active)
        rotation = grid_rotation(self.cfg.sensor.orientation, w.ego[PSI])
        xy = env.to_grid(np.column_stack([fleet.x[idx], fleet.y[idx]]))
        dist = np.hypot(xy[:, 0], xy[:, 1])
        near = np.flatnonzero(dist <= self.cfg.sensor.max_range)
        near = near[np.argsort(dist[near], kind="stable")][: self.VEHICLES]
        heading = fleet.psi[idx[near]] - rotation
        speed = fleet.v[idx[near]]
        ego_heading = w.ego[PSI] - rotation
        ego_v = (w.ego[V] * math.cos(ego_heading), w.ego[V] * math.sin(ego_heading))
        out = np.zeros((self.VEHICLES, len(self.FEATURES)), np.float32)
        n = len(near)
        out[:n, 0] = 1.0
        out[:n, 1:3] = xy[near]
        out[:n, 3] = speed * np.cos(heading) - ego_v[0]
        out[:n, 4] = speed * np.sin(heading) - ego_v[1]
        out[:n, 5] = np.cos(heading)
        out[:n, 6] = np.sin(heading)
        return out


#: The observation types by name (``observation_type=`` of GridSim-v0).
OBSERVATION_TYPES: dict[str, type[ObservationType]] = {
    "grids": GridsObservation,
    "grid": NewestGridObservation,
    "kinematics": KinematicsObservation,
}
