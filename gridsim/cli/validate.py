"""``gridsim validate``: check a scenario file (and a recorded scene's data), or each file of
a folder or glob, and print every problem in plain words."""

from __future__ import annotations

import argparse
import warnings

from gridsim.errors import DataWarning, GridSimError
from gridsim.outputs import counted


def add_parser(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="check a scenario file (YAML or CommonRoad XML; and a recorded scene's data), or "
        "each file of a folder or glob, and print precise errors",
    )
    p.add_argument("path", nargs="+", help="a scenario file, a folder or a glob of them (or "
                   "several files: a glob the shell expanded)")  # fmt: skip
    p.add_argument("--resolved", action="store_true",
                   help="also print the scenario as it is run: every key, the family's "
                   "defaults and extends: filled in (one file)")  # fmt: skip
    p.set_defaults(func=execute)


def _report(path: str):
    """``(scenario, summary, report)`` of one scenario file: it loads, builds, and its
    recorded data (if any) is plausible (:class:`~gridsim.scenario.checks.SceneReport`)."""
    from gridsim.scenario.build import build_world
    from gridsim.scenario.families import scenario_report
    from gridsim.scenario.loader import load_scenario

    sc = load_scenario(path)
    report = scenario_report(sc)
    if not report.problems:
        with warnings.catch_warnings():  # the report lists them
            warnings.simplefilter("ignore", DataWarning)
            build_world(sc, seed=0)  # also resolves maps and libraries
    return sc, f"scenario {sc.name!r}, road type {sc.config.road.type}", report


def execute(args: argparse.Namespace) -> int:
    from gridsim.errors import DataError
    from gridsim.scenario.collection import (
        check_agreement,
        check_track_scenes,
        repeated_recordings,
        scenario_files,
        shared_names_messages,
        shared_track_names,
    )

    args.path = ",".join(args.path)  # several (a glob the shell expanded): a list of them
    files = scenario_files(args.path)
    if args.resolved and files is not None:
        raise GridSimError(f"--resolved prints one scenario; {args.path} is a folder or glob "
                           f"of {len(files)}: give one file")  # fmt: skip
    if files is None:  # one file: its problems are the error
        sc, summary, report = _report(args.path)
        if report.problems:
            raise DataError(report.refusal(args.path))
        check_track_scenes([sc])
        said = f"{args.path}: OK ({summary})" + _warning_lines(report.warnings)
        if not args.resolved:
            print(said)
            return 0
        # what the file means, every default filled in: YAML that loads as the same scenario
        # (the verdict as comments, so that the output can be saved as a file)
        import yaml

        from gridsim.scenario.loader import absolute_paths

        print("\n".join(f"# {line}" for line in said.splitlines()))
        print(f"# {args.path} as it is run (every key; the family's defaults filled in; its "
              "files by absolute paths, so that it loads from any folder)")  # fmt: skip
        doc = absolute_paths(sc.config.model_dump(mode="json"), sc.base_dir)
        print(yaml.safe_dump(doc, sort_keys=False, width=100), end="")
        return 0
    failed, usable = 0, []
    for f in files:  # a collection: one line per file, its problems below it
        try:
            sc, summary, report = _report(str(f))
            problems, notes = report.problems, report.warnings
        except GridSimError as exc:  # one error, its own lines (a count and a list) kept
            failed += 1
            first, *rest = str(exc).splitlines() or ["error"]
            print(f"{f}: {first.removeprefix(f'{f}: ')}")
            for line in rest:
                print(f"  {line.strip()}")
            continue
        if problems:
            failed += 1
            print(f"{f}: {counted(len(problems), 'problem')}")
            print("\n".join(f"  - {p.strip().removeprefix('- ')}" for p in problems))
        else:
            usable.append((f, sc))
            print(f"{f}: OK ({summary})" + _warning_lines(notes))
    print(f"{len(files) - failed} of {len(files)} scenario files OK")
    for first, again, scene in repeated_recordings(usable):
        print(f"warning: {again} replays the same recording as {first} (scene {scene}): its "
              "episodes and windows would count twice")  # fmt: skip
    for said in shared_names_messages(shared_track_names(usable)):
        print(f"warning: {said}")
    try:  # and they run together as one collection
        if usable:
            check_agreement(args.path, [sc for _, sc in usable])
    except GridSimError as exc:
        print(f"{exc} (run them apart, or make them agree)")
        return 2
    try:  # (a file's own mistake, said on its own)
        check_track_scenes([sc for _, sc in usable], some_skipped=bool(failed))
    except GridSimError as exc:
        print(exc)
        return 2
    return 2 if failed else 0


def _warning_lines(notes: tuple[str, ...]) -> str:
    return "".join(f"\n  warning: {n}" for n in notes)
