"""``gridsim scenarios``: list the built-in scenarios, or the scenarios of a folder or glob."""

from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser(
        "scenarios", help="list the built-in scenarios, or the scenarios of a folder or glob"
    )
    p.add_argument("path", nargs="?", default=None, help="a folder or glob of scenario files")
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    from gridsim.scenario.collection import scenario_files, usable_files
    from gridsim.scenario.loader import builtin_scenarios, load_scenario

    if args.path is None:
        for name, desc in builtin_scenarios().items():
            print(f"{name:16s} {desc}")
        return 0
    # every usable file, whether or not they agree enough to run as one collection
    # (gridsim validate says)
    scenarios = ([load_scenario(args.path)] if scenario_files(args.path) is None
                 else usable_files(args.path)[0])  # fmt: skip
    for sc in scenarios:
        print(f"{sc.source}: {sc.name} ({sc.config.road.type}) {sc.config.description}")
    return 0
