"""``gridsim import``: CommonRoad scenario files as editable scenario YAML and trajectory CSV.

For ``scene.xml`` it writes into the output folder ``scene.yaml`` (the scenario the XML file
is when given as it is, :func:`~gridsim.scenario.loader.commonroad_defaults`, with its tracks
read from the CSV), ``scene.csv`` (the dynamic obstacles as tracks) and a copy of the file
as the map, ``maps/scene.xml``. Loading the YAML gives the same worlds as the XML file.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import yaml

from gridsim.errors import GridSimError, OutputError, ScenarioError
from gridsim.outputs import output_problem, write_text
from gridsim.scenario.collection import report_skipped
from gridsim.scenario.family import FAMILIES
from gridsim.scenario.loader import commonroad_defaults, deep_merge, value_at
from gridsim.traffic.commonroad import read_tracks_commonroad, scene_id
from gridsim.traffic.library import write_tracks_csv


def import_commonroad(xml: str | Path, out: str | Path) -> Path:
    """Write the scenario YAML, the tracks CSV and the map of CommonRoad file ``xml`` into
    folder ``out``; returns the YAML's path. Nothing is overwritten (:func:`import_files`)."""
    return import_files([xml], out)[0]


def _targets(xml: Path, out: Path) -> list[Path]:
    """What importing ``xml`` into ``out`` writes: its map, its tracks and its scenario."""
    return [out / "maps" / xml.name, out / f"{xml.stem}.csv", out / f"{xml.stem}.yaml"]


def import_files(files: list[str | Path], out: str | Path) -> list[Path]:
    """Import every CommonRoad file of ``files`` into folder ``out`` (see the module); the
    YAML paths written (:func:`written` names each one's files). Checked before anything
    is written: ``out`` can be a folder, no two files share a name, and no output exists
    already (an import never overwrites). Of several files, one that cannot be read is
    skipped and named in a :class:`~gridsim.errors.DataWarning`; nothing is written if none
    can."""
    paths, out = [Path(f) for f in files], Path(out)
    problem = output_problem(out, directory=True)
    if problem:
        raise OutputError(f"--out {out}: {problem}")
    for xml in paths:
        if xml.suffix.lower() != ".xml":
            raise ScenarioError(f"{xml}: not a CommonRoad .xml file")
    by_stem: dict[str, Path] = {}
    for xml in paths:
        if xml.stem in by_stem:
            raise OutputError(f"{xml} and {by_stem[xml.stem]} have the same name; their imports "
                              "would overwrite each other: import them into separate --out "
                              "folders")  # fmt: skip
        by_stem[xml.stem] = xml
    existing = [t for xml in paths for t in _targets(xml, out) if t.exists()]
    if existing:
        raise OutputError(f"--out {out}: {existing[0]} exists (an import never overwrites): "
                          "choose another --out or remove it")  # fmt: skip
    read, skipped = [], []
    for xml in paths:
        try:
            tracks = read_tracks_commonroad(xml)
            if not tracks:
                raise ScenarioError(f"{xml}: no dynamic obstacle with at least 2 states to replay")
            read.append((xml, tracks, scene_id(xml)))
        except GridSimError as exc:
            if len(paths) == 1:
                raise
            skipped.append((xml, str(exc)))
    report_skipped("import", skipped, len(paths), bool(read),
                   ("can be imported", "cannot be imported"))  # fmt: skip
    return [_write(xml, tracks, scene, out) for xml, tracks, scene in read]


def written(yaml_path: Path, xml: Path) -> list[Path]:
    """The files an import of ``xml`` wrote beside its scenario ``yaml_path``: map, tracks,
    scenario."""
    return _targets(xml, yaml_path.parent)


def _write(xml: Path, tracks, scene: str, out: Path) -> Path:
    stem = xml.stem
    (out / "maps").mkdir(parents=True, exist_ok=True)
    shutil.copyfile(xml, out / "maps" / xml.name)
    write_tracks_csv(tracks, out / f"{stem}.csv")
    doc = {
        "name": stem[:80],
        "description": f"CommonRoad scene {xml.name} (imported); one recorded vehicle is the ego",
        "road": {"type": "recorded", "map": f"maps/{xml.name}", "scene": scene},
        **deep_merge(commonroad_defaults(), {"traffic": {"library": [f"{stem}.csv"]}}),
    }
    for key in FAMILIES["recorded"].ignores:  # (a default a recorded scene never reads)
        *sections, name = key.split(".")
        block = value_at(doc, sections)
        if isinstance(block, dict):
            block.pop(name, None)
    path = out / f"{stem}.yaml"
    header = (
        f"# Imported from {xml.name} by `gridsim import`; edit freely, check with "
        "`gridsim validate`.\n"
    )
    write_text(path, header + yaml.safe_dump(doc, sort_keys=False))
    return path
