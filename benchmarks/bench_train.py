"""NeuroTrajectory rollout throughput: individual-steps per second (one network decision
plus one env step), default scenario, for a preset and backend.

    python benchmarks/bench_train.py [--preset default] [--backend processes] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import time

from neurotrajectory.backends import WorkerSpec, make_backend
from neurotrajectory.evolution import GAConfig, initial_recipes
from neurotrajectory.model import PRESETS


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="default", choices=sorted(PRESETS))
    ap.add_argument("--backend", default="processes", choices=["local", "processes", "ray"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--population", type=int, default=8)
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=10.0, help="episode length [s]")
    args = ap.parse_args()
    seeds = tuple(range(100, 100 + args.episodes))
    spec = WorkerSpec(
        "seamless", {"simulation": {"duration": args.seconds}}, PRESETS[args.preset], seeds
    )
    backend = make_backend(args.backend, spec, args.workers)
    try:
        backend.advance(initial_recipes(GAConfig(population=args.population), 0))
        backend.evaluate(args.population)  # warm-up: references cached, kernels loaded
        t0 = time.perf_counter()
        _, stats = backend.evaluate(args.population)
        seconds = time.perf_counter() - t0
    finally:
        backend.close()
    steps = sum(s["steps"] for s in stats)
    print(json.dumps({"bench": "individual_steps", "preset": args.preset, "backend": args.backend,
                      "workers": args.workers, "individual_steps": steps,
                      "individual_steps_per_s": round(steps / seconds, 1),
                      "target": 1000}))  # fmt: skip


if __name__ == "__main__":
    main()
