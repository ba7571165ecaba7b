"""NeuroTrajectory rollout throughput: individual-steps per second (one network decision
plus one env step) on a scenario (seamless unless ``--scenario``), for a preset and backend.

    python benchmarks/bench_train.py [--preset default] [--backend processes] [--workers 2]
        [--population 32] [--batch 16] [--rounds 5] [--scenario inner_city]

Targets (population 32, ``--backend processes --workers 2``, 2 cores): ``default`` 6,000
(issue 25; 1,500 before), ``paper`` 300 individual-steps/s, on seamless; ``ratio`` is the
measured rate over the target (none on other scenarios). ``individual_steps_per_cpu_s``:
the same steps per CPU-second of the processes that evaluate (all workers together;
steadier than the wall clock when other jobs share the machine; with 2 idle cores the
wall-clock rate is about twice it).
``big_weights_gb_per_s``: how fast the rollouts stream the parameters too big to stay in a
cache (each individual's copy is read once per decision, for all its episodes at once; a lower
bound, counted as if no episode ended early): the ``paper`` preset is bound by memory
bandwidth, not arithmetic.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import time

from neurotrajectory.evolve.backends import WorkerSpec, make_backend
from neurotrajectory.evolve.evolution import GAConfig, initial_recipes
from neurotrajectory.model import PRESETS, PopulationNet

TARGETS = {"default": 6000.0, "paper": 300.0, "tiny": 6000.0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="default", choices=sorted(PRESETS))
    ap.add_argument("--scenario", default="seamless", help="a scenario name or file")
    ap.add_argument("--backend", default="processes", choices=["local", "processes", "ray"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--population", type=int, default=32)
    ap.add_argument("--batch", type=int, default=16, help="individuals per worker batch")
    ap.add_argument("--episodes", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=10.0, help="episode length [s]")
    ap.add_argument("--rounds", type=int, default=5, help="timed evaluations (median reported)")
    args = ap.parse_args()
    seeds = tuple(range(100, 100 + args.episodes))
    spec = WorkerSpec(
        args.scenario,
        {"simulation": {"duration": args.seconds}},
        PRESETS[args.preset],
        seeds,
        batch=args.batch,
    )
    backend = make_backend(args.backend, spec, args.workers)
    try:
        backend.advance(initial_recipes(GAConfig(population=args.population), 0))
        backend.evaluate(args.population, spec.seeds)  # warm-up: references cached, kernels loaded
        rates, per_cpu_s = [], []
        for _ in range(args.rounds):
            t0, c0 = time.perf_counter(), _cpu_seconds(backend)
            _, stats = backend.evaluate(args.population, spec.seeds)
            done = sum(s["steps"] for s in stats)
            rates.append(done / (time.perf_counter() - t0))
            per_cpu_s.append(done / (_cpu_seconds(backend) - c0))
    finally:
        backend.close()
    steps = sum(s["steps"] for s in stats)
    rate = statistics.median(rates)
    target = TARGETS[args.preset] if args.scenario == "seamless" else None
    pop_net = PopulationNet(spec.net)
    big_bytes = 4 * sum(
        math.prod(shape) for name, shape in pop_net.shapes.items() if name not in pop_net.small
    )
    # one forward per individual covers all its episodes (fewer once some have ended)
    streamed = big_bytes * rate / args.episodes / 1e9
    print(json.dumps({"bench": "individual_steps", "preset": args.preset,
                      "scenario": args.scenario, "backend": args.backend,
                      "workers": args.workers, "population": args.population,
                      "batch": args.batch, "individual_steps": steps,
                      "individual_steps_per_s": round(rate, 1),
                      "rounds_min_max": [round(min(rates), 1), round(max(rates), 1)],
                      "individual_steps_per_cpu_s": round(statistics.median(per_cpu_s), 1),
                      "loadavg_1min": os.getloadavg()[0], "target": target,
                      "ratio": round(rate / target, 2) if target else None,
                      "big_weights_mb": round(big_bytes / 1e6, 1),
                      "big_weights_gb_per_s": round(streamed, 2)}))  # fmt: skip


def _cpu_seconds(backend) -> float:
    """CPU time [s] used so far by the processes that evaluate: the worker processes of the
    ``processes`` backend (``/proc/PID/stat``), else this one. Steadier than the wall clock
    on a machine shared with other jobs (Ray's actors are not counted: this process's)."""
    procs = getattr(backend, "procs", None)
    if not procs:
        return time.process_time()
    tick = os.sysconf("SC_CLK_TCK")
    total = 0
    for proc in procs:
        with open(f"/proc/{proc.pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        total += int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15)
    return total / tick


if __name__ == "__main__":
    main()
