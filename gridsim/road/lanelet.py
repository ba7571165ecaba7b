"""Road maps from CommonRoad scenario XML (lanelets), parsed with ``xml.etree``.

Each ``<lanelet>`` has ``<leftBound>`` and ``<rightBound>`` point lists in metres; its drivable
polygon is the left bound followed by the reversed right bound, and its centre line the
mean of both bounds resampled to a common arc-length parameter. Lanelets without a
predecessor (successor) start (end) at the map's border: no road edge is placed across them.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from gridsim.errors import DataError
from gridsim.road.base import Lane, StaticRoad
from gridsim.road.polyline import Polyline

#: The largest map coordinate accepted [m] (UTM coordinates are below 1e7).
MAX_COORDINATE = 1e7


def _points(bound: ET.Element, where: str) -> np.ndarray:
    pts = []
    for pt in bound.findall("point"):
        try:
            pts.append((float(pt.findtext("x")), float(pt.findtext("y"))))
        except (TypeError, ValueError) as exc:
            raise DataError(f"{where}: a <point> lacks a numeric <x> or <y>") from exc
    if len(pts) < 2:
        raise DataError(f"{where}: needs at least 2 points, found {len(pts)}")
    arr = np.array(pts)
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{where}: non-finite coordinates")
    if np.abs(arr).max() > MAX_COORDINATE:
        raise DataError(f"{where}: coordinate {arr.flat[np.abs(arr).argmax()]:g} m is beyond "
                        f"+-{MAX_COORDINATE:g} m")  # fmt: skip
    return arr


def _resample(pts: np.ndarray, n: int) -> np.ndarray:
    line = Polyline(pts)
    return line.point_at(np.linspace(line.s[0], line.s[-1], n))[0]


def parse_commonroad(path: str | Path) -> ET.Element:
    """The root element of a CommonRoad XML file; :class:`DataError` if it is missing or
    malformed."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"CommonRoad file not found: {path}")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise DataError(f"{path}: not well-formed XML ({exc})") from exc
    if root.tag != "commonRoad":
        raise DataError(f"{path}: not a CommonRoad file (root element <{root.tag}>)")
    return root


def load_lanelet_road(path: str | Path) -> StaticRoad:
    """Build a :class:`StaticRoad` from the lanelets of a CommonRoad XML file."""
    path = Path(path)
    root = parse_commonroad(path)
    lanes, polygons, markings, ends = [], [], [], []
    has_pred = {r.get("ref") for ll in root.findall("lanelet") for r in ll.findall("successor")}
    has_succ = {r.get("ref") for ll in root.findall("lanelet") for r in ll.findall("predecessor")}
    for ll in root.findall("lanelet"):
        where = f"{path.name}: lanelet {ll.get('id')}"
        left_el, right_el = ll.find("leftBound"), ll.find("rightBound")
        if left_el is None or right_el is None:
            raise DataError(f"{where}: missing <leftBound> or <rightBound>")
        left = _points(left_el, where + " leftBound")
        right = _points(right_el, where + " rightBound")
        polygons.append(np.vstack([left, right[::-1]]))
        lid = ll.get("id")
        if ll.find("predecessor") is None and lid not in has_pred:
            ends.append([*left[0], *right[0]])
        if ll.find("successor") is None and lid not in has_succ:
            ends.append([*left[-1], *right[-1]])
        markings += [left, right]
        n = max(len(left), len(right), int(Polyline(left).length) + 2)
        left_r, right_r = _resample(left, n), _resample(right, n)
        centre = 0.5 * (left_r + right_r)
        width = float(np.median(np.linalg.norm(left_r - right_r, axis=1)))
        lanes.append(Lane(Polyline(centre), width))
    if not polygons:
        raise DataError(f"{path}: no <lanelet> elements")
    try:
        return StaticRoad(lanes, polygons, markings, open_ends=np.array(ends).reshape(-1, 4))
    except DataError as exc:
        raise DataError(f"{path}: {exc}") from None
