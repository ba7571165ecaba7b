"""Road maps from CommonRoad scenario XML (lanelets), parsed with ``xml.etree``.

Each ``<lanelet>`` has ``<leftBound>`` and ``<rightBound>`` point lists in metres; its drivable
polygon is the left bound followed by the reversed right bound, and its centre line the
mean of both bounds resampled to a common arc-length parameter. Lanelets without a
predecessor (successor) start (end) at the map's border: no road edge is placed across them.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from gridsim.errors import DataError, archive_problem, not_there
from gridsim.frames import MAX_COORDINATE
from gridsim.road.base import Lane, StaticRoad
from gridsim.road.polyline import Polyline

#: A lanelet smaller than this [m^2] is degenerate (its bounds coincide).
MIN_AREA = 1e-3


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
    if not np.any(np.hypot(*np.diff(arr, axis=0).T) > 0):
        raise DataError(f"{where}: all its points coincide (at {arr[0, 0]:g}, {arr[0, 1]:g}); "
                        "a bound needs 2 distinct points")  # fmt: skip
    return arr


def _area(polygon: np.ndarray) -> float:
    """Area [m^2] of a simple polygon ``(N, 2)`` (shoelace formula, either orientation)."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _resample(pts: np.ndarray, n: int) -> np.ndarray:
    line = Polyline(pts)
    return line.point_at(np.linspace(line.s[0], line.s[-1], n))[0]


#: The elements that sit directly under a CommonRoad file's root and hold the bulk of it.
_TOP_LEVEL = frozenset({"lanelet", "obstacle", "dynamicObstacle", "staticObstacle",
                        "environmentObstacle", "phantomObstacle", "trafficSign", "trafficLight",
                        "intersection", "planningProblem"})  # fmt: skip


def commonroad_root(path: str | Path) -> dict[str, str]:
    """The root attributes of a CommonRoad XML file (reads only the root element);
    :class:`DataError` if the file is missing, malformed or not a CommonRoad file."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"CommonRoad file not found: {not_there(path)}")
    try:
        with open(path, "rb") as fh:  # (iterparse closes a file it opened only at its end)
            _, root = next(ET.iterparse(fh, events=("start",)))
    except (ET.ParseError, StopIteration) as exc:
        archive = archive_problem(path)
        if archive:
            raise DataError(f"{path}: {archive}") from None
        raise DataError(f"{path}: not well-formed XML ({exc}){_text_hint(path)}") from None
    if root.tag != "commonRoad":
        raise DataError(f"{path}: not a CommonRoad file (root element <{root.tag}>)")
    return dict(root.attrib)


def _text_hint(path: Path) -> str:
    """A hint when a file that is not XML looks like a trajectory CSV (a ``road.map`` that
    names the tracks instead of the map)."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            first = fh.readline(4096)  # (a binary file has no line to end)
    except OSError:
        return ""
    if "," in first and "track_id" in first:
        return ": a trajectory CSV? a map is a CommonRoad .xml file (tracks go in traffic.library)"
    return ""


def iter_commonroad(path: str | Path, tags: tuple[str, ...]) -> Iterator[ET.Element]:
    """The definitions (elements with an ``id``; references such as a goal's
    ``<lanelet ref=...>`` are skipped) of a CommonRoad XML file whose tag is in ``tags``
    (top-level elements: lanelets, obstacles), in file order, streamed: each is emptied once
    the caller has it, and so are the other top-level elements, so memory does not grow with
    the file.
    :class:`DataError` if the file is missing, malformed or not a CommonRoad file."""
    commonroad_root(path)
    try:
        with open(path, "rb") as fh:  # closed also when the caller stops early
            for _, el in ET.iterparse(fh, events=("end",)):
                if el.tag in _TOP_LEVEL:
                    if el.tag in tags and "id" in el.attrib:
                        yield el
                    el.clear()
    except ET.ParseError as exc:
        raise DataError(f"{path}: not well-formed XML ({exc})") from None


def _lanelet(ll: ET.Element, path: Path) -> dict:
    """A ``<lanelet>``'s id, bounds ``(N, 2)`` [m] and the ids it names as predecessors and
    successors."""
    where = f"{path.name}: lanelet {ll.get('id')}"
    left_el, right_el = ll.find("leftBound"), ll.find("rightBound")
    if left_el is None or right_el is None:
        raise DataError(f"{where}: missing <leftBound> or <rightBound>")
    return {
        "id": ll.get("id"),
        "left": _points(left_el, where + " leftBound"),
        "right": _points(right_el, where + " rightBound"),
        "predecessors": [r.get("ref") for r in ll.findall("predecessor")],
        "successors": [r.get("ref") for r in ll.findall("successor")],
    }


def load_lanelet_road(path: str | Path) -> StaticRoad:
    """Build a :class:`StaticRoad` from the lanelets of a CommonRoad XML file."""
    path = Path(path)
    lanelets = [_lanelet(el, path) for el in iter_commonroad(path, ("lanelet",))]
    twice = sorted(i for i, n in Counter(ll["id"] for ll in lanelets).items() if n > 1)
    if twice:
        raise DataError(f"{path.name}: lanelet id {twice[0]} appears twice (ids must be unique)")
    lanes, polygons, markings, ends = [], [], [], []
    has_pred = {ref for ll in lanelets for ref in ll["successors"]}
    has_succ = {ref for ll in lanelets for ref in ll["predecessors"]}
    for ll in lanelets:
        left, right, lid = ll["left"], ll["right"], ll["id"]
        polygon = np.vstack([left, right[::-1]])
        if _area(polygon) < MIN_AREA:
            raise DataError(f"{path.name}: lanelet {lid} has no area (its bounds coincide); "
                            f"at least {MIN_AREA:g} m^2 is needed")  # fmt: skip
        polygons.append(polygon)
        if not ll["predecessors"] and lid not in has_pred:
            ends.append([*left[0], *right[0]])
        if not ll["successors"] and lid not in has_succ:
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
