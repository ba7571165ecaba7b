"""Train NeuroTrajectory from Python and drive the result: fit the network to recorded human
driving (the warm start), evolve it in closed loop, then drive the knee of its Pareto front on
held-out episodes beside its warm start and the destination curve. The same training as

    neurotrajectory train --scenario seamless --pretrain-episodes 12 --selection es \
        --population 24 --generations 25 --episodes 2 --episode-seconds 15 \
        --backend processes --workers 2 --out runs/example

(the README's main job, whose command also writes ``heldout.json`` and a video: here the
held-out drive is printed); ``--quick`` trains a tiny network for a few seconds.

    pip install ".[train]"
    python examples/06_train_and_evaluate.py [--quick] [--out runs/example]
"""

import argparse
import tempfile

from neurotrajectory.compare.front import heldout
from neurotrajectory.evolve.runs import Run, TrainConfig

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--quick", action="store_true", help="a tiny network, 2 generations (for CI)")
ap.add_argument("--out", default=None, help="the run folder (default: a temporary one)")
args = ap.parse_args()

if args.quick:
    config = TrainConfig(scenario="seamless", preset="tiny", pretrain_episodes=2,
                         pretrain_epochs=2, population=4, generations=2, episodes=1,
                         episode_seconds=4.0, validation_episodes=2)  # fmt: skip
else:  # the README's main job
    config = TrainConfig(scenario="seamless", pretrain_episodes=12, selection="es",
                         population=24, generations=25, episodes=2, episode_seconds=15.0,
                         backend="processes", workers=2)  # fmt: skip

with tempfile.TemporaryDirectory() as tmp:
    out = args.out or f"{tmp}/run"
    run = Run.create(out, config)
    summary = run.train(progress=not args.quick)
    print(f"front of {len(summary['front'])} chosen on {summary['chosen_on']}")
    report = heldout(out, episodes=4 if args.quick else 20)
    # heldout.json's keys: the knee ("network"), its warm start and the destination curve
    for key, name in (("network", "knee member"), ("warm_start", "its warm start"),
                      ("destination curve", "destination curve")):  # fmt: skip
        r = report[key]
        print(f"  {name:<18} completed {r['completed']:4.0%}  mean l1 {r['l1']:8.1f} m^2")
