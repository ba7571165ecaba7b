"""Evaluation speed: recording labelled windows, and the cost per window of each predictor.

    python benchmarks/bench_eval.py [--windows 200]

Prints one JSON line per figure: windows recorded per second (generated and recorded
scenes), and milliseconds per window for constant velocity, DWA (one window at a time, as
in closed loop, and batched), End2End and NeuroTrajectory (default preset, batched and one
at a time), with each method's ratio to DWA one at a time; and End2End's training time per
window and epoch on 1 and 2 threads, with the projected minutes for 33,000 windows and the
default epochs (target: <= 5 min on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # as neurotrajectory sets it; before torch

import numpy as np  # noqa: E402
import torch  # noqa: E402

from neurotrajectory.compare.baselines.constant_velocity import ConstantVelocity  # noqa: E402
from neurotrajectory.compare.baselines.dwa import DWA  # noqa: E402
from neurotrajectory.compare.baselines.end2end import End2End, TrainSettings  # noqa: E402
from neurotrajectory.compare.front import NetPredictor  # noqa: E402
from neurotrajectory.compare.predictors import Setting  # noqa: E402
from neurotrajectory.data.windows import record_group  # noqa: E402
from neurotrajectory.model import PRESETS, NetConfig, TrajectoryNet  # noqa: E402


def _per_window_ms(fn, batch, one_at_a_time: bool) -> float:
    n = len(batch)
    t0 = time.perf_counter()
    if one_at_a_time:
        for i in range(n):
            fn(batch.take(np.array([i])))
    else:
        fn(batch)
    return 1000.0 * (time.perf_counter() - t0) / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--windows", type=int, default=200, help="windows timed per predictor")
    ap.add_argument("--e2e-windows", type=int, default=0, metavar="N",
                    help="also train End2End for real on N windows (the recorded ones "
                         "repeated; 33000: the target's size) with the default epochs")  # fmt: skip
    args = ap.parse_args()
    with open("/proc/loadavg") as fh:
        print(json.dumps({"loadavg": fh.read().split()[:3]}))
    torch.set_num_threads(1)
    for group, episodes in (("seamless", 2), ("urban", 1)):
        t0 = time.perf_counter()
        ds = record_group(group, episodes, seed=0, duration=20.0)
        seconds = time.perf_counter() - t0
        print(json.dumps({"bench": "record_windows", "group": group, "windows": len(ds.windows),
                          "windows_per_s": round(len(ds.windows) / seconds, 1)}))  # fmt: skip
    ds = record_group("seamless", 4, seed=1, duration=30.0)
    batch = ds.windows.take(np.arange(min(args.windows, len(ds.windows))))
    setting = Setting.from_manifest(ds.manifest)
    e2e = End2End.train(batch, setting, TrainSettings(epochs=1))
    cfg = NetConfig(**{**PRESETS["default"].to_dict(), "grid_size": batch.grids.shape[-1]})
    nt = NetPredictor(TrajectoryNet(cfg))
    timings = {
        "constant velocity": _per_window_ms(ConstantVelocity(setting).predict, batch, False),
        "DWA": _per_window_ms(DWA(setting).predict, batch, True),
        "DWA (batched)": _per_window_ms(DWA(setting).predict, batch, False),
        "End2End (batched)": _per_window_ms(e2e.predict, batch, False),
        "End2End (one at a time)": _per_window_ms(e2e.predict, batch, True),
        "NeuroTrajectory (batched)": _per_window_ms(nt.predict, batch, False),
        "NeuroTrajectory (one at a time)": _per_window_ms(nt.predict, batch, True),
    }
    for name, ms in timings.items():
        print(json.dumps({"bench": "predict", "method": name, "windows": len(batch),
                          "ms_per_window": round(ms, 3),
                          "ratio_to_dwa": round(ms / timings["DWA"], 3)}))  # fmt: skip
    epochs = TrainSettings().epochs
    for threads in (1, 2):
        torch.set_num_threads(threads)
        t0 = time.perf_counter()
        End2End.train(batch, setting, TrainSettings(epochs=2))
        ms = 1000.0 * (time.perf_counter() - t0) / (2 * len(batch))
        print(json.dumps({"bench": "end2end_training", "threads": threads, "windows": len(batch),
                          "ms_per_window_epoch": round(ms, 3),
                          "projected_min_33k_windows": round(ms * 33_000 * epochs / 60e3, 2),
                          "target_min": 5.0}))  # fmt: skip
    if args.e2e_windows:
        torch.set_num_threads(2)
        big = batch.take(np.arange(args.e2e_windows) % len(batch))
        t0 = time.perf_counter()
        End2End.train(big, setting, TrainSettings())
        print(json.dumps({"bench": "end2end_training_full", "threads": 2, "windows": len(big),
                          "epochs": epochs, "minutes": round((time.perf_counter() - t0) / 60, 2),
                          "target_min": 5.0}))  # fmt: skip


if __name__ == "__main__":
    main()
