"""``neurotrajectory evaluate``: Table II and the closed loop, a trained run against DWA,
End2End, constant velocity and the destination curve."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tqdm import tqdm

from gridsim.cli.flags import quiet_flag
from neurotrajectory.cli.flags import goal_flag, run_flag, settings_flag
from neurotrajectory.compare.baselines.end2end import TrainSettings
from neurotrajectory.compare.evaluation import EvalConfig
from neurotrajectory.data.windows import GROUPS
from neurotrajectory.evolve.runs import RunError


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
    for flag in ("--episodes", "--episode-seconds", "--test-fraction", "--pick",
                 "--closed-loop-episodes", "--closed-loop-seconds", "--seed"):  # fmt: skip
        settings_flag(p, EvalConfig, flag)
    settings_flag(p, TrainSettings, "--e2e-epochs", dest="epochs")
    settings_flag(p, EvalConfig, "--videos", action="store_true")
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
    flags = set(EvalConfig.model_fields) - {"groups", "sources", "end2end"}
    given = {name: getattr(args, name) for name in flags if getattr(args, name) is not None}
    end2end = {"seed": args.seed} if args.seed is not None else {}
    if args.epochs is not None:
        end2end["epochs"] = args.epochs
    cfg = EvalConfig(**given, groups=tuple(groups), sources=sources,
                     end2end=TrainSettings(**end2end))  # fmt: skip

    def log(message: str) -> None:
        if not args.quiet:
            tqdm.write(f"neurotrajectory: {message}", file=sys.stderr)

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
    out = Path(args.out)
    print((out / "table2.md").read_text())
    written = sorted(p.name for p in out.iterdir() if p.is_file())
    log(
        f"wrote {out}: {', '.join(written)}"
        + (f"; videos in {out / 'videos'}" if (out / "videos").is_dir() else "")
    )
    return 0
