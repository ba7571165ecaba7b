"""Rolling networks out in GridSim-v0 and scoring them with the fitness vector.

An :class:`Evaluator` owns one environment per evaluation episode and one network; it runs
all episodes of a genome in lockstep, one batched forward pass per step.

**Early endings never pay.** An episode that ends by collision or off-road before its
``max_steps`` counts every remaining step at the worst per-step values: ``l1`` as if every
set-point were at the far corner of the action box from the reference
(``horizon * (2 * reach)^2`` with ``reach`` the box half-width, times sqrt 2 squared),
``l2`` at the steering-rate limit every tick and ``l3`` at 0. An episode that ends by
reaching its destination counts the remaining steps at the best values (0, 0, and ``v_max``
every tick): arriving early is a success. Fitness is the mean over episodes of the episode
sums ``[l1, l2, l3]`` (l1, l2 minimised, l3 maximised).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from gridsim.envs.gridsim_env import GridSimEnv
from neurotrajectory.genome import set_genome
from neurotrajectory.model import NetConfig, TrajectoryNet, observation_tensors


@dataclass
class EpisodeStats:
    steps: int = 0
    collisions: int = 0
    off_road: int = 0
    reached: int = 0
    extra: dict = field(default_factory=dict)


def net_config_for(env: GridSimEnv, base: NetConfig) -> NetConfig:
    """``base`` with the sizes the environment dictates (history, horizon, grid, period)."""
    cfg = env.cfg
    if cfg.sensor.rows != cfg.sensor.cols:
        raise ValueError(
            f"the network needs square grids, got {cfg.sensor.rows} x {cfg.sensor.cols}"
        )
    sizes = {
        "history": cfg.env.history,
        "horizon": cfg.env.horizon,
        "grid_size": cfg.sensor.rows,
        "setpoint_period": cfg.env.setpoint_period,
    }
    return NetConfig(**{**base.to_dict(), **sizes})


class Evaluator:
    """Evaluates genomes on a fixed list of episode seeds."""

    def __init__(
        self, scenario: str, overrides: dict, net_cfg: NetConfig, seeds: list[int]
    ) -> None:
        torch.set_num_threads(1)  # the same arithmetic in every process: bit-identical results
        self.envs = [GridSimEnv(scenario, **overrides) for _ in seeds]
        self.seeds = list(seeds)
        env = self.envs[0]
        self.net_cfg = net_config_for(env, net_cfg)
        self.net = TrajectoryNet(self.net_cfg).eval()
        cfg = env.cfg
        self.max_steps = int(round(cfg.simulation.duration / cfg.env.decision_period))
        reach = float(env.action_space.high.max())
        ticks = cfg.ticks_per_decision
        vmax = env.action_kind.params.v_max
        self.worst_step = np.array([cfg.env.horizon * 8.0 * reach**2,
                                    ticks * env.action_kind.params.v_delta_max, 0.0])  # fmt: skip
        self.best_step = np.array([0.0, 0.0, ticks * min(vmax, cfg.speed_range[1])])

    @torch.no_grad()
    def evaluate(self, genome: np.ndarray) -> tuple[np.ndarray, EpisodeStats]:
        """Mean episode fitness ``[l1, l2, l3]`` of ``genome`` and episode statistics."""
        set_genome(self.net, genome)
        n = len(self.envs)
        obs = [env.reset(seed=s)[0] for env, s in zip(self.envs, self.seeds, strict=True)]
        totals = np.zeros((n, 3))
        done_steps = np.zeros(n, int)
        live = list(range(n))
        stats = EpisodeStats()
        for _ in range(self.max_steps):
            if not live:
                break
            plans = self.net(*observation_tensors([obs[i] for i in live])).numpy()
            still = []
            for k, i in enumerate(live):
                obs[i], reward, terminated, truncated, info = self.envs[i].step(plans[k])
                totals[i] += reward
                done_steps[i] += 1
                stats.steps += 1
                if terminated:
                    remaining = self.max_steps - done_steps[i]
                    pad = self.best_step if info["destination_reached"] else self.worst_step
                    totals[i] += max(remaining, 0) * pad
                    stats.collisions += info["collision"]
                    stats.off_road += info["off_road"]
                    stats.reached += info["destination_reached"]
                elif not truncated:
                    still.append(i)
            live = still
        return totals.mean(axis=0), stats
