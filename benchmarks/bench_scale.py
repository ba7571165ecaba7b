"""Large recorded scenes: time and memory to load a CommonRoad scene of many vehicles.

Writes a synthetic CommonRoad 2020a scene per size (a straight six-lane road of 1 km; vehicles
enter in waves of 60, ten per lane 90 m apart, each recorded for 5 s at 0.1 s, the layout of
the NGSIM files but many more of them), then, each in a fresh process:

- ``read``: parse the file into tracks;
- ``make_reset``: ``gym.make("GridSim-v0", scenario=FILE)`` and ``reset(seed=0)``;
- ``validate``: the plausibility checks of ``gridsim validate``;
- ``record`` (only when asked, ``--phases record``: minutes at thousands of vehicles):
  ``neurotrajectory record`` of the scene (every track driven once as the ego, a window
  every 0.1 s) into a dataset folder;

and prints seconds and peak memory above the imports (MB) per phase, and the ratio of each
figure to the smallest scene's scaled by the vehicle count (1.0: linear).

    python benchmarks/bench_scale.py [--vehicles 500 1000 5000] [--dir /tmp/scale]

Target (issue 26): 5,000 vehicles make and reset in <= 10 s on one core.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

LANES, LANE_WIDTH, LENGTH, WAVE, GAP, STATES, DT = 6, 3.5, 1000.0, 60, 90.0, 50, 0.1


def _bound(y: float) -> str:
    pts = "".join(f"<point><x>{x:.1f}</x><y>{y:.2f}</y></point>" for x in (0.0, LENGTH / 2, LENGTH))
    return pts


def _state(tag: str, step: int, x: float, y: float, v: float) -> str:
    return (f"<{tag}><position><point><x>{x:.3f}</x><y>{y:.3f}</y></point></position>"
            f"<orientation><exact>0.0</exact></orientation><time><exact>{step}</exact></time>"
            f"<velocity><exact>{v:.3f}</exact></velocity></{tag}>")  # fmt: skip


def write_scene(path: Path, vehicles: int) -> Path:
    """A synthetic scene of ``vehicles`` recorded cars (deterministic, no overlaps)."""
    out = ['<?xml version="1.0" ?>',
           f'<commonRoad timeStepSize="{DT}" commonRoadVersion="2020a" '
           f'benchmarkID="ZAM_Scale-{vehicles}_1_T-1" author="bench_scale" '
           'affiliation="GridSim" source="synthetic" date="2026-11-25">']  # fmt: skip
    for lane in range(LANES):
        out.append(f'<lanelet id="{lane + 1}"><leftBound>{_bound((lane + 1) * LANE_WIDTH)}'
                   f"</leftBound><rightBound>{_bound(lane * LANE_WIDTH)}</rightBound>"
                   "<laneletType>interstate</laneletType></lanelet>")  # fmt: skip
    for i in range(vehicles):
        wave, k = divmod(i, WAVE)
        lane, slot = divmod(k, WAVE // LANES)
        speed = 20.0 + lane  # one speed per lane: cars of a lane keep their gaps
        y = (lane + 0.5) * LANE_WIDTH
        x0, step0 = 10.0 + slot * GAP, wave * STATES
        states = [(step0 + n, x0 + speed * DT * n) for n in range(STATES)]
        body = _state("initialState", states[0][0], states[0][1], y, speed)
        traj = "".join(_state("state", s, x, y, speed) for s, x in states[1:])
        out.append(f'<dynamicObstacle id="{1000 + i}"><type>car</type><shape><rectangle>'
                   "<length>4.5</length><width>1.8</width></rectangle></shape>"
                   f"{body}<trajectory>{traj}</trajectory></dynamicObstacle>")  # fmt: skip
    out.append("</commonRoad>")
    path.write_text("\n".join(out) + "\n")
    return path


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: kB


def measure(phase: str, path: str) -> dict:
    """One phase on one file, in this process (imports done before the clock starts)."""
    import gymnasium as gym

    import gridsim  # noqa: F401  (registers GridSim-v0)
    from gridsim.scenario import load_scenario
    from gridsim.scenario.families import scenario_problems
    from gridsim.traffic.commonroad import read_tracks_commonroad
    from neurotrajectory.data.recording import record_dataset

    base = _peak_mb()
    t0 = time.perf_counter()
    if phase == "read":
        n = len(read_tracks_commonroad(path))
    elif phase == "make_reset":
        env = gym.make("GridSim-v0", scenario=path)
        env.reset(seed=0)
        n = len(env.unwrapped.world.traffic.tracks)
    elif phase == "record":
        warnings.simplefilter("ignore")  # (the scene's warnings: said once, not what is timed)
        with tempfile.TemporaryDirectory() as tmp:
            n = record_dataset(Path(tmp) / "ds", path, 1)[0]["count"]
    else:
        n = len(scenario_problems(load_scenario(path)))
    return {"seconds": time.perf_counter() - t0, "peak_mb": _peak_mb() - base, "count": n}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicles", type=int, nargs="+", default=[500, 1000, 5000])
    ap.add_argument("--dir", type=Path, default=Path("/tmp/gridsim-bench-scale"))
    ap.add_argument("--phases", nargs="+", default=["read", "make_reset", "validate"])
    ap.add_argument("--measure", nargs=2, metavar=("PHASE", "FILE"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.measure:
        print(json.dumps(measure(*args.measure)))
        return
    args.dir.mkdir(parents=True, exist_ok=True)
    with open("/proc/loadavg") as fh:
        print(json.dumps({"loadavg": fh.read().split()[:3]}))
    first: dict[str, dict] = {}
    for n in sorted(args.vehicles):
        path = args.dir / f"scale_{n}.xml"
        if not path.exists():
            write_scene(path, n)
        for phase in args.phases:
            cmd = [sys.executable, __file__, "--measure", phase, str(path)]
            done = subprocess.run(cmd, capture_output=True, text=True)
            if done.returncode:
                print(json.dumps({"vehicles": n, "phase": phase, "error": done.stderr[-400:]}))
                continue
            row = json.loads(done.stdout.splitlines()[-1])
            ref = first.setdefault(phase, {**row, "vehicles": n})
            scale = n / ref["vehicles"]
            out = {
                "vehicles": n,
                "phase": phase,
                "file_mb": round(path.stat().st_size / 1e6, 1),
                "seconds": round(row["seconds"], 2),
                "peak_mb": round(row["peak_mb"], 1),
                "time_vs_linear": _ratio(row["seconds"], ref["seconds"] * scale),
                "memory_vs_linear": _ratio(row["peak_mb"], ref["peak_mb"] * scale),
            }
            if phase == "make_reset":
                out["target_s"] = 10.0
            print(json.dumps(out), flush=True)


def _ratio(value: float, linear: float) -> float | None:
    """``value`` over its linear extrapolation from the smallest scene (None when that is 0:
    a phase whose peak stayed within the imports' memory)."""
    return round(value / linear, 2) if linear > 0 else None


if __name__ == "__main__":
    main()
