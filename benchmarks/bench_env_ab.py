"""Cached GridSim-v0 steps of two source trees, A/B in fine-grained alternation.

On a machine shared with other jobs, single runs of one tree vary by 20-40 %: the load
changes within seconds. This runs one worker process per tree (``PYTHONPATH`` set to the
tree), each warmed up on five seeds (their references cached, as in training), then hands
them blocks of steps in turn (A B, B A, ...) and compares the blocks' median CPU times per
step (``time.process_time``). Prints one JSON line: the medians of the block medians, the
median of the per-pair ratios (old / new) and its quartiles.

    python benchmarks/bench_env_ab.py OLD_TREE NEW_TREE [--blocks 40] [--steps 300]
        [--action trajectory|control] [--scenario inner_city]

``OLD_TREE``/``NEW_TREE``: folders holding a ``gridsim`` package (e.g. ``git worktree add``
or ``git archive <commit> | tar -x -C <dir>``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

WARMUP_STEPS = 3000  # five seeds of 600 steps: their references are then cached
SEEDS = 5


def worker(action_type: str, scenario: str) -> None:
    """Step on command: read a block size from stdin, print the block's median and mean CPU
    time per step [us]."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import cv2
    import gymnasium as gym
    import numpy as np

    import gridsim  # noqa: F401  (registers GridSim-v0)

    cv2.setNumThreads(1)
    env = gym.make("GridSim-v0", scenario=scenario, action_type=action_type)
    control = np.zeros(2, np.float32)
    _, info = env.reset(seed=0)
    state = {"info": info, "k": 1}

    def steps(n: int) -> list[float]:
        info, out = state["info"], []
        for _ in range(n):
            action = info["reference_setpoints"] if action_type == "trajectory" else control
            t0 = time.process_time()
            _, _, terminated, truncated, info = env.step(action)
            out.append(time.process_time() - t0)
            if terminated or truncated:
                _, info = env.reset(seed=state["k"] % SEEDS)
                state["k"] += 1
        state["info"] = info
        return out

    steps(WARMUP_STEPS)
    print("ready", flush=True)
    for line in sys.stdin:
        us = np.array(steps(int(line))) * 1e6
        print(json.dumps([float(np.median(us)), float(us.mean())]), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--blocks", type=int, default=40)
    ap.add_argument("--steps", type=int, default=300, help="steps per block")
    ap.add_argument("--action", default="trajectory", choices=["trajectory", "control"])
    ap.add_argument("--scenario", default="seamless", help="a scenario name or file")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.action, args.scenario)
        return
    procs = [
        subprocess.Popen(
            [
                sys.executable,
                __file__,
                "--worker",
                "--action",
                args.action,
                "--scenario",
                args.scenario,
                "_",
                "_",
            ],  # fmt: skip
            env={**os.environ, "PYTHONPATH": os.path.abspath(tree), "OMP_NUM_THREADS": "1"},
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        for tree in (args.old, args.new)
    ]
    for p in procs:
        if p.stdout.readline().strip() != "ready":
            raise SystemExit("a worker failed to start")
    medians: list[list[float]] = [[], []]
    for b in range(args.blocks):
        for i in (0, 1) if b % 2 == 0 else (1, 0):
            procs[i].stdin.write(f"{args.steps}\n")
            procs[i].stdin.flush()
            medians[i].append(json.loads(procs[i].stdout.readline())[0])
    for p in procs:
        p.stdin.close()
        p.wait()
    ratios = [a / b for a, b in zip(*medians, strict=True)]
    old, new = statistics.median(medians[0]), statistics.median(medians[1])
    print(json.dumps({
        "bench": f"env_step_{args.action}_cached_reference_ab",
        "scenario": args.scenario,
        "old_median_us": round(old, 1),
        "new_median_us": round(new, 1),
        "new_steps_per_s": round(1e6 / new),
        "median_ratio_old_over_new": round(statistics.median(ratios), 3),
        "ratio_quartiles": [round(q, 3) for q in statistics.quantiles(ratios, n=4)],
        "blocks": args.blocks,
        "steps_per_block": args.steps,
        "load": os.getloadavg()[0],
    }))  # fmt: skip


if __name__ == "__main__":
    main()
