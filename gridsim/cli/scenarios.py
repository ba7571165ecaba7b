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
    from gridsim.outputs import counted
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
        print(f"{sc.source}: {sc.name} ({sc.config.road.type}{_scene(sc)}) "
              f"{sc.config.description}")  # fmt: skip
    print(f"gridsim: {counted(len(scenarios), 'scenario')} listed; `gridsim validate "
          f"{args.path}` reads "
          "their maps and recordings and checks them", file=sys.stderr)  # fmt: skip
    return 0


def _scene(sc) -> str:
    """``", scene SCENE"`` of a recorded scenario (the id ``ego.track``'s ``SCENE/ID`` names
    and datasets label windows with; only the map's head is read), else ``""``."""
    from gridsim.errors import GridSimError
    from gridsim.scenario.families.recorded import scene_of
    from gridsim.scenario.family import is_recorded

    if not is_recorded(sc):
        return ""
    try:
        return f", scene {scene_of(sc)}"
    except (GridSimError, OSError):  # (a map that does not read: validate names why)
        return ", scene unknown"
