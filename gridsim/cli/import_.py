"""``gridsim import``: write scenario YAML and trajectory CSV files from CommonRoad files, to
edit."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(sub) -> None:
    p = sub.add_parser(
        "import",
        help="write scenario YAML and trajectory CSV files from CommonRoad files, to edit",
    )
    p.add_argument("sources", nargs="+", help="CommonRoad .xml files, folders or globs")
    p.add_argument("--out", required=True, help="output folder (YAML, CSV and maps/)")
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    from gridsim.scenario.collection import scenario_files
    from gridsim.scenario.importer import import_files, written

    files = []
    for src in args.sources:
        found = scenario_files(src)
        files += [Path(src)] if found is None else [f for f in found if f.suffix == ".xml"]
    by_stem = {f.stem: f for f in files}  # (a scenario is named by its file's stem)
    for path in import_files(files, args.out):
        wrote = written(path, by_stem[path.stem])  # map, tracks, scenario
        print(f"wrote {wrote[2]}, {wrote[1]} and {wrote[0]}")
    return 0
