"""GridSim-v0: the gymnasium environment.

Observation (``Dict``):

- ``grids``: uint8 ``(history, rows, cols)``, the last ``env.history`` occupancy grids, oldest
  first, one per decision (0 free, 128 unknown, 255 occupied; after ``reset`` all copies
  of the first grid).
- ``ego``: float32 ``(6,)`` = speed [m/s], steering angle [rad], acceleration [m/s^2] and
  steering rate [rad/s] applied in the last tick, and cos / sin of the heading in the grid
  frame (``heading_up``: 1, 0).
- ``destination``: float32 ``(2,)``, where the reference is at the end of the horizon
  (``t + horizon * setpoint_period``), or ``env.goal_seconds`` ahead if the scenario sets it
  (a goal beyond the horizon: no planner is given its last set-point), in the grid frame [m].

The grid frame has its origin at the rear axle; its axes are the world's (north_up) or the
body's (heading_up): see :mod:`gridsim.frames`.

Reward: float32 ``(3,)`` fitness vector ``[l1, l2, l3]`` for the step (see
:meth:`GridSimEnv.step`); ``env.unwrapped.reward_space`` describes it (MO-Gymnasium).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gridsim import interrupts
from gridsim.envs.actions import ACTION_TYPES
from gridsim.envs.human_reference import ReferenceTrajectory, human_reference, reference_from_track
from gridsim.envs.observations import OBSERVATION_TYPES
from gridsim.envs.vector_guard import refuse_scalar_reward_vectorization
from gridsim.errors import ScenarioError
from gridsim.frames import EGO_FEATURES, grid_rotation, grid_to_world, world_to_grid
from gridsim.outputs import short_repr
from gridsim.render.topdown import PLAN_COLOUR, REFERENCE_COLOUR, TopDownRenderer
from gridsim.scenario.build import build_sensor, build_world
from gridsim.scenario.collection import load_collection, pick
from gridsim.scenario.parts import vehicle_params
from gridsim.scenario.schema import Scenario
from gridsim.seeding import EPISODE_SEEDS
from gridsim.vehicle.kinematics import DELTA, PSI, V

#: Options of gymnasium's vector envs that ``gym.make_vec`` passes on to each env when they
#: are given beside the env's own keywords instead of in ``vector_kwargs``.
VECTOR_OPTIONS = frozenset({"context", "shared_memory", "copy", "daemon", "autoreset_mode",
                            "observation_mode"})  # fmt: skip


class GridSimEnv(gym.Env):
    """Drive the ego of a GridSim scenario from occupancy grids.

    ``scenario``: a built-in name, a YAML or CommonRoad XML path, a folder or glob of such
    files (a collection: one scenario per reset, drawn from the seed), or a loaded
    :class:`Scenario`;
    ``action_type``: ``"trajectory"`` (default), ``"control"`` or ``"discrete"``
    (:data:`~gridsim.envs.actions.ACTION_TYPES`);
    ``observation_type``: ``"grids"`` (default: the paper's occupancy grids, ego state and
    destination), ``"grid"`` (the newest grid only) or ``"kinematics"``
    (:data:`~gridsim.envs.observations.OBSERVATION_TYPES`);
    further keyword arguments are scenario overrides (nested dicts), validated by the
    scenario schema, e.g. ``traffic={"participants": 20}``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        scenario: str | Scenario = "seamless",
        render_mode: str | None = None,
        action_type: str = "trajectory",
        observation_type: str = "grids",
        **overrides: Any,
    ) -> None:
        vector = sorted(set(overrides) & VECTOR_OPTIONS)
        if vector:
            raise ScenarioError(f"{', '.join(vector)}: an option of gymnasium's vector env, not "
                                "a scenario key: give it as gym.make_vec(..., vector_kwargs="
                                f"{{{vector[0]!r}: ...}})")  # fmt: skip
        _refuse_unknown_options(overrides)
        if isinstance(scenario, Scenario):
            if overrides:
                raise ScenarioError("overrides need a scenario name or path, not a Scenario object")
            self.scenarios = [scenario]
        else:
            self.scenarios = load_collection(scenario, overrides)
        #: The scenario of the current episode (of a collection: drawn at each reset).
        self.scenario = self.scenarios[0]
        if render_mode not in (None, "rgb_array"):
            raise ValueError(
                f"render_mode must be None or 'rgb_array' (or gym.make's 'rgb_array_list'), got "
                f"{render_mode!r}: GridSim never opens a window; render 'rgb_array' frames with "
                "env.render() or export a video (gridsim.video.record_rollout, `gridsim run "
                "--video out.mp4`)"
            )
        if action_type not in ACTION_TYPES:
            raise ValueError(
                f"action_type must be one of {sorted(ACTION_TYPES)}, got {action_type!r}"
            )
        if observation_type not in OBSERVATION_TYPES:
            raise ValueError(f"observation_type must be one of {sorted(OBSERVATION_TYPES)}, "
                             f"got {observation_type!r}")  # fmt: skip
        cfg = self.scenario.config
        self.render_mode = render_mode
        self.cfg = cfg
        self.sensor = build_sensor(self.scenario)
        self._orientation = cfg.sensor.orientation
        self._ticks = cfg.ticks_per_decision
        e = cfg.env
        self._setpoint_times = e.setpoint_times
        # the reference is looked up at the set-point times, and at the goal's beyond them
        far = e.goal_time > e.horizon_time
        self._look_times = np.append(e.setpoint_times, e.goal_time) if far else e.setpoint_times
        self.metadata = {**self.metadata, "render_fps": 1.0 / e.decision_period}
        # Spaces depend only on the scenario, not on the episode.
        params = vehicle_params(cfg.ego.vehicle)
        self.action_kind = ACTION_TYPES[action_type](
            params, e.horizon, e.setpoint_period, self._orientation, e.decision_period
        )
        self.action_type = action_type
        self.action_space = self.action_kind.space
        self.observation_kind = OBSERVATION_TYPES[observation_type](cfg)
        self.observation_type = observation_type
        self.observation_space = self.observation_kind.space
        #: whether the sensor renders a grid every step (its observations or frames need it)
        self._sensing = self.observation_kind.needs_grids or render_mode is not None
        #: Bounds of the per-step fitness vector [l1, l2, l3] (MO-Gymnasium convention).
        self.reward_space = spaces.Box(
            np.zeros(3, np.float32), np.full(3, np.inf, np.float32), dtype=np.float32
        )
        self.renderer = TopDownRenderer() if render_mode else None
        self.world = None
        # The last grids, a ring: the newest at index _newest (the observation puts them in
        # order, oldest first).
        self._grids = np.zeros((e.history, cfg.sensor.rows, cfg.sensor.cols), np.uint8)
        self._newest = len(self._grids) - 1
        self._scored = None  # the last plan and the reference it was scored against

    # -- episode ----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        interrupts.enter()  # a Ctrl-C waits for the reset's end (gridsim.interrupts)
        try:
            return self._reset(seed, options)
        finally:
            interrupts.leave()

    def _reset(self, seed: int | None, options: dict | None):
        replay = _replayed_episode(options)
        super().reset(seed=seed)
        # (drawn always: the stream goes on alike; after reset(seed=S), episode_seed(S))
        drawn = int(self.np_random.integers(EPISODE_SEEDS))
        episode_seed = drawn if replay is None else replay
        self.episode_seed = episode_seed
        if len(self.scenarios) > 1:
            self.scenario = pick(self.scenarios, episode_seed)
            self.cfg = self.scenario.config
        self.world = build_world(self.scenario, episode_seed)
        self.reference = self._reference(episode_seed)
        self._last_accel = self._last_rate = 0.0
        self._scored = None
        self._travelled = 0.0
        self._terminated = self._truncated = False
        if self._sensing:
            self._grids[:] = self.sensor.observe(self.world)[None]
        self._newest = len(self._grids) - 1
        self._look_ahead()
        return self._observation(), self._info(terms=np.zeros(3, np.float32))

    def _look_ahead(self) -> None:
        """Reference positions at the coming set-point times, world and grid frames."""
        w = self.world
        world, grid = self.reference.positions_in_grid(
            w.time + self._look_times, w.ego[:2], grid_rotation(self._orientation, w.ego[PSI])
        )
        h = len(self._setpoint_times)
        self._ref_future, self._ref_future_grid = world[:h], grid[:h]
        # the destination observed: the last set-point's or beyond
        self._goal_world, self._goal_grid = world[-1], grid[-1]

    def to_grid(self, points: np.ndarray) -> np.ndarray:
        """World points ``(N, 2)`` [m] in the ego's grid frame now (rear axle at the origin)."""
        w = self._current_world("to_grid")
        return world_to_grid(points, w.ego[:2], grid_rotation(self._orientation, w.ego[PSI]))

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Points ``(N, 2)`` [m] of the ego's grid frame now (an action's set-points) in the
        world frame."""
        w = self._current_world("to_world")
        return grid_to_world(points, w.ego[:2], grid_rotation(self._orientation, w.ego[PSI]))

    def _current_world(self, caller: str):
        if self.world is None:
            raise RuntimeError(f"call reset() before {caller}()")
        return self.world

    def reference_in_grid(self, times: np.ndarray) -> np.ndarray:
        """The reference's positions ``(N, 2)`` [m] at absolute episode ``times`` [s] (within
        the look-ahead), in the ego's grid frame like ``info["reference_setpoints"]``."""
        self._current_world("reference_in_grid")
        return self.to_grid(self.reference.positions(np.asarray(times, np.float64)))

    def _reference(self, seed: int) -> ReferenceTrajectory:
        cfg = self.cfg
        track = self.world.ego_track
        if track is not None:
            return reference_from_track(track, self.world.ego_params.center_offset)
        ahead = max(cfg.env.horizon_time, cfg.env.goal_time)
        return human_reference(self.scenario, seed, cfg.simulation.duration + ahead)

    @property
    def time_limit(self) -> float:
        """Episode length [s]: the scenario's duration (on recorded scenes at most the track's)."""
        limit = self.cfg.simulation.duration
        if self.world is not None and self.world.ego_track is not None:
            limit = min(limit, self.world.ego_track.duration)
        return limit

    def step(self, action):
        """Advance one decision period. Returns the fitness vector ``[l1, l2, l3]`` (float32):

        - ``l1`` [m^2] (minimise): sum over the ``horizon`` set-point times ``t + i T`` of the
          squared distance between the commanded position (the action's set-points; for
          control and discrete actions, the bicycle model holding that input) and the
          reference position at the same time;
        - ``l2`` [rad/s] (minimise): sum over the step's ticks of the magnitude of the
          steering rate applied;
        - ``l3`` [m/s] (maximise): sum over the step's ticks of the speed, counting a tick only
          if the speed lies in ``[v_min, v_max]`` (``env.speed_range``).
        """
        interrupts.enter()  # a Ctrl-C waits for the step's end (gridsim.interrupts)
        try:
            return self._step(action)
        finally:
            interrupts.leave()

    def _step(self, action):
        """The body of :meth:`step`: its phases :meth:`_plan`, :meth:`_act`, :meth:`_sense`
        and :meth:`_finish`."""
        self._plan(action)
        self._act()
        self._sense()
        return self._finish()

    def _check_steppable(self) -> None:
        """A :class:`RuntimeError` unless a step may come now (after a reset, before the
        episode's end)."""
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        if self._terminated:
            raise RuntimeError("the episode has terminated (collision, off-road or destination "
                               "reached): call reset() before step()")  # fmt: skip
        if self._truncated:
            raise RuntimeError(f"the episode reached its time limit ({self.time_limit:g} s, "
                               "simulation.duration): call reset() before step()")  # fmt: skip

    def _plan(self, action) -> None:
        """A step's first phase: the action checked and turned into the controller and the
        commanded plan (nothing moves yet)."""
        self._check_steppable()
        world = self.world
        rotation = grid_rotation(self._orientation, world.ego[PSI])
        self._planned = self.action_kind.controller(world, action, rotation)

    def _act(self) -> None:
        """A step's second phase, after :meth:`_plan`: the world's ticks (the fitness terms
        and the last tick's result kept for :meth:`_finish`)."""
        world = self.world
        control, plan = self._planned
        l1 = float(((plan - self._ref_future) ** 2).sum())
        l2 = l3 = 0.0
        v_lo, v_hi = self.cfg.speed_range
        result = None
        tick = getattr(control, "tick", None)  # the controller's own (compiled) tick
        for _ in range(self._ticks):
            result = tick(world) if tick is not None else world.tick(*control(world))
            self._travelled += world.moved  # np.hypot of the rear axle's displacement
            l2 += abs(result.steer_rate)
            v = world.ego[V]
            l3 += v if v_lo <= v <= v_hi else 0.0
            if result.collided or result.off_road:
                break
        self._last_accel, self._last_rate = result.accel, result.steer_rate
        self._scored = (plan, self._ref_future)  # (before the look-ahead moves on)
        self._acted = (result, l1, l2, l3)

    def _sense(self) -> None:
        """A step's third phase, after :meth:`_act`: the new grid."""
        self._newest = (self._newest + 1) % len(self._grids)
        if self._sensing:
            self.sensor.observe(self.world, out=self._grids[self._newest])

    def _finish(self):
        """A step's last phase, after :meth:`_sense`: the look-ahead, the episode's end and
        what :meth:`step` returns."""
        result, l1, l2, l3 = self._acted
        world = self.world
        self._look_ahead()
        tol = self.cfg.env.destination_tolerance
        reached = self.reference.reached(world.ego[:2], self._travelled, tol)
        ends = reached and self.cfg.env.end_at_destination
        terminated = bool(result.collided or result.off_road or ends)
        self._terminated = terminated
        truncated = (not terminated) and world.time >= self.time_limit - 1e-9
        self._truncated = truncated
        terms = np.array([l1, l2, l3], np.float32)
        info = self._info(terms, reached)
        return self._observation(), terms, terminated, truncated, info

    # -- observation and info ---------------------------------------------------------------
    def _observation(self) -> Any:
        return self.observation_kind.observe(self)

    def grid_history(self) -> np.ndarray:
        """The last ``env.history`` occupancy grids ``(history, rows, cols)`` uint8, oldest
        first (a copy)."""
        self._rendered_grids("grid_history")
        k = self._newest + 1
        return np.concatenate((self._grids[k:], self._grids[:k]))

    def newest_grid(self) -> np.ndarray:
        """The occupancy grid of now ``(rows, cols)`` uint8 (a copy): the last of
        :meth:`grid_history`."""
        return self._rendered_grids("newest_grid")[self._newest].copy()

    def _rendered_grids(self, caller: str) -> np.ndarray:
        """The ring of the last grids, after the checks that they are rendered."""
        self._current_world(caller)
        if not self._sensing:
            raise RuntimeError(f"observation_type {self.observation_type!r} renders no grids "
                               "(its observations do not need them): use an observation type "
                               "with needs_grids = True, or render_mode='rgb_array'")  # fmt: skip
        return self._grids

    def ego_features(self) -> np.ndarray:
        """The ego now, float32 ``(6,)``: :data:`~gridsim.frames.EGO_FEATURES` (speed [m/s],
        steering angle [rad], the last tick's acceleration [m/s^2] and steering rate [rad/s],
        cos and sin of the heading in the grid frame)."""
        w = self._current_world("ego_features")
        heading = w.ego[PSI] - grid_rotation(self._orientation, w.ego[PSI])
        # (math's cos and sin are libm's, as NumPy's on a float64 scalar: see kinematics)
        return np.array([w.ego[V], w.ego[DELTA], self._last_accel, self._last_rate,
                         math.cos(heading), math.sin(heading)], np.float32)  # fmt: skip

    def destination(self) -> np.ndarray:
        """The destination [m, grid frame] float32 ``(2,)``: the reference at the goal time
        (the last set-point's, or ``env.goal_seconds`` ahead)."""
        self._current_world("destination")
        return self._goal_grid.copy()

    def _info(self, terms: np.ndarray, reached: bool = False) -> dict[str, Any]:
        w = self.world
        contact = w.last.contact
        return {
            # s; the world's clock is a sum of ticks (7.39999999999999 after 74): shown to
            # the nanosecond, as a user compares it (7.4)
            "time": round(w.time, 9),
            "pose": w.ego.copy(),  # [x, y, psi, v, delta] world frame, rear axle
            "collision": bool(contact.vehicles),
            "collided_with": list(contact.vehicles),
            "off_road": bool(w.last.off_road),
            "road_edges_touched": list(contact.boundaries),
            "destination_reached": reached,
            "reference_setpoints": self._ref_future_grid.copy(),
            "l1": float(terms[0]),
            "l2": float(terms[1]),
            "l3": float(terms[2]),
            "episode_seed": self.episode_seed,
        }

    # -- rendering ----------------------------------------------------------------------------
    def render(self):
        """The top-down frame of now, RGB ``(H, W, 3)`` uint8 (``render_mode="rgb_array"``);
        without a render mode None, with gymnasium's warning."""
        if self.render_mode != "rgb_array":
            gym.logger.warn("render() without a render mode draws nothing: make the env with "
                            'render_mode="rgb_array", e.g. gym.make("GridSim-v0", '
                            'render_mode="rgb_array")')  # fmt: skip
            return None
        self._current_world("render")
        # After a step, the last plan beside the human's set-points it was scored against
        # (l1 sums their squared distances: a plan that matches them covers them), before
        # the first step the human's next set-points.
        if self._scored is None:
            overlay = [(self._ref_future, REFERENCE_COLOUR, "ring")]
        else:
            plan, reference = self._scored
            overlay = [(reference, REFERENCE_COLOUR, "ring"), (plan, PLAN_COLOUR, "dot")]
        sensor = self.cfg.sensor
        human = self.reference.positions(np.array([self.world.time]))[0]  # where it is now
        return self.renderer.render(self.world, self._grids[self._newest], overlay,
                                    grid_frame=(sensor.cell_size, sensor.orientation),
                                    human=human, destination=self._goal_world)  # fmt: skip


