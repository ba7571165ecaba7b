"""GridSim-v0 against highway-env's highway-fast-v0: simulated seconds per CPU-second.

Both envs observe an occupancy grid of the same cells (128 x 128 cells of 0.5 m, 64 m x 64 m
around the ego, axes aligned with the world), run as vector envs of ``--num-envs`` each
(``gym.make_vec``: GridSim-v0's own, which steps its worlds phase by phase, and gymnasium's
``SyncVectorEnv`` for highway-env; 1: one env each in such a vector), take random actions from
their own (seeded) batch action spaces and reset an env in the step its episode ends
(``SAME_STEP`` autoreset), resets included in the time. They run alternately in one process
(GridSim, highway, GridSim, highway, ...), each for a fixed budget of CPU seconds per round,
so that drift in machine speed hits both. Simulated seconds are env-steps x decision period
for GridSim-v0 (0.1 s) and env-steps / policy_frequency for highway-env (1 Hz in
highway-fast-v0, with 5 simulation ticks per step).

Prints JSON lines: the highway-env config used, one line per env per round (with the load),
one summary per env (median simulated s per CPU-s over rounds, env-steps/s, episodes ended,
mean episode length, how they ended) and the ratio GridSim / highway (median of the per-round
ratios) with the target (12x, issue 25; 5x before) and the long-term aim (20x).

highway-env is a benchmark-only extra (it pulls in pygame; nothing is rendered and SDL is set
to its dummy video driver):

    pip install ".[bench]"
    python benchmarks/bench_vs_highway.py [--rounds 5] [--seconds-per-round 10] [--seed 0]
        [--num-envs 16]
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("NUMEXPR_NUM_THREADS", "1")
# highway-env imports pygame: never open a window or an audio device.
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")

import cv2  # noqa: E402
import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import gridsim  # noqa: E402, F401  (registers GridSim-v0)

try:
    import highway_env  # noqa: F401  (registers highway-fast-v0)
except ImportError as exc:  # pragma: no cover - depends on the optional extra
    raise SystemExit(
        'highway-env is not installed: pip install ".[bench]" (benchmark-only extra)'
    ) from exc

cv2.setNumThreads(1)

TARGET_RATIO = 12.0
AIM_RATIO = 20.0
HIGHWAY_ID = "highway-fast-v0"


def highway_config(features: list[str], cells: int, cell: float) -> dict:
    """Occupancy grid of the same cells as GridSim-v0's sensor; everything else as
    highway-fast-v0 defines it (simulation 5 Hz, policy 1 Hz, 3 lanes, 20 vehicles, 30 s)."""
    half = cells * cell / 2
    return {
        "observation": {
            "type": "OccupancyGrid",
            "features": features,
            "grid_size": [[-half, half], [-half, half]],
            "grid_step": [cell, cell],
            "absolute": False,  # ego-centred (highway-env has no absolute mode)
            "align_to_vehicle_axes": False,  # world axes, as GridSim's north_up grid
            "clip": True,
            "as_image": False,
        },
    }


class Runner:
    """A vector of ``num_envs`` envs driven by seeded random actions (one draw of the batch
    action space a step), reset in the same step when an episode ends (``SAME_STEP``
    autoreset: every env-step simulates a decision period); counts env-steps, episode ends
    and CPU/wall time."""

    def __init__(self, name: str, env: gym.vector.VectorEnv, decision_period: float,
                 seed: int) -> None:  # fmt: skip
        self.name = name
        self.env = env
        self.dt = decision_period
        env.action_space.seed(seed)
        self.env.reset(seed=seed)  # first reset (imports, caches) outside the timings
        self.ep_steps = np.zeros(env.num_envs, int)
        self.episode_lengths: list[int] = []
        self.end_reasons: dict[str, int] = {}
        self.total = {"steps": 0, "cpu_s": 0.0, "wall_s": 0.0}

    def _count_ends(self, terminated: np.ndarray, truncated: np.ndarray, info: dict) -> None:
        final = info.get("final_info", {})
        for i in np.flatnonzero(terminated | truncated):
            self.episode_lengths.append(int(self.ep_steps[i]))
            reason = "truncated"
            if terminated[i]:
                reason = next((key for key in ("crashed", "collision", "off_road",
                                               "destination_reached")
                               if key in final and final[key][i]), "terminated")  # fmt: skip
            self.end_reasons[reason] = self.end_reasons.get(reason, 0) + 1
            self.ep_steps[i] = 0

    def run(self, cpu_budget: float) -> dict:
        env, sample, n = self.env, self.env.action_space.sample, self.env.num_envs
        steps, ended_before = 0, len(self.episode_lengths)
        c0, w0 = time.process_time(), time.perf_counter()
        now = c0
        while now - c0 < cpu_budget:
            _, _, terminated, truncated, info = env.step(sample())
            steps += n
            self.ep_steps += 1
            if terminated.any() or truncated.any():
                self._count_ends(terminated, truncated, info)
            now = time.process_time()
        cpu, wall = now - c0, time.perf_counter() - w0
        for key, value in (("steps", steps), ("cpu_s", cpu), ("wall_s", wall)):
            self.total[key] += value
        sim = steps * self.dt
        return {
            "env": self.name,
            "sim_s": round(sim, 2),
            "cpu_s": round(cpu, 3),
            "wall_s": round(wall, 3),
            "sim_s_per_cpu_s": sim / cpu,
            "sim_s_per_wall_s": sim / wall,
            "steps": steps,
            "episodes_ended": len(self.episode_lengths) - ended_before,
            "loadavg": os.getloadavg()[0],
        }


def summary(runner: Runner, rows: list[dict]) -> dict:
    t = runner.total
    lengths = runner.episode_lengths
    return {
        "bench": "summary",
        "env": runner.name,
        "num_envs": runner.env.num_envs,
        "decision_period_s": runner.dt,
        "sim_s_per_cpu_s_median": round(float(np.median([r["sim_s_per_cpu_s"] for r in rows])), 2),
        "sim_s_per_wall_s_median": round(
            float(np.median([r["sim_s_per_wall_s"] for r in rows])), 2
        ),
        "steps_per_cpu_s": round(t["steps"] / t["cpu_s"], 1),
        "steps": t["steps"],
        "episodes_ended": len(lengths),
        "mean_episode_steps": round(float(np.mean(lengths)), 1) if lengths else None,
        "mean_episode_sim_s": round(float(np.mean(lengths)) * runner.dt, 2) if lengths else None,
        "episode_ends": runner.end_reasons,
        "loadavg": [r["loadavg"] for r in rows],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--seconds-per-round", type=float, default=10.0,
                    help="CPU seconds per env per round")  # fmt: skip
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--num-envs", type=int, default=16,
                    help="envs per vector env (both simulators); 1: a single env each")  # fmt: skip
    ap.add_argument(
        "--highway-features",
        default="presence",
        help="comma-separated OccupancyGrid features, e.g. presence,on_road",
    )
    args = ap.parse_args()

    n = args.num_envs
    gs_env = gym.make("GridSim-v0")
    cfg = gs_env.unwrapped.cfg
    sensor = cfg.sensor
    gs_dt = cfg.env.decision_period
    hw_cfg = highway_config(args.highway_features.split(","), sensor.rows, sensor.cell_size)
    hw_env = gym.make(HIGHWAY_ID, config=hw_cfg)
    hw_env.reset(seed=args.seed)  # the config is applied on reset
    hw_full = hw_env.unwrapped.config
    hw_dt = 1.0 / hw_full["policy_frequency"]
    print(json.dumps({
        "bench": "config",
        "gridsim": {
            "id": "GridSim-v0",
            "scenario": cfg.name,
            "grid": [cfg.env.history, sensor.rows, sensor.cols],
            "cell_m": sensor.cell_size,
            "orientation": sensor.orientation,
            "decision_period_s": gs_dt,
            "dt_s": cfg.simulation.dt,
            "episode_s": cfg.simulation.duration,
            "action_space": str(gs_env.action_space),
        },
        "highway": {
            "id": HIGHWAY_ID,
            "version": highway_env.__version__,
            "config_passed": hw_cfg,
            "observation_shape": list(hw_env.observation_space.shape),
            "action_space": str(hw_env.action_space),
            **{k: hw_full[k] for k in ("policy_frequency", "simulation_frequency", "duration",
                                       "lanes_count", "vehicles_count", "action")},
        },
        "num_envs": n,
        "vector_envs": "GridSim-v0: its own (MOSyncVectorEnv, steps phase by phase); "
                       f"{HIGHWAY_ID}: gymnasium's SyncVectorEnv; both SAME_STEP autoreset",
        "rounds": args.rounds,
        "cpu_s_per_env_per_round": args.seconds_per_round,
        "seed": args.seed,
    }), flush=True)  # fmt: skip

    same_step = gym.vector.AutoresetMode.SAME_STEP
    runners = [
        Runner("GridSim-v0", gym.make_vec("GridSim-v0", n, autoreset_mode=same_step), gs_dt,
               args.seed),
        Runner(HIGHWAY_ID, gym.make_vec(HIGHWAY_ID, n, vectorization_mode="sync",
                                        vector_kwargs={"autoreset_mode": same_step},
                                        config=hw_cfg), hw_dt, args.seed),
    ]  # fmt: skip
    rows: dict[str, list[dict]] = {r.name: [] for r in runners}
    ratios = []
    for rnd in range(args.rounds):
        per = {}
        for runner in runners:
            row = runner.run(args.seconds_per_round)
            per[runner.name] = row
            rows[runner.name].append(row)
            out = {**row, "bench": "round", "round": rnd}
            out["sim_s_per_cpu_s"] = round(row["sim_s_per_cpu_s"], 2)
            out["sim_s_per_wall_s"] = round(row["sim_s_per_wall_s"], 2)
            print(json.dumps(out), flush=True)
        ratios.append(per["GridSim-v0"]["sim_s_per_cpu_s"] / per[HIGHWAY_ID]["sim_s_per_cpu_s"])

    for runner in runners:
        print(json.dumps(summary(runner, rows[runner.name])), flush=True)
    ratio = float(np.median(ratios))
    print(json.dumps({
        "bench": "ratio_gridsim_over_highway",
        "sim_s_per_cpu_s_ratio_median": round(ratio, 3),
        "per_round": [round(r, 3) for r in ratios],
        "target": TARGET_RATIO,
        "aim": AIM_RATIO,
        "meets_target": ratio >= TARGET_RATIO,
    }), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
