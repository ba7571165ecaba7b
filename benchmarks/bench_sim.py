"""Simulator speed: occupancy grid, world tick with 20 and with 1,000 vehicles, and on the
inner-city streets (cars on crossing routes, giving way to each other).

Prints one JSON object per line: medians (and 90th percentiles) in microseconds over
``--calls`` timed calls on one core, and the ratio to the target. Run:

    python benchmarks/bench_sim.py [--calls 2000]
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gridsim.scenario import build_sensor, build_world, load_scenario  # noqa: E402
from gridsim.world.scripted_drivers import LaneFollower  # noqa: E402

cv2.setNumThreads(1)


def timed(fn, calls: int) -> np.ndarray:
    out = np.empty(calls)
    for k in range(calls):
        t0 = time.perf_counter()
        fn(k)
        out[k] = time.perf_counter() - t0
    return out * 1e6


def report(name: str, us: np.ndarray, target_us: float | None = None, **extra) -> dict:
    row = {
        "bench": name,
        "median_us": round(float(np.median(us)), 1),
        "p90_us": round(float(np.percentile(us, 90)), 1),
        "calls": len(us),
    }
    if target_us is not None:
        row["target_us"] = target_us
        row["median_over_target"] = round(row["median_us"] / target_us, 2)
    row.update(extra)
    print(json.dumps(row), flush=True)
    return row


def world_with(participants: int, window: tuple[float, float], seed: int = 0):
    sc = load_scenario(
        "seamless", {"traffic": {"participants": participants, "window": list(window)}}
    )
    world = build_world(sc, seed)
    return sc, world


def bench_grid(calls: int) -> dict:
    """128 x 128 grid at 0.5 m with occlusion and 20 vehicles within range."""
    sc, world = world_with(20, (60.0, 60.0))
    sensor = build_sensor(sc)
    driver = LaneFollower(speed=10.0)
    for _ in range(50):
        world.tick(*driver(world))
    f = world.traffic.fleet
    in_range = int(np.sum(f.active & (np.hypot(f.x - world.ego[0], f.y - world.ego[1]) < 50)))
    return report(
        "occupancy_grid_128x128",
        timed(lambda k: sensor.observe(world), calls),
        500.0,
        vehicles_in_range=in_range,
    )


def bench_tick(world, calls: int, target_us: float | None, name: str) -> dict:
    driver = LaneFollower(speed=10.0)
    for _ in range(100):  # settle the spawn
        world.tick(*driver(world))
    controls = []
    durations = np.empty(calls)
    for k in range(calls):
        a, sr = driver(world)
        controls.append((a, sr))
        t0 = time.perf_counter()
        world.tick(a, sr)
        durations[k] = time.perf_counter() - t0
    active = int(world.traffic.fleet.active.sum())
    return report(name, durations * 1e6, target_us, vehicles=active)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=2000)
    args = ap.parse_args()
    bench_grid(args.calls)
    small = bench_tick(world_with(20, (80.0, 160.0))[1], args.calls, 200.0,
                       "world_tick_20_vehicles")  # fmt: skip
    big = bench_tick(world_with(1000, (4000.0, 4000.0))[1], args.calls, None,
                     "world_tick_1000_vehicles")  # fmt: skip
    # (at most 600 ticks: the lane follower leaves the city's streets after about 700)
    bench_tick(build_world(load_scenario("inner_city"), 0), min(args.calls, 600), None,
               "world_tick_inner_city")  # fmt: skip
    ratio = big["median_us"] / small["median_us"]
    print(
        json.dumps(
            {"bench": "tick_1000_over_tick_20", "ratio": round(ratio, 2), "target_ratio": 3.0}
        )
    )


if __name__ == "__main__":
    main()
