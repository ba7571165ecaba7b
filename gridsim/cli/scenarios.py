"""``gridsim scenarios``: list the built-in scenarios, or the scenarios of a folder or glob."""

from __future__ import annotations

import argparse
import sys


def add_parser(sub) -> None:
    p = sub.add_parser(
        "scenarios", help="list the built-in scenarios, or the scenarios of a folder or glob"
    )
    p.add_argument("path", nargs="*", help="a folder or glob of scenario files (or several "
                   "files: a glob the shell expanded)")  # fmt: skip
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    from gridsim.scenario.collection import scenario_files, usable_files
    from gridsim.scenario.loader import builtin_scenarios, load_scenario

    if not args.path:
        for name, desc in builtin_scenarios().items():
            print(f"{name:16s} {desc}")
        return 0
    args.path = ",".join(args.path)  # several (a glob the shell expanded): a list of them
    # every file that loads, whether or not its data is sound and they agree enough to run
    # as one collection (gridsim validate says: it reads every map and recording)
    scenarios = ([load_scenario(args.path)] if scenario_files(args.path) is None
                 else usable_files(args.path, read_data=False)[0])  # fmt: skip
    for sc in scenarios:
        print(f"{sc.source}: {sc.name} ({sc.config.road.type}) {sc.config.description}")
    print(f"gridsim: {len(scenarios)} scenario(s) listed; `gridsim validate {args.path}` reads "
          "their maps and recordings and checks them", file=sys.stderr)  # fmt: skip
    return 0
