"""``gridsim run``: drive a built-in policy in GridSim-v0 and summarise the episode."""

from __future__ import annotations

from tqdm import tqdm

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.errors import GridSimError
from gridsim.policies import POLICIES
from gridsim.video import record_episode


def run_policy(
    scenario: str,
    policy: str,
    steps: int,
    seed: int = 0,
    video: str | None = None,
    progress: bool = True,
    overlay: bool = True,
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
    episode, path = record_episode(env, pol, video, steps, seed,
                                   on_step=lambda *_: bar.update(), overlay=overlay,
                                   label=f"{policy} policy, {env.scenario.name}")  # fmt: skip
    bar.close()
    s = episode.summary()
    summary = {"scenario": env.scenario.name, "policy": policy, "seed": seed, **s,
               "simulated_s": round(s["simulated_s"], 3),
               "distance_m": round(s["distance_m"], 2)}  # fmt: skip
    if path is not None:
        summary["video"] = str(path)
    return summary
