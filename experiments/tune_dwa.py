"""Tune DWA's cost weights and safety settings on the train splits of all evaluation groups.

    python experiments/tune_dwa.py --data /tmp/dwa-data                 # the search
    python experiments/tune_dwa.py --data /tmp/dwa-data --once-on-test  # afterwards, once

The windows are those ``neurotrajectory evaluate`` uses by default (``EvalConfig``: 8 episodes
of 30 s per generated scenario, seed 0; every track of the recorded scenes), read from
``--data/<group>`` or recorded there if missing, and split by track exactly as evaluation
splits them. The search reads only the train side.

Objective (lower is better): the mean over the four groups of DWA's train RMSE divided by
constant velocity's train RMSE in that group, so that every group counts equally.

Search (seeded, deterministic): :data:`START` and ``--samples`` random configurations drawn
from :data:`SPACE`, then at most ``--passes`` passes of coordinate search from the best (each
parameter in turn: its neighbours one :data:`SPACE` step away, kept if the objective
improves). The safety settings are bounded so that DWA stays a planner that avoids the
obstacles of its grid: on RMSE alone, switching the collision test off wins.

Prints JSON lines: one per evaluated configuration, then the chosen one with its per-group
train figures and the wall time. ``--once-on-test`` instead prints the test-side figures of
constant velocity, DWA before issue 10 (:data:`BEFORE_ISSUE_10`), with only the new fallback
(:data:`START`) and with the current defaults; it is meant to be run once, after the
defaults are set.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from neurotrajectory.compare.baselines.constant_velocity import ConstantVelocity
from neurotrajectory.compare.baselines.dwa import DWA, DWAConfig
from neurotrajectory.compare.evaluation import EvalConfig
from neurotrajectory.compare.metrics import accuracy
from neurotrajectory.compare.predictors import Setting
from neurotrajectory.data.storage import load_dataset, save_dataset
from neurotrajectory.data.windows import GROUPS, Windows, record_group, split_by_track

#: DWA as evaluated before issue 10: its defaults then, with the old fallback.
BEFORE_ISSUE_10 = DWAConfig(margin=0.05, collision_horizon=0.5, headway=0.5, w_heading=0.02,
                            w_clearance=0.02, w_speed=0.02, w_lateral=0.05,
                            w_steer_change=0.05, w_late_collision=0.1,
                            fallback="clearance")  # fmt: skip
#: Where the search starts: those settings with the new fallback (fixed, so that a rerun
#: after the defaults were changed searches the same way).
START = replace(BEFORE_ISSUE_10, fallback="relax", fallback_tolerance=0.1)


@dataclass(frozen=True)
class Range:
    """A searched parameter: drawn uniformly in ``[low, high]`` (in log space if ``log``)
    and stepped by ``step`` (a factor if ``log``) in the coordinate search."""

    low: float
    high: float
    step: float
    log: bool = False

    def draw(self, rng: np.random.Generator) -> float:
        if self.log:
            return _round(math.exp(rng.uniform(math.log(self.low), math.log(self.high))))
        return _round(rng.uniform(self.low, self.high))

    def neighbours(self, value: float) -> list[float]:
        if self.log:
            near = [value / self.step, value * self.step]
        else:
            near = [value - self.step, value + self.step]
        return [v for v in map(_round, near) if self.low <= v <= self.high]


#: The search space. Weights are on DWA's normalised cost terms (``w_goal`` = 1 sets the
#: scale); margin [m], horizons [s, multiples of the 0.1 s rollout step], tolerance [m].
SPACE = {
    "w_heading": Range(1e-3, 1.0, 2.0, log=True),
    "w_clearance": Range(1e-3, 1.0, 2.0, log=True),
    "w_speed": Range(1e-3, 1.0, 2.0, log=True),
    "w_lateral": Range(1e-3, 1.0, 2.0, log=True),
    "w_steer_change": Range(1e-3, 1.0, 2.0, log=True),
    "w_late_collision": Range(1e-3, 1.0, 2.0, log=True),
    "margin": Range(0.0, 0.2, 0.05),
    "collision_horizon": Range(0.3, 1.0, 0.1),
    "headway": Range(0.3, 1.0, 0.1),
    "fallback_tolerance": Range(0.05, 0.8, 2.0, log=True),
}
#: parameters drawn on the rollout step's grid
STEPPED = ("collision_horizon", "headway")


def _round(x: float) -> float:
    """Three significant digits, so that chosen values read as defaults."""
    return float(f"{x:.3g}")


@dataclass
class Split:
    """One group's windows on one side of the split, with what every candidate shares."""

    group: str
    windows: Windows
    setting: Setting
    cv_rmse: float


