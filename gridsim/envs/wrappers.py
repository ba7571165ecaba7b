"""Wrappers for GridSim-v0."""

from __future__ import annotations

from collections.abc import Sequence

import gymnasium as gym
import numpy as np

from gridsim.envs.plan_smoothing import PlanSmoother

#: Default weights for [l1, l2, l3]: squared set-point error and steering rate are costs,
#: speed a reward (l1 is in m^2 summed over the horizon, hence its small weight).
DEFAULT_WEIGHTS = (-0.01, -0.5, 0.1)


class _FitnessReward(gym.RewardWrapper):
    """A reward made from GridSim-v0's fitness vector ``[l1, l2, l3]``, which stays in
    ``info["fitness"]`` (the innermost such wrapper's: the paper's vector). Refuses an env
    whose reward is not that vector (one of these wrappers already under it)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        inner = env
        while isinstance(inner, gym.Wrapper):
            if isinstance(inner, _FitnessReward):
                mine, under = type(self).__name__, type(inner).__name__
                raise ValueError(f"{mine} takes the fitness vector [l1, l2, l3], but {under} "
                                 "is already under it: use one")  # fmt: skip
            inner = inner.env

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        info = {**info, "fitness": np.asarray(reward, dtype=np.float32)}
        return obs, self.reward(reward), terminated, truncated, info


class LinearScalarization(_FitnessReward, gym.utils.RecordConstructorArgs):
    """Scalar reward ``w . [l1, l2, l3]`` for single-objective RL libraries.

    Use negative weights for the minimised objectives (l1, l2) and a positive one for l3.
    The vector is still in ``info["fitness"]``; ``reward_space`` is the scalar's (shape
    ``()``: one objective, for libraries that count them; ``env.unwrapped.reward_space`` is
    still GridSim-v0's vector).
    """

    def __init__(self, env: gym.Env, weights: Sequence[float] = DEFAULT_WEIGHTS) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, weights=weights)
        _FitnessReward.__init__(self, env)
        w = np.asarray(weights, dtype=np.float64)
        if w.shape != (3,) or not np.all(np.isfinite(w)):
            raise ValueError(f"weights must be 3 finite numbers for [l1, l2, l3], got {weights!r}")
        self.weights = w
        # l1, l2, l3 >= 0: each weighted term runs from 0 to its weight's sign of infinity
        low, high = (-np.inf if (w < 0).any() else 0.0), (np.inf if (w > 0).any() else 0.0)
        self.reward_space = gym.spaces.Box(low, high, shape=(), dtype=np.float64)

    def reward(self, reward) -> float:
        return float(np.dot(self.weights, reward))


def make_scalar_env(weights: Sequence[float] = DEFAULT_WEIGHTS, **kwargs) -> LinearScalarization:
    """``GridSimScalar-v0``: GridSim-v0 made with ``kwargs``, its reward ``weights . [l1, l2,
    l3]``. Registered, so that libraries that wrap the env they make before any wrapper of
    yours (Stable-Baselines3's ``make_vec_env`` puts its ``Monitor`` first, which needs a
    scalar reward) get the scalar: ``make_vec_env("GridSimScalar-v0", env_kwargs={"weights":
    (-0.01, -0.5, 0.1), "action_type": "control"})``."""
    from gridsim.envs.gridsim_env import make_env

    return LinearScalarization(make_env(**kwargs), weights)


#: The signs that make every objective maximised: ``[-l1, -l2, l3]``.
MAXIMISED_SIGNS = np.array([-1.0, -1.0, 1.0], np.float32)


class MaximisedObjectives(_FitnessReward, gym.utils.RecordConstructorArgs):
    """The reward vector ``[-l1, -l2, l3]``: every objective maximised, as MO-Gymnasium and
    MORL libraries (MORL-Baselines' Pareto filters, hypervolumes) assume; GridSim-v0's own
    ``[l1, l2, l3]`` minimises l1 and l2. ``reward_space`` is ``Box([-inf, -inf, 0], [0, 0,
    inf])``; the paper's vector is still in ``info["fitness"]``."""

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        _FitnessReward.__init__(self, env)
        own = env.get_wrapper_attr("reward_space")
        low, high = own.low * MAXIMISED_SIGNS + 0.0, own.high * MAXIMISED_SIGNS + 0.0  # (no -0)
        self.reward_space = gym.spaces.Box(np.minimum(low, high), np.maximum(low, high),
                                           dtype=np.float32)  # fmt: skip

    def reward(self, reward) -> np.ndarray:
        return np.asarray(reward, np.float32) * MAXIMISED_SIGNS + np.float32(0.0)  # (no -0)


class PlanSmoothing(gym.ActionWrapper, gym.utils.RecordConstructorArgs):
    """Steps GridSim-v0 (trajectory action) with each action blended with the plan before it:
    ``keep`` is the share of the previous plan kept (see :mod:`gridsim.envs.plan_smoothing`).
    The reward's ``l1`` and ``info`` describe the plan followed, the blended one."""

    def __init__(self, env: gym.Env, keep: float) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, keep=keep)
        gym.ActionWrapper.__init__(self, env)
        if getattr(env.unwrapped, "action_type", None) != "trajectory":
            raise ValueError("PlanSmoothing blends trajectory actions: make the environment "
                             "with action_type='trajectory'")  # fmt: skip
        self.smoother = PlanSmoother(keep)

    def action(self, action):
        return self.smoother(self.env, action)


class CaptionedRender(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """``render()`` frames annotated as the exported videos are (:mod:`gridsim.render.annotations`:
    ``label`` for the driver, time, speed, the fitness summed since the reset, a colour legend,
    a scale bar). The env must be made with ``render_mode="rgb_array"``."""

    def __init__(self, env: gym.Env, label: str | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, label=label)
        gym.Wrapper.__init__(self, env)
        if env.render_mode != "rgb_array":
            raise ValueError("CaptionedRender annotates rgb_array frames: make the environment "
                             "with render_mode='rgb_array'")  # fmt: skip
        self.label = label
        self._info: dict | None = None
        self._fitness = np.zeros(3)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._info, self._fitness = info, np.zeros(3)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._info = {**info, "truncated": bool(truncated)}  # (a wrapper's time limit too)
        self._fitness = self._fitness + (info["l1"], info["l2"], info["l3"])
        return obs, reward, terminated, truncated, info

    def render(self):
        from gridsim.render.annotations import annotate_env_frame

        frame = self.env.render()
        if frame is None or self._info is None:
            return frame
        return annotate_env_frame(self.env, frame, self._info, self.label, self._fitness.copy())


#: GridSim's wrappers whose reward is still a vector (``gym.make_vec``'s sync and async
#: modes cannot stack it: :func:`~gridsim.envs.vector_guard.refuse_scalar_reward_vectorization`).
VECTOR_REWARD_WRAPPERS = (MaximisedObjectives, PlanSmoothing, CaptionedRender)
