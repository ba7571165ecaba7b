"""``gridsim import``: CommonRoad scenario files as editable scenario YAML and trajectory CSV.

For ``scene.xml`` it writes into the output folder ``scene.yaml`` (the scenario the XML file
is when given as it is, :data:`~gridsim.scenario.loader.COMMONROAD_DEFAULTS`, with its tracks
read from the CSV), ``scene.csv`` (the dynamic obstacles as tracks) and a copy of the file
as the map, ``maps/scene.xml``. Loading the YAML gives the same worlds as the XML file.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import yaml

from gridsim.errors import ScenarioError
from gridsim.outputs import write_text
from gridsim.scenario.loader import COMMONROAD_DEFAULTS, deep_merge
from gridsim.traffic.commonroad import read_tracks_commonroad, scene_id
from gridsim.traffic.library import write_tracks_csv


def import_commonroad(xml: str | Path, out: str | Path) -> Path:
    """Write the scenario YAML, the tracks CSV and the map of CommonRoad file ``xml`` into
    folder ``out``; returns the YAML's path."""
    xml, out = Path(xml), Path(out)
    if xml.suffix.lower() != ".xml":
        raise ScenarioError(f"{xml}: not a CommonRoad .xml file")
    tracks = read_tracks_commonroad(xml)
    if not tracks:
        raise ScenarioError(f"{xml}: no dynamic obstacle with at least 2 states to replay")
    stem = xml.stem
    (out / "maps").mkdir(parents=True, exist_ok=True)
    shutil.copyfile(xml, out / "maps" / xml.name)
    write_tracks_csv(tracks, out / f"{stem}.csv")
    doc = {
        "name": stem[:80],
        "description": f"CommonRoad scene {xml.name} (imported); one recorded vehicle is the ego",
        "road": {"type": "recorded", "map": f"maps/{xml.name}", "scene": scene_id(xml)},
        **deep_merge(COMMONROAD_DEFAULTS, {"traffic": {"library": [f"{stem}.csv"]}}),
    }
    path = out / f"{stem}.yaml"
    header = (
        f"# Imported from {xml.name} by `gridsim import`; edit freely, check with "
        "`gridsim validate`.\n"
    )
    write_text(path, header + yaml.safe_dump(doc, sort_keys=False))
    return path