def load_splits(data: Path, side: str, max_windows: int | None, seed: int) -> list[Split]:
    """Each group's ``side`` ("train" or "test") of the evaluation split, at most
    ``max_windows`` of them per group (drawn with ``seed``)."""
    cfg = EvalConfig()
    out = []
    for group in GROUPS:
        folder = data / group
        if folder.is_dir():
            ds = load_dataset(folder)
        else:
            ds = record_group(group, cfg.episodes, cfg.seed, duration=cfg.episode_seconds)
            save_dataset(ds, folder)
        sides = split_by_track(ds.windows, cfg.test_fraction, cfg.seed)
        windows = sides[0] if side == "train" else sides[1]
        if max_windows is not None and len(windows) > max_windows:
            rng = np.random.default_rng(np.random.SeedSequence([seed, len(out)]))
            windows = windows.take(np.sort(rng.choice(len(windows), max_windows, replace=False)))
        setting = Setting.from_manifest(ds.manifest)
        cv = ConstantVelocity(setting).predict(windows)
        out.append(Split(group, windows, setting, accuracy(cv, windows.target,
                                                           windows.heading).rmse))  # fmt: skip
    return out


def score(config: DWAConfig, split: Split) -> dict:
    """DWA's RMSE [m] on ``split``, its ratio to constant velocity's, and the share of
    windows at each fallback level (none admissible)."""
    dwa = DWA(split.setting, config)
    w = split.windows
    plans = [dwa.plan_many(w.take(np.arange(a, min(a + DWA.CHUNK, len(w)))))
             for a in range(0, len(w), DWA.CHUNK)]  # fmt: skip
    rmse = accuracy(np.concatenate([p.setpoints for p in plans]), w.target, w.heading).rmse
    levels = np.bincount(np.concatenate([p.level for p in plans]), minlength=4) / len(w)
    return {"rmse": round(rmse, 4), "ratio": round(rmse / split.cv_rmse, 4),
            "fallback": round(1.0 - levels[0], 4),
            "fallback_levels": [round(x, 4) for x in levels[1:]]}  # fmt: skip


def objective(config: DWAConfig, splits: list[Split]) -> tuple[float, dict]:
    scores = {s.group: score(config, s) for s in splits}
    return float(np.mean([s["ratio"] for s in scores.values()])), scores


def _searched(config: DWAConfig) -> dict:
    return {k: getattr(config, k) for k in SPACE}


def search(splits: list[Split], samples: int, passes: int, seed: int) -> DWAConfig:
    """Random then coordinate search (see the module docstring); prints every evaluation."""
    count = 0

    def evaluate(config: DWAConfig, stage: str) -> float:
        nonlocal count
        value, scores = objective(config, splits)
        print(json.dumps({"eval": count, "stage": stage, "objective": round(value, 4),
                          "config": _searched(config), "train": scores}), flush=True)  # fmt: skip
        count += 1
        return value

    rng = np.random.default_rng(seed)
    best, best_value = START, evaluate(START, "start")
    for _ in range(samples):
        drawn = {k: r.draw(rng) for k, r in SPACE.items()}
        drawn |= {k: _round(0.1 * round(drawn[k] / 0.1)) for k in STEPPED}
        config = replace(START, **drawn)
        value = evaluate(config, "random")
        if value < best_value:
            best, best_value = config, value
    for _ in range(passes):
        improved = False
        for name, r in SPACE.items():
            for value in r.neighbours(getattr(best, name)):
                config = replace(best, **{name: value})
                v = evaluate(config, f"coordinate {name}")
                if v < best_value:
                    best, best_value, improved = config, v, True
        if not improved:
            break
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--data",
        type=Path,
        required=True,
        help="folder with one dataset per group (recorded there if missing)",
    )
    ap.add_argument("--samples", type=int, default=64, help="random configurations")
    ap.add_argument("--passes", type=int, default=6, help="coordinate-search passes (at most)")
    ap.add_argument(
        "--max-windows",
        type=int,
        default=None,
        help="train windows per group (a seeded subsample; default all)",
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--once-on-test",
        action="store_true",
        help="print the test figures of the current defaults instead of tuning",
    )
    args = ap.parse_args()
    t0 = time.perf_counter()
    if args.once_on_test:
        for split in load_splits(args.data, "test", None, args.seed):
            print(json.dumps({"group": split.group, "test_windows": len(split.windows),
                              "test_tracks": len(np.unique(split.windows.track)),
                              "cv_rmse": round(split.cv_rmse, 4),
                              "dwa_before_issue_10": score(BEFORE_ISSUE_10, split),
                              "dwa_start": score(START, split),
                              "dwa": score(DWAConfig(), split)}), flush=True)  # fmt: skip
        return
    splits = load_splits(args.data, "train", args.max_windows, args.seed)
    print(json.dumps({"train_windows": {s.group: len(s.windows) for s in splits},
                      "cv_rmse": {s.group: round(s.cv_rmse, 4) for s in splits}}))  # fmt: skip
    before, before_scores = objective(BEFORE_ISSUE_10, splits)
    print(json.dumps({"before_issue_10": round(before, 4), "train": before_scores}))
    best = search(splits, args.samples, args.passes, args.seed)
    value, scores = objective(best, splits)
    wall = round(time.perf_counter() - t0, 1)
    print(json.dumps({"chosen": _searched(best), "objective": round(value, 4), "train": scores,
                      "config": asdict(best), "is_default": best == DWAConfig(),
                      "wall_s": wall}))  # fmt: skip


if __name__ == "__main__":
    main()
