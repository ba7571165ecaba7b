"""Vector GridSim-v0 with vector rewards: ``gym.make_vec("GridSim-v0", n)``.

gymnasium's vector environments cannot hold the fitness vector ``[l1, l2, l3]``:
``SyncVectorEnv`` keeps one float reward per environment, and ``AsyncVectorEnv``'s workers
answer the step after an episode end (``AutoresetMode.NEXT_STEP``, the default) with the
scalar reward 0, which does not stack with the vectors (gymnasium issue #1445).
:class:`MOSyncVectorEnv` and :class:`MOAsyncVectorEnv` stack them as ``(num_envs, 3)``, with
a zero vector on that autoreset step, in every autoreset mode (like MO-Gymnasium's
``MOSyncVectorEnv``).

``gym.make_vec(..., vectorization_mode="sync" | "async")`` builds gymnasium's own classes and
never calls :func:`make_vector_env`;
:func:`~gridsim.envs.vector_guard.refuse_scalar_reward_vectorization` turns the combinations
that would fail mid-rollout into an error at construction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import iterate

from gridsim.envs.gridsim_env import GridSimEnv, step_all

EnvFns = Sequence[Callable[[], gym.Env]]


class MOSyncVectorEnv(gym.vector.SyncVectorEnv):
    """``SyncVectorEnv`` whose rewards have the shape of the environments' ``reward_space``.

    When its environments are distinct :class:`GridSimEnv` themselves (not wrapped: as
    :func:`make_vector_env` builds them), a step steps them phase by phase
    (:func:`~gridsim.envs.gridsim_env.step_all`: the same results, the shared tables kept in
    cache); gymnasium's ``step`` then collects those results, resets and stacks as usual."""

    def __init__(self, env_fns: EnvFns, **kwargs: Any) -> None:
        super().__init__(env_fns, **kwargs)
        try:  # (a wrapper's own, as the asynchronous one reads it: a scalarisation's is ())
            space = self.envs[0].get_wrapper_attr("reward_space")
        except AttributeError:
            space = None
        shape = space.shape if space is not None else ()
        self._rewards = np.zeros((self.num_envs, *shape), dtype=np.float64)
        self.reward_space = space
        self._phased = len({id(e) for e in self.envs}) == len(self.envs) and all(
            type(e) is GridSimEnv for e in self.envs
        )

    def step(self, actions: Any) -> tuple:
        check_batch(self, actions)
        if not self._phased:
            return super().step(actions)
        skipped = self._autoreset_envs if self.autoreset_mode == AutoresetMode.NEXT_STEP else None
        live = [i for i in range(self.num_envs) if skipped is None or not skipped[i]]
        per_env = list(iterate(self.action_space, actions))
        results = step_all([self.envs[i] for i in live], [per_env[i] for i in live])
        envs = self.envs
        answered = list(envs)
        for i, result in zip(live, results, strict=True):
            answered[i] = _Stepped(envs[i], result)
        self.envs = answered  # gymnasium's step reads each result from its env's step
        try:
            return super().step(actions)
        finally:
            self.envs = envs


class _Stepped:
    """An environment already stepped: its ``step`` answers ``result``; the rest is its own."""

    def __init__(self, env: GridSimEnv, result: tuple) -> None:
        self._env, self._result = env, result

    def step(self, action: Any) -> tuple:
        return self._result

    def __getattr__(self, name: str) -> Any:
        return getattr(self._env, name)


class MOAsyncVectorEnv(gym.vector.AsyncVectorEnv):
    """``AsyncVectorEnv`` whose NEXT_STEP autoreset steps answer a zero reward vector.

    It runs :func:`mo_async_worker` in its subprocesses (unless given another ``worker``).
    """

    def __init__(self, env_fns: EnvFns, **kwargs: Any) -> None:
        super().__init__(env_fns, **{"worker": mo_async_worker, **kwargs})
        self.reward_space = self.get_attr("reward_space")[0]

    def step_async(self, actions: Any) -> None:
        """gymnasium's, after :func:`check_batch` (gymnasium's sends each environment its
        action before it finds the batch too long or short: the workers stepped a batch
        said to be refused, and every later step answered the one before)."""
        check_batch(self, actions)
        super().step_async(actions)


