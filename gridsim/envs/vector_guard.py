"""What ``gym.make_vec`` must not build for GridSim-v0: gymnasium's own vector envs where
they cannot hold the reward vector (see :mod:`gridsim.envs.vector`)."""

from __future__ import annotations

import sys

import gymnasium as gym
from gymnasium.envs.registration import VectorizeMode
from gymnasium.vector import AutoresetMode

from gridsim.envs import ENV_ID


def refuse_scalar_reward_vectorization() -> None:
    """Raise if ``gym.make_vec`` is building a vector env that cannot hold the reward vector.

    With ``vectorization_mode="sync"`` or ``"async"``, ``make_vec`` builds gymnasium's own
    ``SyncVectorEnv`` or ``AsyncVectorEnv`` and never calls
    :func:`~gridsim.envs.vector.make_vector_env`: the single-env entry point, which calls
    this, is the only GridSim code it runs. So the call's
    arguments are read from ``make_vec``'s frame on the stack (nothing is raised elsewhere).
    ``wrappers`` are trusted to scalarise the reward (e.g. ``LinearScalarization``), unless
    every one is a GridSim wrapper known to keep the vector (``MaximisedObjectives``,
    ``PlanSmoothing``, ``CaptionedRender``). The id may name the module
    (``"gridsim:GridSim-v0"``) or be the env's spec.
    """
    from gridsim.envs.wrappers import VECTOR_REWARD_WRAPPERS

    frame = sys._getframe(1)
    while frame is not None and frame.f_code is not gym.make_vec.__code__:
        frame = frame.f_back
    if frame is None:
        return
    wrappers = frame.f_locals.get("wrappers") or ()
    if any(not (isinstance(w, type) and issubclass(w, VECTOR_REWARD_WRAPPERS))
           for w in wrappers):  # fmt: skip
        return
    env_id = frame.f_locals.get("id")
    env_id = getattr(env_id, "id", env_id)
    if not isinstance(env_id, str) or env_id.rpartition(":")[2] != ENV_ID:
        return  # another env (one that wraps GridSim-v0 is its author's to vectorise)
    mode = frame.f_locals.get("vectorization_mode")
    vector_kwargs = frame.f_locals.get("vector_kwargs") or {}
    fixes = (
        "leave vectorization_mode unset (GridSim's own vector env: rewards (num_envs, 3) in "
        "every autoreset mode; asynchronous=True for subprocesses, autoreset_mode=... to choose "
        "the mode), or pass wrappers=[gridsim.envs.wrappers.LinearScalarization] for scalar "
        "rewards"
    )
    if mode == VectorizeMode.SYNC:
        raise ValueError(
            "gym.make_vec('GridSim-v0', vectorization_mode='sync') builds gymnasium's "
            "SyncVectorEnv, which stores one float reward per environment and cannot hold "
            f"GridSim's reward vector [l1, l2, l3]: {fixes}"
        )
    if mode != VectorizeMode.ASYNC or vector_kwargs.get("worker") is not None:
        return
    autoreset = AutoresetMode(vector_kwargs.get("autoreset_mode", AutoresetMode.NEXT_STEP))
    if autoreset is AutoresetMode.NEXT_STEP:
        raise ValueError(
            "gym.make_vec('GridSim-v0', vectorization_mode='async') builds gymnasium's "
            "AsyncVectorEnv, whose workers answer the step after an episode end (autoreset_mode "
            "NEXT_STEP, the default) with a scalar reward 0 that cannot be stacked with GridSim's "
            f"reward vectors [l1, l2, l3]: {fixes}; or keep vectorization_mode='async' with "
            "vector_kwargs={'worker': gridsim.envs.vector.mo_async_worker} or "
            "vector_kwargs={'autoreset_mode': gym.vector.AutoresetMode.SAME_STEP}"
        )
