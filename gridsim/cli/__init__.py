"""The ``gridsim`` command line."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from gridsim.errors import GridSimError

POLICY_NAMES = ("idle", "reference", "lane-follow", "random")


def at_least(minimum: int):
    """An argparse type: an integer >= ``minimum``. argparse names the option in its error
    (``argument --seed: expected an integer >= 0, got -3``) and exits with status 2."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected an integer >= {minimum}, got {text!r}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


def _cmd_scenarios(args: argparse.Namespace) -> int:
    from gridsim.scenario.collection import load_collection
    from gridsim.scenario.loader import builtin_scenarios

    if args.path is None:
        for name, desc in builtin_scenarios().items():
            print(f"{name:16s} {desc}")
        return 0
    for sc in load_collection(args.path):
        print(f"{sc.source}: {sc.name} ({sc.config.road.type}) {sc.config.description}")
    return 0


def _problems(path: str) -> tuple[str, list[str]]:
    """``(summary, problems)`` of one scenario file: it loads, builds, and its recorded data
    (if any) is plausible."""
    from gridsim.scenario.build import build_world
    from gridsim.scenario.checks import scenario_problems
    from gridsim.scenario.loader import load_scenario

    sc = load_scenario(path)
    build_world(sc, seed=0)  # also resolves maps and libraries
    return f"scenario {sc.name!r}, road type {sc.config.road.type}", scenario_problems(sc)


def _cmd_validate(args: argparse.Namespace) -> int:
    from gridsim.errors import DataError
    from gridsim.scenario.collection import scenario_files

    files = scenario_files(args.path)
    if files is None:  # one file: its problems are the error
        summary, problems = _problems(args.path)
        if problems:
            lines = "\n".join(f"  - {p}" for p in problems)
            raise DataError(
                f"{args.path}: implausible recorded scene ({len(problems)} problem(s)):\n{lines}"
            )
        print(f"{args.path}: OK ({summary})")
        return 0
    failed = 0
    for f in files:  # a collection: one line per file, its problems below it
        try:
            summary, problems = _problems(str(f))
        except GridSimError as exc:
            summary, problems = "error", str(exc).splitlines()
        if problems:
            failed += 1
            print(f"{f}: {len(problems)} problem(s)")
            print("\n".join(f"  - {p.strip().removeprefix('- ')}" for p in problems))
        else:
            print(f"{f}: OK ({summary})")
    print(f"{len(files) - failed} of {len(files)} scenario files OK")
    return 2 if failed else 0


def _cmd_import(args: argparse.Namespace) -> int:
    from gridsim.scenario.collection import scenario_files
    from gridsim.scenario.importer import import_commonroad

    files = []
    for src in args.sources:
        found = scenario_files(src)
        files += [Path(src)] if found is None else [f for f in found if f.suffix == ".xml"]
    for f in files:
        print(f"{f}: wrote {import_commonroad(f, args.out)}")
    return 0


def _cmd_drive(args: argparse.Namespace) -> int:
    from gridsim.cli.drive import drive

    summary = drive(args.scenario, args.seconds, args.seed, Path(args.out), progress=not args.quiet)
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from gridsim.cli.run import run_policy

    summary = run_policy(
        args.scenario, args.policy, args.steps, args.seed, video=args.video,
        progress=not args.quiet, overlay=args.overlay,
    )  # fmt: skip
    print(json.dumps(summary, indent=2))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gridsim", description="Headless GridSim driving simulator.")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser(
        "scenarios", help="list the built-in scenarios, or the scenarios of a folder or glob"
    )
    s.add_argument("path", nargs="?", default=None, help="a folder or glob of scenario files")
    s.set_defaults(func=_cmd_scenarios)
    s = sub.add_parser(
        "validate",
        help="check a scenario file (YAML or CommonRoad XML; and a recorded scene's data), or "
        "each file of a folder or glob, and print precise errors",
    )
    s.add_argument("path")
    s.set_defaults(func=_cmd_validate)
    s = sub.add_parser(
        "import",
        help="write scenario YAML and trajectory CSV files from CommonRoad files, to edit",
    )
    s.add_argument("sources", nargs="+", help="CommonRoad .xml files, folders or globs")
    s.add_argument("--out", required=True, help="output folder (YAML, CSV and maps/)")
    s.set_defaults(func=_cmd_import)
    s = sub.add_parser("run", help="drive a policy in GridSim-v0, print a summary, export a video")
    s.add_argument(
        "--scenario", default="seamless", help="built-in name, YAML/XML path, folder or glob"
    )
    s.add_argument("--steps", type=at_least(1), default=300, help="decisions to run at most")
    s.add_argument(
        "--policy",
        default="reference",
        choices=POLICY_NAMES,
        help="the driver: the human reference, lane following, random or idle",
    )
    s.add_argument("--seed", type=at_least(0), default=0, help="episode seed")
    s.add_argument("--video", default=None, help="write a video (.mp4, or .gif)")
    s.add_argument("--overlay", action="store_true",
                   help="caption the video: time, speed and what the dots are")  # fmt: skip
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=_cmd_run)
    s = sub.add_parser(
        "drive", help="drive the lane-following ego; write grids and a top-down frame"
    )
    s.add_argument(
        "--scenario", default="seamless", help="built-in name, YAML/XML path, folder or glob"
    )
    s.add_argument("--seconds", type=float, default=20.0, help="simulated time [s]")
    s.add_argument("--seed", type=at_least(0), default=0, help="episode seed")
    s.add_argument("--out", default="out/drive", help="output folder")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=_cmd_drive)
    return p


def run_command(
    parser: argparse.ArgumentParser,
    argv: list[str] | None,
    errors: tuple[type[Exception], ...] = (GridSimError,),
) -> int:
    """Parse ``argv`` and run the chosen sub-command's ``func``. An expected error (one of
    ``errors``: bad input, named by the message) is printed as ``PROG: error: MESSAGE`` with
    exit status 2, as argparse prints a bad flag; anything else is a bug and raises."""
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except errors as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
