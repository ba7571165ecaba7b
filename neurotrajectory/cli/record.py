"""``neurotrajectory record``: record labelled windows of human driving (a dataset)."""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from gridsim.cli.flags import at_least, quiet_flag, seed_flag
from gridsim.outputs import interrupted, new_folder, summary_text
from neurotrajectory.cli.flags import goal_flag, settings_flag
from neurotrajectory.compare.evaluation import EvalConfig
from neurotrajectory.data.recording import CHECKPOINT_SECONDS, checkpoint_windows
from neurotrajectory.data.windows import GROUPS
from neurotrajectory.evolve.runs import RunError

#: The evaluation's defaults: a split recorded here is the one ``evaluate`` makes.
EVAL = EvalConfig.defaults()


def add_parser(sub) -> None:
    p = sub.add_parser("record", help="record labelled windows of human driving")
    p.add_argument("--scenario", required=True,
                   help=f"a scenario group ({', '.join(GROUPS)}), a built-in scenario, a YAML "
                        "or CommonRoad XML path, or a folder or glob of them; recorded scenes "
                        "drive every track once")  # fmt: skip
    p.add_argument("--name", default=None, metavar="NAME",
                   help="the group name the dataset records (default: --scenario)")  # fmt: skip
    p.add_argument("--group", default=None, help=argparse.SUPPRESS)  # the old --name: refused
    settings_flag(p, EvalConfig, "--episodes")
    p.add_argument("--episode-seconds", dest="episode_seconds", type=float, default=None,
                   help="length of each episode [s] (default: the scenario's)")  # fmt: skip
    p.add_argument(
        "--stride",
        type=at_least(1),
        default=None,
        help="decisions between windows (default 1 on recorded scenes, else 5)",
    )
    seed_flag(p, "seed of the episodes and split")
    p.add_argument(
        "--split",
        choices=["train", "test"],
        default=None,
        help="keep only this side of the split by track that `evaluate` with the same --seed "
        "and --test-fraction makes (e.g. train data for a group's run)",
    )
    settings_flag(p, EvalConfig, "--test-fraction",
                  help="share of the tracks on the test side of --split")  # fmt: skip
    goal_flag(p, "the windows see the destination")
    p.add_argument("--out", required=True,
                   help="dataset folder (created). An interrupted record keeps its work in the "
                        "hidden folder .OUT.partial beside it, and the same command goes on from "
                        "there; remove that folder to start afresh")  # fmt: skip
    quiet_flag(p)
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    from gridsim.outputs import progress_bar
    from neurotrajectory.data.recording import record_dataset
    from neurotrajectory.data.windows import bar_callbacks, check_group, early_note

    if args.group is not None:
        raise RunError(f"record --group {args.group}: the dataset's group name is --name now "
                       f"(--name {args.group}); --group NAME=FOLDER is evaluate's")  # fmt: skip
    if args.test_fraction is not None and not args.split:
        raise RunError(f"--test-fraction {args.test_fraction:g} sets the test side of --split: "
                       "give --split train or --split test (or leave it out)")  # fmt: skip
    if args.test_fraction is None:
        args.test_fraction = EVAL["test_fraction"]
    if args.episodes is None:
        args.episodes = EVAL["episodes"]
    name, source = (args.name, args.scenario) if args.name else (args.scenario, None)
    check_group(args.scenario)
    # the side evaluate --seed S --test-fraction F uses
    split = (args.split, args.test_fraction) if args.split else None
    # --out is held before recording and appears when done; the windows are written as
    # they are recorded (memory holds about one shard whatever the dataset's size), with
    # checkpoints from which the same command goes on if it is interrupted
    with (
        new_folder(args.out, resumable=True) as partial,
        progress_bar(desc=f"record {name}", unit="episode", disable=args.quiet) as bar,
    ):
        try:
            manifest, tracks = record_dataset(
                partial, name, args.episodes, args.seed, args.stride, args.episode_seconds,
                source=source, goal_seconds=args.goal_seconds, split=split, resume=True,
                log=lambda line: bar.write(f"neurotrajectory: {line}", file=sys.stderr),
                **bar_callbacks(bar))  # fmt: skip
        except BaseException as exc:
            if interrupted(exc):
                bar.close()  # (not drawn again below the message)
                print(_kept(partial), file=sys.stderr)
            raise
    if manifest.get("ended_early"):
        whole = " (counted over the whole group, before the split)" if split else ""
        print(f"neurotrajectory: {early_note(manifest['ended_early'])}{whole}", file=sys.stderr)
    print(
        summary_text(
            {
                "out": str(Path(args.out)),
                "windows": manifest["count"],
                "tracks": tracks,
                "group": manifest["group"],
                "source": manifest["source"],
                **({"ended_early": manifest["ended_early"]} if "ended_early" in manifest else {}),
                # (a scripted pipeline sees here what the warning said: files left out)
                **(
                    {"skipped": [s["file"] for s in manifest["skipped"]]}
                    if manifest.get("skipped")
                    else {}
                ),  # fmt: skip
            },
            indent=1,
        )
    )
    return 0


def _kept(partial: Path) -> str:
    """What an interrupted ``record`` leaves in ``partial`` for the same command to go on
    with (nothing, and ``partial`` is removed, before its first checkpoint)."""
    kept = checkpoint_windows(partial)
    if kept is None:
        shutil.rmtree(partial, ignore_errors=True)
        return (f"neurotrajectory: interrupted before its first checkpoint (one every "
                f"{CHECKPOINT_SECONDS:g} s): nothing is kept")  # fmt: skip
    windows, whole = kept
    of = " of the whole group (the split's side is copied at the end)" if whole else ""
    return (f"neurotrajectory: the {windows} windows{of} recorded until the last checkpoint are "
            f"kept in {partial}: the same command goes on from there (remove that folder to "
            "start afresh)")  # fmt: skip
