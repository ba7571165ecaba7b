"""Action types of GridSim-v0, pluggable by name (:data:`ACTION_TYPES`).

Each type defines its space, turns an action into a per-tick controller for the decision
period, and gives the *commanded trajectory*: the positions [m, world] at the ``horizon``
set-point times that the action asks for (used by the fitness term l1).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np
from gymnasium import spaces

from gridsim.envs import actions_kernels as kernels
from gridsim.road.polyline import Polyline
from gridsim.vehicle.control import PursuitGains, follow_path
from gridsim.vehicle.kinematics import PSI, BicycleParams, V, step_bicycle
from gridsim.world import world_kernels

Controller = Callable[[object], tuple[float, float]]  # world -> (accel, steer rate)
#: Tight pursuit for following set-points (cuts corners less than lane keeping needs to).
TRACKING_GAINS = PursuitGains(min_lookahead=2.5, lookahead_time=0.4)


def _real(action, kind: str) -> np.ndarray:
    """``action`` as float64; a ``ValueError`` naming the action unless it holds finite real
    numbers (integers or floats: not booleans, complex numbers, strings or ragged lists)."""
    try:
        raw = np.asarray(action)
    except (ValueError, TypeError) as exc:  # ragged nested sequences
        raise ValueError(f"{kind} action must be an array of numbers, got {action!r} "
                         f"({exc})") from None  # fmt: skip
    if raw.dtype.kind not in "iuf":
        raise ValueError(f"{kind} action must hold real numbers (integers or floats), got dtype "
                         f"{raw.dtype}: {raw.tolist()!r}")  # fmt: skip
    a = raw.astype(np.float64)
    if not np.isfinite(a).all():
        raise ValueError(f"{kind} action contains NaN or infinite values: {raw.tolist()}")
    return a


def rollout_controls(
    state: np.ndarray,
    accel: float,
    steer_rate: float,
    params: BicycleParams,
    period: float,
    horizon: int,
) -> np.ndarray:
    """Positions ``(horizon, 2)`` of the ego holding ``(accel, steer_rate)`` for ``horizon``
    set-point periods."""
    out = np.empty((horizon, 2))
    s = state
    for i in range(horizon):
        s = step_bicycle(s, accel, steer_rate, params, period).state
        out[i] = s[:2]
    return out


class ActionType(ABC):
    """How an action drives the ego for one decision period."""

    def __init__(
        self,
        params: BicycleParams,
        horizon: int,
        setpoint_period: float,
        orientation: str,
        decision_period: float = 0.1,
    ) -> None:
        """``params``: the ego's vehicle; ``horizon`` set-points ``setpoint_period`` [s]
        apart; ``orientation``: the grid frame's (:mod:`gridsim.frames`); an action drives
        for ``decision_period`` [s]."""
        self.params = params
        self.horizon = horizon
        self.period = setpoint_period
        self.orientation = orientation
        self.decision_period = decision_period
        self.space = self._make_space()

    @abstractmethod
    def _make_space(self) -> spaces.Space:
        """The action space (built once)."""

    @abstractmethod
    def controller(self, world, action, rotation: float) -> tuple[Controller, np.ndarray]:
        """A per-tick controller and the commanded positions ``(horizon, 2)`` [m, world]."""


class TrajectoryAction(ActionType):
    """``(horizon, 2)`` set-points [m] in the grid frame at ``t + i * setpoint_period``;
    values beyond the space bounds are clipped. A pure-pursuit controller follows the
    polyline through them, at the speed that reaches the first set-point on time. A first
    set-point that is not ahead of the rear axle (the car cannot reverse) means: stop."""

    def _make_space(self) -> spaces.Box:
        reach = self.params.v_max * self.horizon * self.period + 5.0
        return spaces.Box(-reach, reach, (self.horizon, 2), np.float32)

    def controller(self, world, action, rotation):
        a = _real(action, "trajectory")
        if a.shape != (self.horizon, 2):
            raise ValueError(
                f"trajectory action must have shape ({self.horizon}, 2), got {a.shape}"
            )
        box = self.space
        ex, ey = float(world.ego[0]), float(world.ego[1])
        c, s = math.cos(rotation), math.sin(rotation)
        pts, first, path_arrays = kernels.setpoint_path(a, box.low, box.high, ex, ey, c, s)
        speed = float(first) / self.period
        psi = world.ego[PSI]  # (math's cos and sin are libm's, as NumPy's on a float64 scalar)
        heading = np.array([math.cos(psi), math.sin(psi)])
        ahead = float(np.dot(pts[0] - world.ego[:2], heading)) > 0.0
        # (a path of 2 or more points has 2 or more distinct ones: they are 1 mm apart)
        arrays = path_arrays if len(path_arrays[0]) >= 2 and ahead else None
        return PathControl(arrays, speed, self.params, TRACKING_GAINS, self._pursuit()), pts

    def _pursuit(self) -> tuple:
        """The constant part of :meth:`PathControl.kernel_data` (made once)."""
        if self._pursuit_data is None:
            p, g = self.params, TRACKING_GAINS
            limits = (p.wheelbase, p.delta_max, p.b_max, p.a_max, p.v_delta_max, g.steer_time,
                      g.speed_gain)  # fmt: skip
            self._pursuit_data = (float(g.min_lookahead), float(g.lookahead_time),
                                  tuple(float(v) for v in limits), float(p.b_max))  # fmt: skip
        return self._pursuit_data

    _pursuit_data = None


#: The path arrays :meth:`PathControl.kernel_data` hands over when there is no path.
_NO_PATH = tuple(np.zeros(shape) for shape in [(0, 2), (0, 2), (0,), (0,), (0,)])


class PathControl:
    """The trajectory action's controller: pure pursuit along the path of ``arrays`` (those
    of :func:`~gridsim.road.polyline_kernels.segments`) at ``speed`` [m/s]
    (:func:`~gridsim.vehicle.control.follow_path`), or a stop when ``arrays`` is None. Called
    with a world, it gives the inputs ``(accel, steer rate)``; :meth:`tick` ticks the world
    with them (compiled where it can: :meth:`~gridsim.world.world.World.tick_following`).
    ``pursuit``: ``(min_lookahead, lookahead_time, pursuit_one limits, b_max)`` of ``params``
    and ``gains``."""

    __slots__ = ("_arrays", "_path", "speed", "params", "gains", "_pursuit")

    def __init__(self, arrays: tuple | None, speed: float, params: BicycleParams,
                 gains: PursuitGains, pursuit: tuple) -> None:  # fmt: skip
        self._arrays, self._path = arrays, None
        self.speed, self.params, self.gains, self._pursuit = speed, params, gains, pursuit

    @property
    def path(self) -> Polyline | None:
        """The path followed (None: stop), made on first use (the compiled tick reads the
        arrays)."""
        if self._path is None and self._arrays is not None:
            self._path = Polyline.from_segments(tuple(a.copy() for a in self._arrays))
        return self._path

    def __call__(self, w) -> tuple[float, float]:
        path = self.path
        if path is None:  # nothing ahead to drive to: brake to a stop, hold the wheel
            return -min(self.params.b_max, w.ego[V] / w.dt), 0.0
        return follow_path(w.ego, path, self.speed, self.params, self.gains)

    def tick(self, w):
        """``w.tick(*self(w))`` (the same bits)."""
        return w.tick_following(self)

    def kernel_data(self) -> world_kernels.Follow:
        """What :func:`~gridsim.world.world_kernels.follow_tick` takes as ``follow``."""
        a = self._arrays
        if a is None:
            return world_kernels.Follow(world_kernels.STOP, _NO_PATH, float(self.speed),
                                        *self._pursuit, _NO_HOLD)  # fmt: skip
        # segments' order is (points, segments, lengths, headings, arc lengths)
        arrays = (a[0], a[1], a[2], a[4], a[3])
        return world_kernels.Follow(world_kernels.PURSUIT, arrays, float(self.speed),
                                    *self._pursuit, _NO_HOLD)  # fmt: skip


_NO_HOLD = (0.0, 0.0)
_NO_PURSUIT = (0.0, 0.0, (0.0,) * 7, 0.0)


class HeldInputs:
    """The controller of the control and discrete actions: the inputs ``(accel, steer rate)``
    held for the decision period. Called with a world, it gives them; :meth:`tick` ticks the
    world with them (compiled where it can: :meth:`~gridsim.world.world.World.tick_following`)."""

    __slots__ = ("accel", "rate")

    def __init__(self, accel: float, rate: float) -> None:
        self.accel, self.rate = accel, rate

    def __call__(self, w) -> tuple[float, float]:
        return self.accel, self.rate

    def tick(self, w):
        """``w.tick(*self(w))`` (the same bits)."""
        return w.tick_following(self)

    def kernel_data(self) -> world_kernels.Follow:
        """What :func:`~gridsim.world.world_kernels.follow_tick` takes as ``follow``."""
        held = (float(self.accel), float(self.rate))
        return world_kernels.Follow(world_kernels.HOLD, _NO_PATH, 0.0, *_NO_PURSUIT, held)


class ControlAction(ActionType):
    """``[acceleration m/s^2, steering rate rad/s]``, held for the decision period; values
    beyond the vehicle limits are clipped by the vehicle model."""

    def _make_space(self) -> spaces.Box:
        p = self.params
        return spaces.Box(
            np.array([-p.b_max, -p.v_delta_max], np.float32),
            np.array([p.a_max, p.v_delta_max], np.float32),
            dtype=np.float32,
        )

    def controller(self, world, action, rotation):
        a = _real(action, "control")
        if a.shape != (2,):
            raise ValueError(f"control action must have shape (2,), got {a.shape}")
        accel, rate = float(a[0]), float(a[1])
        plan = rollout_controls(world.ego, accel, rate, self.params, self.period, self.horizon)
        return HeldInputs(accel, rate), plan


class DiscreteAction(ActionType):
    """The original GridSim's discrete commands: 0 keep, 1 accelerate (``a_max``),
    2 decelerate (``-b_max / 2``), 3 steer left, 4 steer right (the steering angle moves
    :data:`STEER_STEP_DEG` degrees over the decision period, within the rate limit)."""

    STEER_STEP_DEG = 3.0
    NAMES = ("keep", "accelerate", "decelerate", "left", "right")

    def _make_space(self) -> spaces.Discrete:
        return spaces.Discrete(len(self.NAMES))

    def controller(self, world, action, rotation):
        a = _real(action, "discrete")
        k = int(a.item()) if a.size == 1 else -1
        if not 0 <= k < len(self.NAMES) or k != a.item():
            raise ValueError(f"discrete action must be an integer in [0, 4], got {action!r}")
        p = self.params
        rate = np.deg2rad(self.STEER_STEP_DEG) / self.decision_period
        accel = {1: p.a_max, 2: -0.5 * p.b_max}.get(k, 0.0)
        steer = {3: rate, 4: -rate}.get(k, 0.0)
        plan = rollout_controls(world.ego, accel, steer, p, self.period, self.horizon)
        return HeldInputs(accel, steer), plan


ACTION_TYPES: dict[str, type[ActionType]] = {
    "trajectory": TrajectoryAction,
    "control": ControlAction,
    "discrete": DiscreteAction,
}
