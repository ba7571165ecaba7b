"""``gridsim compile``: compile the simulator's kernels for this machine and cache them, so that
the first environment a user makes runs at once (``pip install .`` does it while it builds).

The kernels are numba functions compiled on first call for the argument types they get
(:mod:`gridsim.jit`); driving every built-in scenario briefly with every action type makes
each kernel meet the types it meets in use. What is compiled is cached next to the source
(``__pycache__``), keyed by the source's content, the CPU and numba's version.
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable

import numpy as np

from gridsim.errors import DataWarning


def add_parser(sub) -> None:
    p = sub.add_parser(
        "compile",
        help="compile the simulator's kernels for this machine and cache them (pip install . "
        "does it; run it after an editable install, or to fill a read-only install's cache)",
    )
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    print("compiling or loading the kernels of every built-in scenario:")
    done = compile_kernels()
    print(f"{done['kernels']} kernels ready ({done['compiled']} compilations) in "
          f"{done['seconds']:g} s")  # fmt: skip
    return 0


#: Decisions driven per scenario and action type: enough to start the traffic, the sensor,
#: the shadow world and the controllers.
STEPS = 12


def compile_kernels(report: Callable[[str], None] = print) -> dict:
    """Drive every built-in scenario with every action type for :data:`STEPS` decisions (the
    reference set-points, then seeded random actions), which compiles every kernel they use
    or loads it from the cache; ``{"scenarios", "kernels", "compiled", "seconds"}``."""
    from gridsim.envs.gridsim_env import ACTION_TYPES, GridSimEnv
    from gridsim.jit import compiled_kernels
    from gridsim.scenario.loader import builtin_scenarios

    t0 = time.perf_counter()
    before = compiled_kernels()
    names = list(builtin_scenarios())
    for name in names:
        report(f"  {name}")
        for action_type in ACTION_TYPES:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DataWarning)
                env = GridSimEnv(name, action_type=action_type)
                env.action_space.seed(0)
                _, info = env.reset(seed=0)
            for _ in range(STEPS):
                if action_type == "trajectory":
                    action = info["reference_setpoints"]
                else:
                    action = env.action_space.sample()
                _, _, terminated, truncated, info = env.step(action)
                if terminated or truncated:
                    _, info = env.reset(seed=1)
            fleet = env.world.traffic.fleet
            if fleet.active.any():  # the paths' look-ahead of a shadow human that gives way
                on = np.flatnonzero(fleet.active)[:1]  # (rare in a few steps; the same types)
                fleet.paths.frenet_to_world(fleet.path[on], fleet.s[on], fleet.d[on])
    # the C library's functions on float32 too (the trainer's kernels of the ego state)
    from gridsim import libm

    for dtype in (np.float64, np.float32):
        for function, arity in libm.ARITY.items():
            function(*[np.full(2, 0.5, dtype)] * arity)
    # the batched bicycle step (many vehicles: DWA's rollouts), which the envs do not take
    from gridsim.vehicle.kinematics import BicycleParams, step_bicycle

    step_bicycle(np.zeros((2, 5)), np.zeros(2), np.zeros(2), BicycleParams(), 0.1)
    # the trainer's: pooled grids and their first convolution, the destination curves of a
    # batch (its prior, the destination-curve baseline)
    from gridsim.sensors.occupancy_kernels import block_sums, pooled_convolution
    from gridsim.vehicle.curve_kernels import curves_many

    block_sums(np.zeros((1, 2, 2), np.uint8), 2, np.empty((1, 1, 1), np.float32))
    f32 = np.float32
    pooled_convolution(np.zeros((1, 2, 4, 4), np.uint8), 2, np.zeros((1, 1, 3, 3), f32),
                       np.zeros((1, 1), f32), 2, 1, np.empty((2, 1, 1, 1), f32))  # fmt: skip

    one = np.ones(2)
    curves_many(
        one, one, 0 * one, np.ones((2, 2)), one, 1.0, (1.0,) * 4, np.empty((2, 2, 2), np.float32)
    )
    after = compiled_kernels()
    return {"scenarios": len(names), "kernels": after["kernels"],
            "compiled": after["compiled"] - before["compiled"],
            "seconds": round(time.perf_counter() - t0, 1)}  # fmt: skip
