"""``gridsim run``: drive a built-in policy in GridSim-v0 and summarise the episode."""

from __future__ import annotations

import numpy as np
from tqdm import tqdm

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.errors import GridSimError
from gridsim.policies import POLICIES
from gridsim.video import record_rollout


def run_policy(
    scenario: str,
    policy: str,
    steps: int,
    seed: int = 0,
    video: str | None = None,
    progress: bool = True,
    overlay: bool = False,
) -> dict:
    """Run ``policy`` for up to ``steps`` decisions; optionally write a video. Returns a
    summary: distance driven, collisions, off-road, fitness sums and the episode outcome."""
    if policy not in POLICIES:
        raise GridSimError(f"unknown policy {policy!r}; choose from {sorted(POLICIES)}")
    if steps < 1:
        raise GridSimError(f"--steps must be >= 1, got {steps}")
    pol = POLICIES[policy]()
    env = GridSimEnv(
        scenario, render_mode="rgb_array" if video else None, action_type=pol.action_type
    )
    env.action_space.seed(seed)
    bar = tqdm(
        total=steps, desc=f"{policy} on {env.scenario.name}", unit="step", disable=not progress
    )
    path, infos = record_rollout(env, pol, video, steps, seed, on_step=lambda _: bar.update(),
                                 overlay=overlay)  # fmt: skip
    bar.close()
    poses = np.array([i["pose"][:2] for i in infos])
    fitness = np.sum([i["reward"] for i in infos], axis=0) if infos else np.zeros(3)
    last = infos[-1] if infos else {}
    summary = {
        "scenario": env.scenario.name,
        "policy": policy,
        "seed": seed,
        "steps": len(infos),
        "simulated_s": round(float(last.get("time", 0.0)), 3),
        "distance_m": round(float(np.sum(np.hypot(*np.diff(poses, axis=0).T))), 2)
        if len(poses) > 1
        else 0.0,
        "collision": bool(last.get("collision", False)),
        "off_road": bool(last.get("off_road", False)),
        "destination_reached": bool(last.get("destination_reached", False)),
        "fitness_sums": {"l1": float(fitness[0]), "l2": float(fitness[1]), "l3": float(fitness[2])},
    }
    if path is not None:
        summary["video"] = str(path)
    return summary
