"""Picking and driving members of a trained Pareto front."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from gridsim.envs.gridsim_env import GridSimEnv
from neurotrajectory.evolution import minimised
from neurotrajectory.genome import set_genome
from neurotrajectory.model import NetConfig, TrajectoryNet, observation_tensors
from neurotrajectory.rollout import net_config_for
from neurotrajectory.train import Run, RunError

PICKS = ("knee", "best-l1", "best-l2", "best-l3")


def pick_member(fitness: np.ndarray, pick: str) -> int:
    """Index into the front: ``best-lK`` optimises one objective; ``knee`` is the member
    closest to the ideal point after scaling each (minimised) objective to [0, 1] over
    the front."""
    f = minimised(fitness)
    if pick == "knee":
        lo, hi = f.min(axis=0), f.max(axis=0)
        z = (f - lo) / np.where(hi > lo, hi - lo, 1.0)
        return int(np.argmin(np.hypot.reduce(z, axis=1)))
    if pick in PICKS:
        return int(np.argmin(f[:, PICKS.index(pick) - 1]))
    raise RunError(f"unknown pick {pick!r}; choose from {list(PICKS)}")


class NetPolicy:
    """A trained network as a GridSim-v0 policy (trajectory action)."""

    action_type = "trajectory"

    def __init__(self, net: TrajectoryNet) -> None:
        self.net = net.eval()

    @torch.no_grad()
    def __call__(self, env, obs, info):
        return self.net(*observation_tensors(obs))[0].numpy()


def load_front_member(run_dir: str | Path, pick: str) -> tuple[Run, NetPolicy, dict]:
    """The run, a policy for the chosen front member, and that member's fitness."""
    run = Run.open(run_dir)
    path = run.out / "front.npz"
    if not path.exists():
        raise RunError(f"{run.out}: no front.npz yet (the run has not finished)")
    with np.load(path) as data:
        genomes, fitness = data["genomes"], data["fitness"]
        base = NetConfig(**json.loads(str(data["net"])))
    k = pick_member(fitness, pick)
    env = GridSimEnv(run.config.scenario, **run.config.overrides)
    net = TrajectoryNet(net_config_for(env, base))
    set_genome(net, genomes[k])
    member = {
        "pick": pick,
        "l1": float(fitness[k, 0]),
        "l2": float(fitness[k, 1]),
        "l3": float(fitness[k, 2]),
    }
    return run, NetPolicy(net), member
