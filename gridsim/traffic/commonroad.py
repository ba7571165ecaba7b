"""Recorded vehicles from CommonRoad scenario XML: the dynamic obstacles as :class:`Track`.

Both layouts are read: 2018 (``<obstacle>`` with ``<role>dynamic</role>``) and 2020a
(``<dynamicObstacle>``). A state's ``<time>`` is a step index; times in seconds are steps
times the root's ``timeStepSize``. Values are ``<exact>`` or the middle of
``<intervalStart>``/``<intervalEnd>``; a missing ``<velocity>`` is derived from the positions.
Shapes: ``<rectangle>`` (length, width) or ``<circle>`` (a square of its diameter).
Obstacles with a single state (nothing to replay; with a warning) and static obstacles are
left out.

The scene id of a file (:func:`scene_id`) is the root's ``benchmarkID`` attribute, else the
file's stem; tracks read from it carry it as ``scenario_id``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from gridsim.errors import DataError, warn_data
from gridsim.outputs import named, short_repr
from gridsim.road.lanelet import commonroad_root, iter_commonroad
from gridsim.traffic.track import Track, impossible_note, refuse_mostly_impossible


def _scene_id(root_attrib: dict, path: Path) -> str:
    return root_attrib.get("benchmarkID") or path.stem


def scene_id(path: str | Path) -> str:
    """The scene id of a CommonRoad file: its root's ``benchmarkID`` (or the file's stem).
    Reads only the root element."""
    return _scene_id(commonroad_root(path), Path(path))


def _value(el: ET.Element | None, where: str) -> float | None:
    """``<exact>`` or the middle of an interval under ``el`` (``None`` if ``el`` is)."""
    if el is None:
        return None
    try:
        exact = el.findtext("exact")
        if exact is not None:
            return float(exact)
        lo, hi = el.findtext("intervalStart"), el.findtext("intervalEnd")
        if lo is not None and hi is not None:
            return 0.5 * (float(lo) + float(hi))
    except ValueError as exc:
        raise DataError(f"{where}: <{el.tag}> is not a number ({exc})") from None
    raise DataError(f"{where}: <{el.tag}> has neither <exact> nor an interval")


def _state(st: ET.Element, where: str) -> tuple[float, float, float, float, float | None]:
    """``(step, x, y, orientation, velocity or None)`` of a ``<state>``/``<initialState>``
    (``where``: the file, the obstacle and which of its states it is)."""
    point = st.find("position/point")
    if point is None:
        raise DataError(f"{where}: no <position><point> (shapes are not supported)")
    try:
        x, y = float(point.findtext("x")), float(point.findtext("y"))
    except (TypeError, ValueError):
        raise DataError(f"{where}: its <point> lacks a numeric <x> or <y>") from None
    step = _value(st.find("time"), where)
    heading = _value(st.find("orientation"), where)
    missing = [tag for tag, v in (("<time>", step), ("<orientation>", heading)) if v is None]
    if missing:
        raise DataError(f"{where}: no {' or '.join(missing)}")
    return step, x, y, heading, _value(st.find("velocity"), where)


def _at(st: ET.Element) -> str:
    """`` (time step N)`` of a state whose ``<time><exact>`` reads, for its messages."""
    exact = st.findtext("time/exact")
    return f" (time step {exact.strip()})" if exact and exact.strip() else ""


def _size(obstacle: ET.Element, where: str) -> tuple[float, float]:
    rect, circle = obstacle.find("shape/rectangle"), obstacle.find("shape/circle")
    if rect is None and circle is None:
        raise DataError(f"{where}: <shape> must be a <rectangle> or a <circle>")
    try:
        if rect is not None:
            length, width = float(rect.findtext("length")), float(rect.findtext("width"))
        else:
            length = width = 2.0 * float(circle.findtext("radius"))
    except (TypeError, ValueError):
        raise DataError(f"{where}: the shape's size is missing or not a number") from None
    if not (length > 0 and width > 0):
        raise DataError(f"{where}: shape size must be > 0, got {length} x {width}")
    return length, width


def _is_dynamic(obstacle: ET.Element) -> bool:
    """A 2020a ``<dynamicObstacle>`` or a 2018 ``<obstacle>`` with ``<role>dynamic</role>``."""
    if obstacle.tag == "dynamicObstacle":
        return True
    return (obstacle.findtext("role") or "").strip() == "dynamic"


def read_tracks_commonroad(path: str | Path) -> list[Track]:
    """The dynamic obstacles of a CommonRoad file as tracks (file order). An obstacle that
    cannot be read or is impossible data (:func:`~gridsim.traffic.track.track_data_problem`)
    is left out with a warning naming the file, the obstacle and the state, unless most are:
    then a :class:`DataError` names them all (:func:`~gridsim.traffic.track.
    refuse_mostly_impossible`). The file is streamed: memory grows with the tracks, not with
    the XML."""
    path = Path(path)
    attrib = commonroad_root(path)
    tracks, dt, sid, seen = [], None, _scene_id(attrib, path), set()
    impossible: list[str] = []
    single: list[str] = []  # dynamic obstacles with one state: nothing to replay
    for ob in iter_commonroad(path, ("obstacle", "dynamicObstacle")):
        if dt is None:
            dt = _time_step(attrib, path)
        if ob.get("id") in seen:
            raise DataError(f"{path}: obstacle id {ob.get('id')} appears twice (must be unique)")
        seen.add(ob.get("id"))
        if _is_dynamic(ob):
            try:
                track = _track(ob, path, sid, dt)
            except DataError as exc:  # the obstacle left out, or the file (below)
                impossible.append(str(exc).removeprefix(f"{path}: "))
                continue
            if track is not None:
                tracks.append(track)
            else:
                single.append(str(ob.get("id")))
    refuse_mostly_impossible(path, len(tracks), impossible)
    notes = [impossible_note(impossible)] if impossible else []
    if single:
        notes.append(f"{len(single)} dynamic obstacle(s) with a single state left out (at "
                     f"least 2 are needed): {named(single)}")  # fmt: skip
    if notes:
        warn_data(f"{path}: " + "; ".join(notes))
    return tracks


def _time_step(attrib: dict, path: Path) -> float:
    text = attrib.get("timeStepSize")
    if text is None:
        raise DataError(f"{path}: the root has no timeStepSize (the seconds per time step)")
    try:
        dt = float(text)
    except ValueError:
        comma = " (a decimal point, not a comma)" if "," in text else ""
        raise DataError(f"{path}: timeStepSize {short_repr(text)} is not a number"
                        f"{comma}") from None  # fmt: skip
    if not dt > 0:
        raise DataError(f"{path}: timeStepSize must be > 0, got {dt}")
    return dt


def _track(ob: ET.Element, path: Path, sid: str, dt: float) -> Track | None:
    """One dynamic obstacle as a track (``None`` if it has a single state)."""
    where = f"{path}: obstacle {ob.get('id')}"
    first, rest = ob.find("initialState"), ob.findall("trajectory/state")
    states = [] if first is None else [_state(first, f"{where}: its <initialState>")]
    states += [_state(st, f"{where}: <state> {k} of its trajectory{_at(st)}")
               for k, st in enumerate(rest, 1)]  # fmt: skip
    if len(states) < 2:
        return None
    a = np.array([s[:4] for s in states])
    order = np.argsort(a[:, 0], kind="stable")
    a = a[order]
    if np.nanmin(a[:, 0]) < 0:
        raise DataError(f"{where}: time step {np.nanmin(a[:, 0]):g} is negative (steps count "
                        "from 0)")  # fmt: skip
    repeated = np.flatnonzero(np.diff(a[:, 0]) == 0)
    if len(repeated):
        raise DataError(f"{where}: time step {a[repeated[0], 0]:g} appears twice")
    t = a[:, 0] * dt
    v = np.array([states[k][4] for k in order], dtype=object)
    if any(s is None for s in v):  # derive from the positions
        with np.errstate(all="ignore"):  # non-finite positions: Track names them
            seg = np.hypot(np.diff(a[:, 1]), np.diff(a[:, 2])) / np.diff(t)
        speed = np.append(seg, seg[-1])
    else:
        speed = v.astype(float)
    length, width = _size(ob, where)
    heading = np.unwrap(a[:, 3]) if np.all(np.isfinite(a[:, 3])) else a[:, 3]  # Track names it
    kind = (ob.findtext("type") or "").strip()
    return Track(sid, str(ob.get("id")), t, a[:, 1], a[:, 2], heading, speed,
                 length, width, str(path), kind=kind)  # fmt: skip
