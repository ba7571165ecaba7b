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
    from gridsim.errors import GridSimError
    from gridsim.outputs import counted
    from gridsim.scenario.collection import scenario_files
    from gridsim.scenario.loader import builtin_scenarios, load_scenario

    if not args.path:
        for name, desc in builtin_scenarios().items():
            print(f"{name:16s} {desc}")
        return 0
    args.path = ",".join(args.path)  # several (a glob the shell expanded): a list of them
    files = scenario_files(args.path)
    one = files is None  # one file: it loads, or its error is the command's
    if one:
        files = [args.path]
    # every file that loads, whether or not its data is sound and they agree enough to run
    # as one collection (gridsim validate says: it reads every map and recording); those
    # that do not load are listed too, with their first problem
    listed, failed = 0, 0
    for f in files:
        try:
            sc = load_scenario(f, shared=True)
        except GridSimError as exc:
            if one:
                raise
            failed += 1
            lines = str(exc).splitlines()
            first = lines[0].removeprefix(f"{f}: ")
            if first.endswith(":") and len(lines) > 1:  # a list of problems: the first
                first += " " + lines[1].strip().removeprefix("- ")
            print(f"{f}: does not load: {first}")
            continue
        listed += 1
        print(f"{sc.source}: {sc.name} ({sc.config.road.type}{_scene(sc)}) "
              f"{sc.config.description}")  # fmt: skip
    but = (f", {counted(failed, 'file')} that {'does' if failed == 1 else 'do'} not load"
           if failed else "")  # fmt: skip
    print(f"gridsim: {counted(listed, 'scenario')} listed{but}; `gridsim validate "
          f"{args.path}` reads their maps and recordings and checks them, naming every "
          "problem", file=sys.stderr)  # fmt: skip
    return 1 if failed else 0


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
