"""Rolling networks out in GridSim-v0 and scoring them with the fitness vector.

An :class:`Evaluator` runs the evaluation episodes of a batch of individuals in lockstep,
one batched forward pass (each individual with its own weights) per step.

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

from dataclasses import astuple, dataclass, field

import numpy as np
import torch

from gridsim.envs.gridsim_env import GridSimEnv, step_all
from gridsim.envs.plan_smoothing import PlanSmoother
from gridsim.scenario.collection import load_collection
from gridsim.scenario.parts import vehicle_params
from gridsim.scenario.schema import ScenarioConfig
from neurotrajectory.curves import CurveLimits
from neurotrajectory.model import NetConfig, PopulationNet, TrajectoryNet


@dataclass
class EpisodeStats:
    """An individual's episodes: steps driven, how they ended, and ``lost``: the mean share of
    an episode's steps lost to collisions and leaving the road (its constraint violation)."""

    steps: int = 0
    collisions: int = 0
    off_road: int = 0
    reached: int = 0
    lost: float = 0.0
    extra: dict = field(default_factory=dict)


def net_config_for(cfg: ScenarioConfig, base: NetConfig) -> NetConfig:
    """``base`` with the sizes and limits a scenario dictates (history, horizon, grid, period,
    the ego's limits, the goal time); no environment is built."""
    if cfg.sensor.rows != cfg.sensor.cols:
        raise ValueError(
            f"the network needs square grids, got {cfg.sensor.rows} x {cfg.sensor.cols}"
        )
    sizes = {
        "history": cfg.env.history,
        "horizon": cfg.env.horizon,
        "grid_size": cfg.sensor.rows,
        "setpoint_period": cfg.env.setpoint_period,
        "limits": astuple(CurveLimits.from_params(vehicle_params(cfg.ego.vehicle))),
        "goal_seconds": cfg.env.goal_seconds,
    }
    return NetConfig(**{**base.to_dict(), **sizes})


def scenario_net_config(scenario: str, overrides: dict, base: NetConfig) -> NetConfig:
    """:func:`net_config_for` the scenario ``scenario`` (name or path; of a collection, its
    first file) with ``overrides``."""
    return net_config_for(load_collection(scenario, overrides)[0].config, base)