#: The keywords of ``GridSimEnv`` and of ``gym.make_vec``'s default vector env: a misspelt one
#: is told apart from a scenario section.
ENV_OPTIONS = ("scenario", "render_mode", "action_type", "observation_type")
VECTOR_ENV_OPTIONS = ("num_envs", "asynchronous", "autoreset_mode", "context")


#: ``reset(options=...)`` keys.
RESET_OPTIONS = ("episode_seed",)


def _replayed_episode(options: dict | None) -> int | None:
    """The ``episode_seed`` of ``reset(options={"episode_seed": S})`` (an ``info`` of an
    earlier episode: the same episode again), checked; None without it."""
    options = options or {}
    for key in options:
        if key not in RESET_OPTIONS:
            raise ValueError(f"reset() has no option {key!r}; its options: "
                             f"{', '.join(RESET_OPTIONS)}")  # fmt: skip
    value = options.get("episode_seed")
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"reset(options={{'episode_seed': ...}}) takes an int (an info's "
                         f"'episode_seed'), got {short_repr(value)}")  # fmt: skip
    if not 0 <= value < 2**31 - 1:
        raise ValueError(f"episode_seed must be in [0, 2**31 - 1), got {value}")
    return int(value)


def _refuse_unknown_options(overrides: dict) -> None:
    """A :class:`ScenarioError` for a keyword that is neither a scenario section nor an option
    of the env, with the closest spelling of either."""
    import difflib

    from gridsim.scenario.schema import ScenarioConfig

    sections = tuple(ScenarioConfig.model_fields)
    for key in overrides:
        if key in sections:
            continue
        known = ENV_OPTIONS + VECTOR_ENV_OPTIONS + sections
        close = difflib.get_close_matches(key, known, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        if key == "seed":
            hint = " (an episode's seed is reset(seed=...)'s)"
        raise ScenarioError(f"GridSim-v0 has no option {key!r}{hint}. Its options: "
                            f"{', '.join(ENV_OPTIONS)} (make_vec: {', '.join(VECTOR_ENV_OPTIONS)});"
                            f" scenario sections to override: {', '.join(sections)}")  # fmt: skip


def make_env(**kwargs: Any) -> gym.Env:
    """The entry point of ``gym.make("GridSim-v0", ...)`` (and of ``gym.make_vec``'s
    ``"sync"``/``"async"`` modes, which it refuses when they cannot hold the reward vector).
    ``render_mode="rgb_array_list"`` is the env in ``"rgb_array"`` under gymnasium's
    ``RenderCollection`` (``render()`` returns the frames since the last call)."""
    refuse_scalar_reward_vectorization()
    if kwargs.get("render_mode") == "rgb_array_list":
        from gymnasium.wrappers import RenderCollection

        return RenderCollection(GridSimEnv(**{**kwargs, "render_mode": "rgb_array"}))
    return GridSimEnv(**kwargs)


def step_all(envs: Sequence[GridSimEnv], actions: Sequence) -> list[tuple]:
    """``[env.step(action) for env, action in zip(envs, actions)]`` for distinct
    :class:`GridSimEnv` (not wrapped: a wrapper's step would be bypassed), each phase of a
    step for every environment in turn: every action checked and planned, then every
    world's ticks, then every grid, then every look-ahead and result. The tables the worlds
    of a process share (the sensor's rays, the library's profiles) then stay in cache from
    one environment to the next (``benchmarks/bench_env.py``'s ``lockstep`` measures it),
    with the same results (each environment's own computations are unchanged). Every
    environment and action is checked before any world moves (the errors of
    :meth:`GridSimEnv.step`)."""
    if len(envs) != len(actions):
        raise ValueError(f"{len(envs)} environments and {len(actions)} actions")
    if any(env is not env.unwrapped for env in envs):
        raise ValueError(
            "step_all steps GridSimEnv themselves: give env.unwrapped (a "
            "wrapper's own step would be bypassed), or step wrapped ones alone"
        )
    if len({id(env) for env in envs}) != len(envs):
        raise ValueError("an environment is listed twice: step_all steps each once")
    interrupts.enter()  # a Ctrl-C waits for the steps' end (gridsim.interrupts)
    try:
        for env, action in zip(envs, actions, strict=True):
            env._plan(action)
        for env in envs:
            env._act()
        for env in envs:
            env._sense()
        return [env._finish() for env in envs]
    finally:
        interrupts.leave()


__all__ = ["EGO_FEATURES", "GridSimEnv", "make_env", "step_all"]
