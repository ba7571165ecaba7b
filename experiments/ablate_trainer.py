"""Ablation of the trainer's ingredients on the README's main job: each variant trains with
the main job's settings without its warm start (``recipe``: evolution alone) and one
ingredient changed (``warm-start`` adds the warm start: the README's main job; the
``warm-start-*`` variants change one thing in it; ``warm-start-grid-frame`` is the network
and warm start before the ego-frame residual, skip read-out and validated epoch), then drives
its knee member on the same 20 held-out seamless episodes (``heldout.json``). Prints one JSON
line per variant.

    python experiments/ablate_trainer.py --out runs/ablation [--variants recipe no-constraint]

Variants (flags added to the main job's command):
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

MAIN_JOB = ["--scenario", "seamless", "--population", "24", "--generations", "25",
            "--episodes", "2", "--episode-seconds", "15", "--backend", "processes",
            "--workers", "2", "--heldout", "20", "--quiet"]  # fmt: skip

VARIANTS = {
    "recipe": [],
    "warm-start": ["--pretrain-episodes", "12"],
    "warm-start-one-generation": ["--pretrain-episodes", "12", "--generations", "1"],
    "warm-start-no-skip": ["--pretrain-episodes", "12", "--no-skip"],
    "warm-start-evolve-head": ["--pretrain-episodes", "12", "--evolve", "head", "--sigma", "0.01"],
    "warm-start-evolve-readout": [
        "--pretrain-episodes",
        "12",
        "--evolve",
        "readout",
        "--sigma",
        "0.02",
    ],
    "warm-start-grid-frame": [
        "--pretrain-episodes",
        "12",
        "--no-skip",
        "--frame",
        "grid",
        "--pretrain-validation",
        "0",
    ],
    "no-validation-front": ["--validation-episodes", "0"],
    "sigma-0.02": ["--validation-episodes", "0", "--sigma", "0.02"],
    "no-constraint": ["--unconstrained"],
    "fixed-episodes": ["--fixed-episodes"],
    "constant-velocity-prior": ["--prior", "constant_velocity"],
    "no-prior": ["--prior", "none"],
}
__doc__ += "\n".join(
    f"- ``{k}``: {' '.join(v) or '(none: the recipe)'}" for k, v in VARIANTS.items()
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="a folder for the runs (one per variant)")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    args = ap.parse_args()
    for name in args.variants:
        out = Path(args.out) / name
        cmd = [sys.executable, "-m", "neurotrajectory", "train", *MAIN_JOB, *VARIANTS[name],
               "--out", str(out)]  # fmt: skip
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        report = json.loads((out / "heldout.json").read_text())
        net, curve = report["network"], report["destination curve"]
        print(json.dumps({
            "variant": name, "flags": VARIANTS[name], "wall_s": round(wall, 1),
            "completed": net["completed"], "progress": round(net["progress"], 3),
            "collision": net["collision"], "off_road": net["off_road"],
            "l1": round(net["l1"], 1), "l2": round(net["l2"], 3), "l3": round(net["l3"], 1),
            "destination_curve_l1": round(curve["l1"], 1),
            "destination_curve_completed": curve["completed"],
        }), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
