"""Gymnasium environments: ``GridSim-v0`` (reward: the fitness vector ``[l1, l2, l3]``) and
``GridSimScalar-v0`` (the same, its reward scalarised by
:class:`~gridsim.envs.wrappers.LinearScalarization` with the keyword ``weights``: for
single-objective libraries such as Stable-Baselines3)."""

from __future__ import annotations

import importlib

import gymnasium

ENV_ID = "GridSim-v0"
#: The scalar-reward variant (keyword ``weights``, default ``wrappers.DEFAULT_WEIGHTS``).
SCALAR_ENV_ID = "GridSimScalar-v0"


def register_envs() -> None:
    """Register ``GridSim-v0`` and ``GridSimScalar-v0`` with gymnasium (idempotent)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=ENV_ID,
            # a function, not the class: gymnasium would wrap render_mode="human" around the
            # class's rgb_array frames and open a pygame window; GridSimEnv refuses it
            entry_point="gridsim.envs.gridsim_env:make_env",
            # gym.make_vec's default: rewards stacked (num_envs, 3), sync or asynchronous=True
            # (gymnasium's own vector envs, vectorization_mode="sync"/"async", hold them only
            # in some autoreset modes; make_env refuses the combinations that would fail
            # mid-rollout)
            vector_entry_point="gridsim.envs.vector:make_vector_env",
            # without OrderEnforcing, gym.make returns GridSimEnv itself: env.reward_space
            # works (GridSimEnv refuses step() before reset() on its own)
            order_enforce=False,
            # The reward is a vector (MO-Gymnasium style); gymnasium's passive checker would
            # warn on every step. check_env is run in the test suite instead.
            disable_env_checker=True,
        )
    if SCALAR_ENV_ID not in gymnasium.registry:
        gymnasium.register(
            id=SCALAR_ENV_ID,
            entry_point="gridsim.envs.wrappers:make_scalar_env",
            order_enforce=False,  # as GridSim-v0
            disable_env_checker=True,  # checked in the test suite
        )


#: Submodules reachable as attributes after ``import gridsim`` (``gridsim.envs.wrappers...``,
#: as the docs write them), imported on first use so that ``import gridsim`` stays light.
_SUBMODULES = ("actions", "gridsim_env", "observations", "plan_smoothing", "vector",
               "vector_guard", "wrappers")  # fmt: skip


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