def check_batch(vector: gym.vector.VectorEnv, actions: Any) -> None:
    """A :class:`ValueError` naming the batch's shape when ``actions`` are not one action per
    environment of ``vector`` (its batched ``action_space``'s shape), before any is sent."""
    want = getattr(vector.action_space, "shape", None)
    if want is None or isinstance(actions, dict | tuple):
        return
    got = np.shape(actions)
    if got != want:
        raise ValueError(
            f"a vector of {vector.num_envs} environments steps a batch of actions "
            f"of shape {want} (one per environment: action_space), got {got}"
        )


class _ZeroRewardOnAutoresetPipe:
    """The worker's end of the pipe; a step answered with a scalar reward where the
    environment's last reward was an array (gymnasium's autoreset ``0``) gets zeros instead."""

    def __init__(self, pipe: Connection) -> None:
        self._pipe = pipe
        self._command: str | None = None
        self._last_reward: Any = None

    def recv(self) -> Any:
        message = self._pipe.recv()
        self._command = message[0]
        return message

    def send(self, message: Any) -> None:
        if self._command == "step" and message[1]:  # a successful step's answer
            obs, reward, terminated, truncated, info = message[0]
            if np.ndim(reward) < np.ndim(self._last_reward):
                reward = np.zeros_like(self._last_reward)
                message = ((obs, reward, terminated, truncated, info), True)
            else:
                self._last_reward = reward
        self._pipe.send(message)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._pipe, name)


def mo_async_worker(
    index: int, env_fn: Callable[[], gym.Env], pipe: Connection, *args: Any
) -> None:
    """gymnasium's ``AsyncVectorEnv`` worker, answering a zero reward vector on autoreset.

    gymnasium's ``_async_worker`` hard-codes the reward 0 of a NEXT_STEP autoreset step; rather
    than copy its loop, this runs it on a pipe that swaps that 0 for zeros shaped like the
    environment's rewards. Also usable as ``AsyncVectorEnv(..., worker=mo_async_worker)``.
    """
    from gymnasium.vector.async_vector_env import _async_worker  # gymnasium's default worker

    _async_worker(index, env_fn, _ZeroRewardOnAutoresetPipe(pipe), *args)


def make_vector_env(
    num_envs: int = 1,
    *,
    asynchronous: bool = False,
    autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    context: str | None = None,
    **kwargs: Any,
) -> MOSyncVectorEnv | MOAsyncVectorEnv:
    """The vector entry point of GridSim-v0 (``gym.make_vec``'s default mode).

    Args:
        num_envs: number of environments.
        asynchronous: one subprocess per environment (:class:`MOAsyncVectorEnv`) instead of
            stepping them in turn (:class:`MOSyncVectorEnv`).
        autoreset_mode: gymnasium's ``AutoresetMode`` (or its value, e.g. ``"SameStep"``).
        context: with ``asynchronous``, the subprocesses' start method (``"spawn"``,
            ``"forkserver"`` or ``"fork"``; default: multiprocessing's).
        **kwargs: the arguments of ``GridSimEnv``.
    """
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    if not isinstance(asynchronous, bool):
        raise ValueError(f"asynchronous must be True or False, got {asynchronous!r}")
    try:
        autoreset_mode = AutoresetMode(autoreset_mode)
    except ValueError:
        valid = ", ".join(f"AutoresetMode.{m.name} ({m.value!r})" for m in AutoresetMode)
        raise ValueError(f"autoreset_mode must be one of {valid}, got {autoreset_mode!r}") from None
    if context is not None:
        import multiprocessing

        if not asynchronous:
            raise ValueError(f"context={context!r} is the start method of the subprocesses of "
                             "asynchronous=True; the synchronous vector env has none")  # fmt: skip
        if context not in multiprocessing.get_all_start_methods():
            raise ValueError(f"context must be one of {multiprocessing.get_all_start_methods()}, "
                             f"got {context!r}")  # fmt: skip
    kwargs.pop("max_episode_steps", None)  # the scenario's duration ends episodes
    env_fns = [lambda: GridSimEnv(**kwargs) for _ in range(num_envs)]
    if asynchronous:
        return MOAsyncVectorEnv(env_fns, autoreset_mode=autoreset_mode, context=context)
    return MOSyncVectorEnv(env_fns, autoreset_mode=autoreset_mode)
