"""Is there a correction of a recorded-group run's warm start that every driver shares? Adds
a constant offset to the warm start's read-out biases (``--axis along``: ``k * t_i`` metres
along the heading at set-point time ``t_i``, a speed offset of ``k`` m/s; ``--axis across``:
``k`` metres to the left at every set-point), drives the run's training tracks and its
held-out tracks once each (as ``heldout.json`` does, plans smoothed as the run's) and prints
the mean closed-loop l1, completions and progress per offset, one JSON line each.

A correction evolution could find and that carries over would lower l1 on both sides at the
same offset. Choose nothing on the held-out side: it is printed to see whether the training
side's best offset carries over.

    python experiments/warm_start_offsets.py runs/gain/highway-s3-recipe --axis along \\
        --offsets -0.1 -0.05 -0.02 0 0.02 0.05
"""

from __future__ import annotations

import argparse
import json
import warnings

import numpy as np
import torch

from gridsim.errors import DataWarning
from neurotrajectory.compare.closed_loop import drive_episodes
from neurotrajectory.compare.front import load_front, load_warm_start, run_tracks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", help="a run folder trained on recorded scenes, with a warm start")
    ap.add_argument("--axis", choices=["along", "across"], default="along")
    ap.add_argument("--offsets", nargs="+", type=float, default=[-0.05, -0.02, 0.0, 0.02, 0.05])
    args = ap.parse_args()
    warnings.simplefilter("ignore", DataWarning)  # (the scenes' notes, said by train already)
    run, *_ = load_front(args.run)
    cfg = run.config
    policy = load_warm_start(run)
    if policy is None or not cfg.ego_tracks:
        raise SystemExit(f"{args.run}: needs a warm-started run on recorded scenes")
    if policy.net.cfg.frame != "ego" or policy.net.cfg.max_correction is not None:
        raise SystemExit(f"{args.run}: the offsets are along and across the heading only for a "
                         "network whose residual is in the ego frame, unbounded")  # fmt: skip
    branches = policy.net.branches
    bias, times = branches.head_bias.detach().clone(), policy.net.times.clone()
    split = run_tracks(cfg)
    train, held = split.trained, split.held
    seeds = list(cfg.heldout_seeds(max(len(held), len(train))))

    def drive(tracks) -> list[dict]:
        return [drive_episodes(ref, policy, [seed], cfg.episode_seconds, ego={"track": track},
                               goal_seconds=cfg.goal_seconds)[0]
                for (ref, track), seed in zip(tracks, seeds, strict=False)]  # fmt: skip

    def summary(rows: list[dict]) -> dict:
        return {"l1": round(float(np.mean([r["l1"] for r in rows])), 2),
                "completed": f"{sum(bool(r['completed']) for r in rows)}/{len(rows)}",
                "progress": round(float(np.nanmean([r["progress"] for r in rows])), 3)}  # fmt: skip

    for k in args.offsets:
        with torch.no_grad():
            branches.head_bias.copy_(bias)
            if args.axis == "along":
                branches.head_bias[:, 0] += k * times
            else:
                branches.head_bias[:, 1] += k
        print(json.dumps({"run": args.run, "axis": args.axis, "offset": k,
                          "train": summary(drive(train)), "held_out": summary(drive(held))}),
              flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
