"""``neurotrajectory evaluate``: Table II and the closed loop, a trained run against DWA,
End2End, constant velocity and the destination curve."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from gridsim.cli.flags import at_least, quiet_flag, seed_flag
from neurotrajectory.cli.flags import (
    episode_seconds_flag,
    goal_flag,
    pick_flag,
    run_flag,
    test_fraction_flag,
)
from neurotrajectory.compare.baselines.end2end import TrainSettings
from neurotrajectory.compare.evaluation import EvalConfig
from neurotrajectory.data.windows import GROUPS
from neurotrajectory.evolve.runs import RunError

#: The defaults of every flag that sets an :class:`EvalConfig` field.
EVAL = EvalConfig()


def add_parser(sub) -> None:
    p = sub.add_parser("evaluate", help="compare with DWA, End2End and constant velocity")
    run_flag(p, "a finished training run")
    p.add_argument("--group-run", dest="group_run", action="append", default=[],
                   metavar="GROUP=RUN", help="another run for one group (repeatable)")  # fmt: skip
    goal_flag(p, "every planner is given the destination")
    p.add_argument("--out", required=True, help="evaluation folder (created)")
    p.add_argument(
        "--data",
        default=None,
        help="folder with one recorded dataset per group (default: record them)",
    )
    p.add_argument(
        "--groups",
        nargs="+",
        default=None,
        choices=list(GROUPS),
        help="built-in groups (default: all, or none when --group is given)",
    )
    p.add_argument("--group", action="append", default=[], metavar="NAME=FOLDER",
                   help="a group of your scenarios: a folder or glob of scenario files "
                        "(repeatable)")  # fmt: skip
    p.add_argument(
        "--episodes",
        type=at_least(1),
        default=EVAL.episodes,
        help=f"episodes recorded per generated scenario (default {EVAL.episodes})",
    )
    episode_seconds_flag(p, f"length of each recorded episode [s] (default "
                            f"{EVAL.episode_seconds:g})", default=EVAL.episode_seconds)  # fmt: skip
    test_fraction_flag(p, f"share of each group's tracks held out for testing (default "
                          f"{EVAL.test_fraction:g})", default=EVAL.test_fraction)  # fmt: skip
    pick_flag(p, "the front member compared (picked without test data)")
    p.add_argument("--e2e-epochs", dest="e2e_epochs", type=at_least(1),
                   default=TrainSettings.epochs,
                   help=f"training epochs of the End2End baseline (default "
                        f"{TrainSettings.epochs})")  # fmt: skip
    p.add_argument("--closed-loop-episodes", dest="closed_loop_episodes", type=at_least(0),
                   default=EVAL.closed_loop_episodes,
                   help=f"closed-loop episodes per scenario (default "
                        f"{EVAL.closed_loop_episodes}; 0: skip)")  # fmt: skip
    p.add_argument("--closed-loop-seconds", dest="closed_loop_seconds", type=float,
                   default=EVAL.closed_loop_seconds,
                   help=f"length of each closed-loop episode [s] (default "
                        f"{EVAL.closed_loop_seconds:g})")  # fmt: skip
    p.add_argument(
        "--videos",
        action="store_true",
        help="export each method's first closed-loop episode to <out>/videos/",
    )
    seed_flag(p, "seed of the split and episodes")
    quiet_flag(p, "no progress messages")
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    from neurotrajectory.compare.evaluation import evaluate

    sources = {}
    for item in args.group:
        group, sep, path = item.partition("=")
        if not sep or not group or not path:
            raise RunError(f"--group takes NAME=FOLDER (or a glob), got {item!r}")
        if group in sources:
            raise RunError(f"--group {group} is given twice ({sources[group]} and {path}); "
                           "give each group its own name")  # fmt: skip
        sources[group] = path
    groups = args.groups if args.groups is not None else ([] if sources else list(GROUPS))
    twice = sorted({g for g in groups if groups.count(g) > 1})
    if twice:
        raise RunError(f"--groups names {', '.join(twice)} more than once")
    groups = [*groups, *(g for g in sources if g not in groups)]
    cfg = EvalConfig(
        groups=tuple(groups), episodes=args.episodes, episode_seconds=args.episode_seconds,
        sources=sources,
        test_fraction=args.test_fraction, seed=args.seed, pick=args.pick,
        end2end=TrainSettings(epochs=args.e2e_epochs, seed=args.seed),
        closed_loop_episodes=args.closed_loop_episodes,
        closed_loop_seconds=args.closed_loop_seconds, videos=args.videos,
        goal_seconds=args.goal_seconds,
    )  # fmt: skip
    log = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    group_runs = {}
    for item in args.group_run:
        group, sep, path = item.partition("=")
        if not sep or not path:
            raise RunError(f"--group-run takes GROUP=RUN_DIR, got {item!r}")
        if group in group_runs:
            raise RunError(f"--group-run {group} is given twice ({group_runs[group]} and {path})")
        group_runs[group] = path
    evaluate(args.run, args.out, cfg, data_dir=args.data, log=log, group_runs=group_runs,
             progress=not args.quiet)  # fmt: skip
    print((Path(args.out) / "table2.md").read_text())
    return 0
