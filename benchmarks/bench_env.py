"""GridSim-v0 speed: env.step throughput and reset time, one process, one core.

Prints JSON lines. ``step`` uses the default scenario (seamless) and observation (5 grids of
128 x 128) with the trajectory action fed from the reference set-points; the target is
:data:`TARGET_STEPS_PER_S` in steady state (the median step), on new seeds (each step also
advances the lazy human reference) and on seeds driven before (cached reference). ``reset``
is timed cold (a new seed: builds the world and the reference's first seconds) and warm (a
seed seen before: a copy of the kept world, the reference from the cache).

    python benchmarks/bench_env.py [--steps 3000] [--resets 10] [--cpu] [--lockstep-rounds 8]

``lockstep`` steps 32 environments together (16 individuals x 2 episodes, as a training
worker does, newest grid observed) one after the other and with
:func:`~gridsim.envs.gridsim_env.step_all` (each phase for all of them in turn), rounds
alternated, and prints both (us per environment step, medians of the rounds) and their ratio.

``--cpu`` times with ``time.process_time`` (CPU time of the process) instead of the wall
clock: steadier on a machine shared with other jobs.
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2  # noqa: E402
import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import gridsim  # noqa: E402, F401  (registers GridSim-v0)

cv2.setNumThreads(1)

TARGET_STEPS_PER_S = 2500.0


def _run(env, steps: int, action_type: str, seeds: list[int], clock) -> tuple[np.ndarray, float]:
    """Step durations [s] over ``steps`` steps, resetting with the next of ``seeds`` (cycled)
    whenever an episode ends, and the total wall time including the resets."""
    control = np.zeros(2, np.float32)
    obs, info = env.reset(seed=seeds[0])
    durations, k = [], 1
    t_start = time.perf_counter()
    for _ in range(steps):
        action = info["reference_setpoints"] if action_type == "trajectory" else control
        t0 = clock()
        obs, r, term, trunc, info = env.step(action)
        durations.append(clock() - t0)
        if term or trunc:
            obs, info = env.reset(seed=seeds[k % len(seeds)])
            k += 1
    return np.array(durations), time.perf_counter() - t_start


def bench_steps(steps: int, action_type: str, cached_reference: bool, clock) -> dict:
    """Steps on the default scenario. A step on a new seed also advances that seed's human
    reference by a tick (:mod:`gridsim.envs.human_reference`); with ``cached_reference`` the same
    seeds were driven once before, as when a population shares its episode seeds, so only
    the step itself is timed."""
    env = gym.make("GridSim-v0", action_type=action_type)
    seeds = list(range(100))
    if cached_reference:
        _run(env, steps, action_type, seeds, clock)
    durations, total = _run(env, steps, action_type, seeds, clock)
    us = durations * 1e6
    row = {
        "bench": f"env_step_{action_type}" + ("_cached_reference" if cached_reference else ""),
        "steps_per_s": round(len(us) / (us.sum() / 1e6), 1),
        "median_us": round(float(np.median(us)), 1),
        "median_steps_per_s": round(1e6 / float(np.median(us)), 1),
        "p90_us": round(float(np.percentile(us, 90)), 1),
        "steps": steps,
        "wall_s_including_resets": round(total, 2),
        "target_steps_per_s": TARGET_STEPS_PER_S,
    }
    row["median_over_target"] = round(row["median_steps_per_s"] / TARGET_STEPS_PER_S, 2)
    print(json.dumps(row), flush=True)
    return row


def bench_reset(n: int, clock) -> None:
    env = gym.make("GridSim-v0")
    cold, warm = [], []
    for seed in range(n):
        t0 = clock()
        env.reset(seed=1000 + seed)
        cold.append(clock() - t0)
    for seed in range(n):
        t0 = clock()
        env.reset(seed=1000 + seed)
        warm.append(clock() - t0)
    row = {
        "bench": "env_reset",
        "cold_median_ms": round(1e3 * float(np.median(cold)), 1),
        "warm_median_ms": round(1e3 * float(np.median(warm)), 1),
        "target_cold_ms": 5.0,
        "target_warm_ms": 2.0,
        "resets": n,
        "episode_s": 60.0,
    }
    print(json.dumps(row))


def bench_lockstep(rounds: int, clock, envs_n: int = 32, decisions: int = 150) -> None:
    from gridsim.envs.gridsim_env import GridSimEnv, step_all

    envs = [GridSimEnv("seamless", observation_type="grid") for _ in range(envs_n)]
    seeds = [1000 + k % 2 for k in range(envs_n)]  # 2 episodes each, as in training

    def run(together: bool) -> float:
        infos = [env.reset(seed=s)[1] for env, s in zip(envs, seeds, strict=True)]
        live, spent, steps = list(range(envs_n)), 0.0, 0
        for _ in range(decisions):
            if not live:
                break
            actions = [infos[k]["reference_setpoints"] for k in live]
            t = clock()
            if together:
                out = step_all([envs[k] for k in live], actions)
            else:
                out = [envs[k].step(a) for k, a in zip(live, actions, strict=True)]
            spent += clock() - t
            steps += len(live)
            for k, (*_, info) in zip(live, out, strict=True):
                infos[k] = info
            live = [k for k, o in zip(live, out, strict=True) if not (o[2] or o[3])]
        return 1e6 * spent / steps

    run(False), run(True)  # warm-up
    times: dict[bool, list[float]] = {False: [], True: []}
    for _ in range(rounds):
        for together in (False, True):
            times[together].append(run(together))
    one, phased = (float(np.median(times[k])) for k in (False, True))
    print(json.dumps({"bench": "lockstep_32_envs", "one_after_another_us": round(one, 1),
                      "step_all_us": round(phased, 1), "ratio": round(one / phased, 3),
                      "rounds": rounds, "loadavg": os.getloadavg()[0]}))  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--resets", type=int, default=10)
    ap.add_argument("--cpu", action="store_true", help="time CPU, not wall-clock, time")
    ap.add_argument("--lockstep-rounds", type=int, default=8)
    args = ap.parse_args()
    clock = time.process_time if args.cpu else time.perf_counter
    for cached in (False, True):
        bench_steps(args.steps, "trajectory", cached, clock)
        bench_steps(args.steps, "control", cached, clock)
    bench_reset(args.resets, clock)
    bench_lockstep(args.lockstep_rounds, clock)


if __name__ == "__main__":
    main()