class Evaluator:
    """Evaluates genomes on a fixed list of episode seeds, ``batch`` individuals at a time.

    The ``E`` episodes of each of up to ``batch`` individuals (``batch * E`` environments) are
    stepped in lockstep, with one :class:`~neurotrajectory.model.PopulationNet` forward pass
    per step for all individuals that still have a running episode. An individual's fitness
    does not depend on the batch it is evaluated in (see :mod:`neurotrajectory.model`).

    The CNN features of a frame, and their product with ``fc1``, are computed once, when the
    frame is the newest one, and kept per environment while it moves back through the
    history: the environments then observe the newest grid only (``observation_type="grid"``;
    after a reset the history is its first grid repeated). ``cache=False`` observes the whole
    history (``"grids"``) and recomputes every frame every step; the result is the same.
    """

    def __init__(
        self,
        scenario: str,
        overrides: dict,
        net_cfg: NetConfig,
        seeds: list[int],
        batch: int = 16,
        cache: bool = True,
    ) -> None:
        torch.set_num_threads(1)  # the same arithmetic in every process: bit-identical results
        if batch < 1:
            raise ValueError(f"batch must be >= 1, got {batch}")
        self.scenario, self.overrides = scenario, overrides
        self.seeds = list(seeds)
        self.batch, self.cache = batch, cache
        self._envs: dict[bool, list[GridSimEnv]] = {True: [], False: []}  # by ``cache``
        env = self._env_grid(1, max(len(seeds), 1))[0][0]
        self.net_cfg = net_config_for(env.cfg, net_cfg)
        self.net = TrajectoryNet(self.net_cfg).eval()  # the parameter layout of a genome
        self.pop_net = PopulationNet(self.net_cfg)
        cfg = env.cfg
        self.max_steps = cfg.episode_decisions
        reach = float(env.action_space.high.max())
        ticks = cfg.ticks_per_decision
        vmax = env.action_kind.params.v_max
        self.worst_step = np.array([cfg.env.horizon * 8.0 * reach**2,
                                    ticks * env.action_kind.params.v_delta_max, 0.0])  # fmt: skip
        self.best_step = np.array([0.0, 0.0, ticks * min(vmax, cfg.speed_range[1])])

    @property
    def envs(self) -> list[GridSimEnv]:
        """The environments made so far for the current ``cache`` setting."""
        return self._envs[self.cache]

    def _env_grid(self, k: int, e: int) -> list[list[GridSimEnv]]:
        """Environments for ``k`` individuals of ``e`` episodes each (created on first use):
        with the frame cache, observing the newest grid only (the cache holds the history)."""
        envs = self._envs[self.cache]
        while len(envs) < k * e:
            kind = "grid" if self.cache else "grids"
            envs.append(GridSimEnv(self.scenario, observation_type=kind, **self.overrides))
        return [envs[i * e : (i + 1) * e] for i in range(k)]

    def evaluate(self, genome: np.ndarray, seeds=None) -> tuple[np.ndarray, EpisodeStats]:
        """Mean episode fitness ``[l1, l2, l3]`` of ``genome`` and episode statistics, on
        ``seeds`` (default: the evaluator's)."""
        return self.evaluate_many(np.asarray(genome, dtype=np.float32)[None], seeds)[0]

    def evaluate_many(self, population, seeds=None) -> list[tuple[np.ndarray, EpisodeStats]]:
        """:meth:`evaluate` for every row of ``population`` ``(K, n)`` float32, ``batch`` rows at
        a time, on the episodes ``seeds`` (default: the evaluator's). Rows already in 64-byte
        aligned storage (see :func:`~neurotrajectory.model.aligned_rows`; strided views of it
        too) are used in place, others are copied once."""
        seeds = self.seeds if seeds is None else [int(s) for s in seeds]
        if not seeds:
            raise ValueError("need at least one episode seed")
        store = self.pop_net.store(population)
        out = []
        for start in range(0, store.shape[0], self.batch):
            out.extend(self._evaluate_batch(store[start : start + self.batch], seeds))
        return out

    @torch.no_grad()
    def _evaluate_batch(self, store: torch.Tensor, seeds: list[int]):
        net = self.pop_net
        k_all, e, t = store.shape[0], len(seeds), self.net_cfg.history
        small = net.small_copy(store)
        envs = self._env_grid(k_all, e)
        obs = [[env.reset(seed=s)[0] for env, s in zip(row, seeds, strict=True)]
               for row in envs]  # fmt: skip
        # after a reset every frame of the history is the first grid; each step adds one
        reset = np.ones((k_all, e), bool)
        keep = self.net_cfg.smoothing  # one plan smoother per environment, if any
        smoothers = [[PlanSmoother(keep) for _ in range(e)] for _ in range(k_all)] if keep else None
        grid = torch.zeros(k_all, e, t, self.net_cfg.fc1)  # fc1 x CNN features, per frame
        totals = np.zeros((k_all, e, 3))
        done_steps = np.zeros((k_all, e), int)
        live = np.ones((k_all, e), bool)
        stats = [EpisodeStats() for _ in range(k_all)]
        rows, params = None, None
        for _ in range(self.max_steps):
            active = np.flatnonzero(live.any(axis=1))
            if len(active) == 0:
                break
            if rows is None or not np.array_equal(rows, active):
                rows, params = active, net.params(store, small, active)
            # every environment of every running individual, always: fixed shapes
            if self.cache:  # the newest frame's features, into each running episode's cache
                frames = np.stack([[o["grid"] for o in obs[k]] for k in rows])
                new = net.grid_part(params, net.frame_features(params, frames))
                a, j = np.nonzero(live[rows])  # running episodes: batch row a, episode j
                k, fresh = rows[a], reset[rows[a], j]
                if (~fresh).any():  # one new frame at the end of the history
                    ka, ja, aa = (torch.from_numpy(v[~fresh]) for v in (k, j, a))
                    grid[ka, ja] = torch.cat([grid[ka, ja, 1:], new[aa, ja][:, None]], dim=1)
                if fresh.any():  # just reset: every frame of the history is this one
                    ka, ja, aa = (torch.from_numpy(v[fresh]) for v in (k, j, a))
                    grid[ka, ja] = new[aa, ja][:, None].expand(-1, t, -1)
                reset[k, j] = False
            else:  # every frame of the history, every step
                for slot in range(t):
                    frames = np.stack([[o["grids"][slot] for o in obs[k]] for k in rows])
                    grid[rows, :, slot] = net.grid_part(params, net.frame_features(params, frames))
            ego = torch.from_numpy(
                np.array([[o["ego"] for o in obs[k]] for k in rows], dtype=np.float32)
            )
            dest = torch.from_numpy(
                np.array([[o["destination"] for o in obs[k]] for k in rows], dtype=np.float32)
            )
            plans = net.head(params, grid[rows], ego, dest).numpy()
            moves = []  # every running episode (k, j) and its plan, in order
            for a, k in enumerate(rows):
                for j in np.flatnonzero(live[k]):
                    plan = plans[a, j]
                    if smoothers is not None:
                        plan = smoothers[k][j](envs[k][j], plan)
                    moves.append((k, j, plan))
            # each phase of the step for every environment in turn (the same results as one
            # environment after another; the tables they share stay in cache)
            stepped = step_all([envs[k][j] for k, j, _ in moves], [p for _, _, p in moves])
            for (k, j, _), result in zip(moves, stepped, strict=True):
                obs[k][j], reward, terminated, truncated, info = result
                totals[k, j] += reward
                done_steps[k, j] += 1
                stats[k].steps += 1
                if terminated:
                    remaining = self.max_steps - done_steps[k, j]
                    pad = self.best_step if info["destination_reached"] else self.worst_step
                    totals[k, j] += max(remaining, 0) * pad
                    if not info["destination_reached"]:
                        stats[k].lost += max(remaining, 0) / (self.max_steps * e)
                    stats[k].collisions += info["collision"]
                    stats[k].off_road += info["off_road"]
                    stats[k].reached += info["destination_reached"]
                if terminated or truncated:
                    live[k, j] = False
        return [(totals[k].mean(axis=0), stats[k]) for k in range(k_all)]
