"""The ``gridsim`` command line."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from gridsim.errors import GridSimError

POLICY_NAMES = ("idle", "reference", "lane-follow", "random")


def _cmd_scenarios(args: argparse.Namespace) -> int:
    from gridsim.scenario.loader import builtin_scenarios

    for name, desc in builtin_scenarios().items():
        print(f"{name:16s} {desc}")
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    from gridsim.errors import DataError
    from gridsim.scenario.build import build_world
    from gridsim.scenario.checks import scenario_problems
    from gridsim.scenario.loader import load_scenario

    sc = load_scenario(args.path)
    build_world(sc, seed=0)  # also resolves maps and libraries
    problems = scenario_problems(sc)
    if problems:
        lines = "\n".join(f"  - {p}" for p in problems)
        raise DataError(
            f"{args.path}: implausible recorded scene ({len(problems)} problem(s)):\n{lines}"
        )
    print(f"{args.path}: OK (scenario {sc.name!r}, road type {sc.config.road.type})")
    return 0


def _cmd_drive(args: argparse.Namespace) -> int:
    from gridsim.drive import drive

    summary = drive(args.scenario, args.seconds, args.seed, Path(args.out), progress=not args.quiet)
    print(json.dumps(summary, indent=2))
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from gridsim.run import run_policy

    summary = run_policy(
        args.scenario, args.policy, args.steps, args.seed, video=args.video, progress=not args.quiet
    )
    print(json.dumps(summary, indent=2))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gridsim", description="Headless GridSim driving simulator.")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("scenarios", help="list the built-in scenarios")
    s.set_defaults(func=_cmd_scenarios)
    s = sub.add_parser(
        "validate",
        help="check a scenario YAML file (and a recorded scene's data) and print precise errors",
    )
    s.add_argument("path")
    s.set_defaults(func=_cmd_validate)
    s = sub.add_parser("run", help="drive a policy in GridSim-v0, print a summary, export a video")
    s.add_argument("--scenario", default="seamless", help="built-in name or YAML path")
    s.add_argument("--steps", type=int, default=300, help="decisions to run at most")
    s.add_argument("--policy", default="reference", choices=POLICY_NAMES)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--video", default=None, help="write a video (.mp4, or .gif)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=_cmd_run)
    s = sub.add_parser(
        "drive", help="drive the lane-following ego; write grids and a top-down frame"
    )
    s.add_argument("--scenario", default="seamless", help="built-in name or YAML path")
    s.add_argument("--seconds", type=float, default=20.0, help="simulated time [s]")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--out", default="out/drive", help="output folder")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=_cmd_drive)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except GridSimError as exc:
        print(f"gridsim: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
