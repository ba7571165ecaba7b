"""A library of recorded vehicle trajectories loaded from CSV (or CommonRoad XML, see
:mod:`gridsim.traffic.commonroad`).

The CSV format is that of the shipped NGSIM file (see ``gridsim/data/ngsim/README.md``): one
row per state, columns ``scenario_id, track_id, time_s, x_m, y_m, heading_rad, speed_mps,
length_m, width_m`` (others ignored). Positions are rectangle centres in metres, headings
counter-clockwise from +x. Tracks are keyed by ``(scenario_id, track_id)``.
"""

from __future__ import annotations

import csv
import dataclasses
import difflib
import math
import re
from importlib import resources
from pathlib import Path

import numpy as np

from gridsim.errors import DataError, archive_problem, not_there, warn_data
from gridsim.outputs import atomic_text, named, short_repr
from gridsim.traffic.commonroad import read_tracks_commonroad
from gridsim.traffic.track import (
    MAX_SPEED,
    Track,
    impossible_note,
    listed,
    refuse_mostly_impossible,
)

REQUIRED_COLUMNS = (
    "scenario_id",
    "track_id",
    "time_s",
    "x_m",
    "y_m",
    "heading_rad",
    "speed_mps",
    "length_m",
    "width_m",
)
#: An optional column: what each road user is (:attr:`~gridsim.traffic.track.Track.kind`).
KIND_COLUMN = "obstacle_type"
_NUMERIC = REQUIRED_COLUMNS[2:]


class TrajectoryLibrary:
    """Recorded tracks, from one or more CSV files."""

    def __init__(self, tracks: list[Track]) -> None:
        if not tracks:
            raise DataError("the trajectory library is empty")
        #: per scene recounted from its first whole second, that second [s] (a Unix-epoch
        #: clock's: :func:`_counted_from_scene_start`)
        self.time_origins = _time_origins(tracks)
        tracks = _joined_across_files(_counted_from_scene_start(tracks, self.time_origins))
        _warn_numbers_written_twice(tracks)
        self.tracks = tracks
        #: ``(file, reason)`` of the files of a folder or glob left out (they cannot be read)
        self.skipped: tuple[tuple[str, str], ...] = ()
        #: what the first scenario that reads the library says about it (its files' notes)
        self.notices: tuple[str, ...] = ()
        self._by_key: dict[tuple[str, str], Track] = {}
        self._scenes: dict[str, list[Track]] = {}  # scene id -> its tracks (found once)
        for t in tracks:
            key = (t.scenario_id, t.track_id)
            if key in self._by_key:
                other = self._by_key[key].source or "<tracks>"
                raise DataError(
                    f"{t.source or '<tracks>'}: track {t.track_id} of scene {t.scenario_id} is "
                    f"also in {other}; a scene's track ids must be unique"
                )
            self._by_key[key] = t

    def __len__(self) -> int:
        return len(self.tracks)

    @classmethod
    def builtin(cls) -> TrajectoryLibrary:
        """The NGSIM tracks shipped with gridsim."""
        return _builtin()

    @classmethod
    def from_csv(cls, *paths: str | Path) -> TrajectoryLibrary:
        return cls.from_files(*paths)

    @classmethod
    def from_files(cls, *paths: str | Path) -> TrajectoryLibrary:
        """Tracks of trajectory CSV files and CommonRoad XML files (by suffix)."""
        tracks: list[Track] = []
        singles: list = []
        for p in paths:
            tracks += read_tracks(p, singles)
        if not tracks:
            raise _no_tracks(", ".join(map(str, paths)))
        library = cls(tracks)
        for note in single_states_notes(library.tracks, singles, library.time_origins):
            warn_data(note)
        return library

    def scene(self, scenario_id: str) -> list[Track]:
        """All tracks of one recorded scene, in file order (a new list; the scene is looked
        for once: every world of a scene asks)."""
        out = self._scenes.get(scenario_id)
        if out is None:
            out = self._scenes[scenario_id] = [t for t in self.tracks
                                               if t.scenario_id == scenario_id]  # fmt: skip
        if not out:
            known = sorted({t.scenario_id for t in self.tracks})
            raise DataError(f"no tracks for scene {scenario_id!r}; known scenes: {known}")
        return list(out)

    def get(self, scenario_id: str, track_id: str) -> Track:
        try:
            return self._by_key[(scenario_id, str(track_id))]
        except KeyError:
            raise DataError(f"no track {track_id!r} in scene {scenario_id!r}") from None

    def select(self, min_duration: float = 0.0, max_length: float = np.inf) -> list[Track]:
        """Tracks at least ``min_duration`` seconds long and at most ``max_length`` metres."""
        return [t for t in self.tracks if t.duration >= min_duration and t.length <= max_length]


#: A whole number as a spreadsheet or pandas may write it: ``427``, ``0427``, ``427.0``.
_WHOLE_NUMBER = re.compile(r"(\d+)(?:\.0*)?")


def _warn_numbers_written_twice(tracks: list[Track]) -> None:
    """A warning naming the ids of a scene that are one number written two ways (``427``,
    ``0427``, ``427.0``: a spreadsheet's or pandas' export): they are read as two vehicles."""
    forms: dict[tuple[str, str], set[str]] = {}
    for t in tracks:
        tid = t.recorded_id or t.track_id
        number = _WHOLE_NUMBER.fullmatch(tid.strip())  # (as text: 64-bit ids stay exact)
        if number:
            forms.setdefault((t.scenario_id, number[1].lstrip("0") or "0"), set()).add(tid)
    twice = [f"{sid}: {' and '.join(sorted(ids))}" for (sid, _), ids in forms.items()
             if len(ids) > 1]  # fmt: skip
    if twice:
        listed = named(twice, sep="; ")
        warn_data(f"{len(twice)} track id(s) are one number written two ways, read as "
                  f"different vehicles ({listed}): write each id one way (a spreadsheet or "
                  "pandas export may add leading zeros or '.0')")  # fmt: skip


#: s: the time stamps of a scene that begins this far from 0 are counted from its first whole
#: second (rounded to the microsecond): float64 resolves 1e-10 s at 1e6 s, below the traffic
#: clock's tolerance (1e-9 s), but 2.4e-7 s at a Unix-epoch time (1.7e9 s), where vehicles
#: appeared a tick early or late (grids differed from the same scene counted from 0).
RECOUNTED_FROM = 1e6


def _time_origins(tracks: list[Track]) -> dict[str, int]:
    """The whole second [s] each scene of ``tracks`` whose first time stamp lies
    :data:`RECOUNTED_FROM` or more from 0 is counted from (its first stamp's)."""
    first: dict[str, float] = {}
    for t in tracks:
        first[t.scenario_id] = min(first.get(t.scenario_id, math.inf), float(t.t[0]))
    return {sid: math.floor(f) for sid, f in first.items() if abs(f) >= RECOUNTED_FROM}


def recounted(times: np.ndarray, origin: int) -> np.ndarray:
    """Time stamps [s] counted from ``origin`` [s] (rounded to the microsecond)."""
    return np.round(np.asarray(times, np.float64) - origin, 6)


def _counted_from_scene_start(tracks: list[Track], origins: dict[str, int]) -> list[Track]:
    """``tracks``, those of the scenes of ``origins`` (:func:`_time_origins`) counted from
    that second instead, said in a warning (a track's ``t`` then reads that much less; a
    scene is a scene id in every file of the library, so that files split by time keep one
    clock)."""
    if not origins:
        return tracks
    said = ", ".join(f"{sid} from {o:d} s" for sid, o in origins.items())
    warn_data(f"time stamps from {min(origins.values())} s on (a Unix-epoch clock?) are "
              f"counted from the scene's first whole second ({said}; float64 resolves only "
              "2e-7 s at 1.7e9 s: vehicles would appear a tick early or late); the tracks' "
              "times read that much less")  # fmt: skip
    return [dataclasses.replace(t, t=recounted(t.t, origins[t.scenario_id]))
            if t.scenario_id in origins else t for t in tracks]  # fmt: skip


def _joined_across_files(tracks: list[Track]) -> list[Track]:
    """``tracks`` with the vehicles a recording split into files by time joined: the rows of
    every piece of one scene and recorded id in several files (their times may share only
    identical rows at the boundary) put together and cut again where a pause shows another
    vehicle under the id (:func:`_pieces`: ``ID``, ``ID#2``, ...), with a warning; a piece
    of one state or of impossible data is left out, said in the warning (as a file's own
    are). The same id at overlapping times is refused (a :class:`DataError` naming both
    files)."""
    groups: dict[tuple[str, str], list[Track]] = {}
    for t in tracks:
        groups.setdefault((t.scenario_id, t.recorded_id or t.track_id), []).append(t)
    split = {key for key, group in groups.items() if len({g.source for g in group}) > 1}
    if not split:
        return tracks
    taken = {(t.scenario_id, t.track_id) for t in tracks  # (the joined pieces' names freed)
             if (t.scenario_id, t.recorded_id or t.track_id) not in split}  # fmt: skip
    out, joined, left_out = [], {}, []  # joined: (the files, in time order) -> the ids
    for t in tracks:
        key = (t.scenario_id, t.recorded_id or t.track_id)
        if key not in split:
            out.append(t)
        elif t is groups[key][0]:  # the vehicle in place of its first piece
            pieces = sorted(groups[key], key=lambda g: float(g.t[0]))
            out += _join(key, pieces, taken, left_out)
            files = tuple(dict.fromkeys(g.source or "<tracks>" for g in pieces))
            joined.setdefault(files, []).append(f"{key[0]}/{key[1]}")
    said = [f"{len(ids)} from {' into '.join(files)}: {named(ids)}"
            for files, ids in joined.items()]  # fmt: skip
    notes = [f"track(s) go on in another file at later times (a recording split into files "
             f"by time?), each joined and cut again where it pauses as another vehicle under "
             f"the same id: {'; '.join(said)}"]  # fmt: skip
    if left_out:
        notes.append(f"of those, {len(left_out)} piece(s) left out: {named(left_out)}")
    warn_data("; ".join(notes))
    return out


def _join(key: tuple[str, str], pieces: list[Track], taken: set,
          left_out: list[str]) -> list[Track]:  # fmt: skip
    """The tracks of one vehicle (``key``: scene and recorded id) from its ``pieces`` (of
    several files, in time order): their rows joined (an identical row in two files once),
    cut at pauses, each piece sized and sourced by its first row's file; ``taken``: the
    library's (scene, id) pairs (a cut's ``ID#2`` avoids them, and takes its own); a piece
    that cannot be a track is named in ``left_out``."""
    sid, rid = key
    for a, b in zip(pieces, pieces[1:], strict=False):
        shared = (a.t >= b.t[0]) & (a.t <= min(a.t[-1], b.t[-1]))
        same = a.source == b.source or (  # (one file's own pieces never overlap)
            shared.sum() <= 1 and (not shared.any() or _same_state(a, b, int(np.argmax(shared))))
        )
        if not same:
            raise DataError(f"{b.source or '<tracks>'}: track {rid} of scene {sid} is also in "
                            f"{a.source or '<tracks>'} at times that overlap ({a.t[0]:g}-"
                            f"{a.t[-1]:g} s there, {b.t[0]:g}-{b.t[-1]:g} s here); a scene's "
                            "track ids must be unique")  # fmt: skip
    # rows: t, x, y, heading, speed, length, width, piece
    rows = np.concatenate([np.column_stack([p.t, p.x, p.y, p.heading, p.speed,
                                            np.full(len(p.t), p.length),
                                            np.full(len(p.t), p.width),
                                            np.full(len(p.t), k)])
                           for k, p in enumerate(pieces)])  # fmt: skip
    rows = rows[np.argsort(rows[:, 0], kind="stable")]
    rows = rows[np.concatenate(([True], np.diff(rows[:, 0]) > 0))]  # a boundary row once
    cut = _pieces(rows)
    out, single, impossible = _piece_tracks(sid, rid, cut, taken,
                                            [pieces[int(a[0, 7])].source for a in cut],
                                            pieces[0].kind)  # fmt: skip
    taken.update((sid, t.track_id) for t in out)
    left_out += [f"{sid}/{name} (a single state)" for name, _ in single] + impossible
    return out


def _piece_tracks(sid: str, tid: str, pieces: list[np.ndarray], taken, sources: list[str],
                  kind: str = "") -> tuple[list[Track], list[tuple], list[str]]:  # fmt: skip
    """The tracks of the ``pieces`` (rows ``t, x, y, heading, speed, length, width``, by
    time; :func:`_pieces`) of id ``tid`` of scene ``sid``: named ``tid``, ``tid#2``, ... (a
    suffixed name already in ``taken``, (scene, id) pairs: another ``#``), each sized by its
    first row and read from ``sources[k]``, of ``kind`` (:attr:`Track.kind`); with the pieces
    of a single state (their name and row), left out, and the problems of those of impossible
    data, left out too."""
    tracks, single, impossible = [], [], []
    for k, piece in enumerate(pieces):
        name = tid if k == 0 else f"{tid}#{k + 1}"
        while k and (sid, name) in taken:  # an id the scene has already: another suffix
            name += "#"
        if len(piece) < 2:
            single.append((name, piece[0]))
            continue
        try:
            tracks.append(Track(sid, name, piece[:, 0], piece[:, 1], piece[:, 2],
                                np.unwrap(piece[:, 3]), piece[:, 4], float(piece[0, 5]),
                                float(piece[0, 6]), sources[k], tid, kind))  # fmt: skip
        except DataError as exc:  # impossible data: this piece
            impossible.append(str(exc))
    return tracks, single, impossible


def _same_state(a: Track, b: Track, k: int) -> bool:
    """Whether state ``k`` of ``a`` is ``b``'s first, exactly (a boundary row in both files)."""
    return all(float(getattr(a, f)[k]) == float(getattr(b, f)[0])
               for f in ("t", "x", "y", "speed"))  # fmt: skip


_BUILTIN: TrajectoryLibrary | None = None


def _builtin() -> TrajectoryLibrary:
    global _BUILTIN
    if _BUILTIN is None:
        ref = resources.files("gridsim") / "data" / "ngsim" / "ngsim_trajectories.csv"
        with resources.as_file(ref) as path:
            _BUILTIN = TrajectoryLibrary.from_csv(path)
    return _BUILTIN


def read_tracks(path: str | Path, singles: list | None = None) -> list[Track]:
    """Tracks of a trajectory CSV, or of a CommonRoad XML file's dynamic obstacles;
    ``singles``: see :func:`read_tracks_csv`."""
    if Path(path).suffix.lower() == ".xml":
        return read_tracks_commonroad(path)
    return read_tracks_csv(path, singles)


def read_library_file(path: str | Path, singles: list | None = None) -> list[Track]:
    """:func:`read_tracks`, refused (a :class:`DataError`) when the file holds no track."""
    tracks = read_tracks(path, singles)
    if not tracks:
        raise _no_tracks(str(path))
    return tracks


def _no_tracks(where: str) -> DataError:
    return DataError(f"{where}: no vehicle tracks (dynamic obstacles with at least 2 states)")


def single_states_notes(tracks: list[Track], singles: list,
                        origins: dict[str, int] | None = None) -> list[str]:  # fmt: skip
    """A note per file (for a :class:`DataWarning`) naming the tracks of a single state left out
    (``singles``: ``(file, scene, name, id, row)`` from :func:`read_tracks_csv`) that are not
    rows of ``tracks`` (the library's, joined across files, their scenes' clocks recounted
    from ``origins``: :attr:`TrajectoryLibrary.time_origins`): a vehicle's row at the
    boundary of a recording split into files by time is in both files, and nothing is
    lost."""
    origins = origins or {}
    rows: dict[tuple[str, str], list[np.ndarray]] = {}
    for t in tracks:
        rows.setdefault((t.scenario_id, t.recorded_id or t.track_id), []).append(
            np.column_stack([t.t, t.x, t.y])
        )
    lost: dict[str, list[str]] = {}
    for path, sid, name, tid, row in singles:
        if sid in origins:  # (on the file's clock)
            row = np.array([recounted(row[0], origins[sid]), *row[1:3]])
        kept = any(np.any(np.all(a == row[:3], axis=1)) for a in rows.get((sid, tid), []))
        if not kept:
            lost.setdefault(path, []).append(f"({sid}, {name})")
    return [f"{path}: {len(names)} track(s) with a single state left out (at least 2 are "
            f"needed): {named(names)}" for path, names in lost.items()]  # fmt: skip


def read_tracks_csv(path: str | Path, singles: list | None = None) -> list[Track]:
    """Parse a trajectory CSV; raise :class:`DataError` naming the file, row and column.
    Tracks of a single state are left out, said in the file's warning, or, with ``singles``,
    put in it (``(file, scene, name, id, row)``) for :func:`single_states_notes` once every
    file of a library is read."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"trajectory file not found: {not_there(path)}")
    try:
        return _parse_tracks_csv(path, singles)
    except UnicodeDecodeError as exc:
        archive = archive_problem(path)
        if archive:
            raise DataError(f"{path}: {archive}") from None
        raise DataError(
            f"{path}: not a UTF-8 text file (byte {exc.start}: {exc.reason}); save the CSV as UTF-8"
        ) from None


def _parse_tracks_csv(path: Path, singles: list | None) -> list[Track]:
    """The tracks of a trajectory CSV, in the order of their first row; each track's rows
    sorted by time (rows may come in any order). Rows are converted a block at a time (a
    file of a million rows reads in seconds, in little more memory than its numbers); every
    row that cannot be read is named, by line (and column)."""
    with path.open(newline="", encoding="utf-8-sig") as fh:  # a BOM (Excel) is skipped
        reader = csv.reader(fh)
        header = next(reader, None) or []
        if not header:
            raise DataError(f"{path}: the file is empty; a trajectory CSV starts with the header "
                            f"{','.join(REQUIRED_COLUMNS)}")  # fmt: skip
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing and (layout := _header_layout(header)):  # what is wrong, first
            raise DataError(f"{path}: {layout} (the header a trajectory CSV starts with: "
                            f"{','.join(REQUIRED_COLUMNS)})")  # fmt: skip
        if missing:
            raise DataError(f"{path}: missing column(s) {missing}; required: "
                            f"{list(REQUIRED_COLUMNS)}{_header_hint(header, missing)}")  # fmt: skip
        twice = [c for c in REQUIRED_COLUMNS if header.count(c) > 1]
        if twice:  # (which one holds the values? a column pasted twice, or one misnamed)
            cols = ", ".join(str(k + 1) for k, h in enumerate(header) if h == twice[0])
            raise DataError(f"{path}: column {twice[0]!r} appears {header.count(twice[0])} "
                            f"times in the header (columns {cols}); name each once")  # fmt: skip
        where = [header.index(c) for c in REQUIRED_COLUMNS]
        kind_at = header.index(KIND_COLUMN) if KIND_COLUMN in header else None
        kinds: dict[tuple[str, str], str] = {}  # track -> its first row's obstacle_type
        index: dict[tuple[str, str], int] = {}  # track -> its number, in order of first row
        blocks, groups, at, rows, lines = [], [], [], [], []
        gaps = _MissingValues()
        problems: list[tuple[int, str]] = []  # the rows that cannot be read: all named

        def convert() -> None:  # the rows read so far (those with a missing value left out)
            values, missing, unreadable = _block(header, where, rows, lines)
            problems.extend(unreadable)
            if problems:  # the file is refused: its numbers are not kept
                rows.clear()
                lines.clear()
                return
            gaps.note(values, missing, lines)
            keep = ~missing
            blocks.append(values[keep])
            at.append(np.array(lines, dtype=np.int64)[keep])
            groups.append([index.setdefault((r[where[0]].strip(), r[where[1]].strip()),
                                            len(index))
                           for r, kept in zip(rows, keep, strict=True) if kept])  # fmt: skip
            if kind_at is not None:
                for r, kept in zip(rows, keep, strict=True):
                    if kept and len(r) > kind_at:
                        kinds.setdefault((r[where[0]].strip(), r[where[1]].strip()),
                                         r[kind_at].strip())  # fmt: skip
            rows.clear()
            lines.clear()

        for row in reader:
            # (blank lines are skipped, and so are lines of spaces or of empty fields only: a
            # spreadsheet's trailing ",,,,,," rows)
            if row and (row[0].strip() or any(f.strip() for f in row)):
                if len(rows) == _BLOCK:  # (the file's last row stays in the last block)
                    convert()
                    if len(problems) >= MAX_UNREADABLE:
                        break
                rows.append(row)
                lines.append(reader.line_num)
        cut = None if problems else _cut_mid_write(path, header, where, rows, lines)
        if rows:
            convert()
    _refuse_unreadable(path, problems)
    if not blocks:
        raise DataError(f"{path}: no data rows")
    gaps.refuse_most(path)
    values = np.concatenate(blocks)
    group = np.concatenate([np.array(g, dtype=np.int64) for g in groups])
    order = np.lexsort((values[:, 0], group))  # by track, then time (stable: file order)
    values, group, line = values[order], group[order], np.concatenate(at)[order]
    bounds = np.flatnonzero(np.diff(group)) + 1
    tracks, split, single, resized, repeated, impossible = [], [], [], [], [], []
    for (sid, tid), a, rows_at in zip(index, np.split(values, bounds), np.split(line, bounds),
                                      strict=True):  # fmt: skip
        again = np.diff(a[:, 0]) <= 0  # (sorted by time: a time stamp given again)
        if np.any(again):
            conflict = np.flatnonzero(again & np.any(a[1:] != a[:-1], axis=1))
            if len(conflict):
                k = int(conflict[0])
                raise DataError(f"{path}: lines {rows_at[k]} and {rows_at[k + 1]}: track "
                                f"({sid}, {tid}) has two rows at time {a[k, 0]:g} s with other "
                                f"values{_same_time_hint(a[k], a[k + 1])}")  # fmt: skip
            repeated.append((int(np.count_nonzero(again)), int(rows_at[1:][again][0])))
            a = a[np.concatenate(([True], ~again))]  # rows given twice: read once
        pieces = _pieces(a)
        for p in pieces:  # (each a vehicle) its size is its first row's
            if np.any(np.ptp(p[:, 5:7], axis=0) > 0.1 * p[0, 5:7]):
                resized.append(f"{tid} ({p[:, 5].min():g}-{p[:, 5].max():g} x "
                               f"{p[:, 6].min():g}-{p[:, 6].max():g} m)")  # fmt: skip
                break
        if len(pieces) > 1:
            split.append((tid, [float(p[0, 0]) for p in pieces[1:]]))
        mine, ones, bad = _piece_tracks(sid, tid, pieces, index, [str(path)] * len(pieces),
                                        kinds.get((sid, tid), ""))  # fmt: skip
        tracks += mine
        if singles is None:
            single += [f"({sid}, {name})" for name, _ in ones]
        else:
            singles += [(str(path), sid, name, tid, row) for name, row in ones]
        # impossible data: the track left out, or the file (below)
        impossible += [problem.removeprefix(f"{path}: ") for problem in bad]
    refuse_mostly_impossible(path, len(tracks), impossible)
    notes = [text for text in (cut, gaps.note_text()) if text]
    _warn_tracks(path, split, single, resized, repeated, impossible, "; ".join(notes))
    if not tracks:
        raise DataError(f"{path}: no track with at least 2 states")
    return tracks


def _same_time_hint(a: np.ndarray, b: np.ndarray) -> str:
    """Why two rows ``(t, x, y, heading, speed, ...)`` of one track may share a time stamp:
    positions as far apart as the speed moves a car in a few tenths of a second are one car
    whose time stamps were rounded (25 Hz to 0.1 s); farther ones, two vehicles under one
    id."""
    gap = float(np.hypot(a[1] - b[1], a[2] - b[2]))
    if gap <= 0.3 * max(float(a[4]), float(b[4])) + 0.5:
        return (
            f" ({gap:.2g} m apart: are the time stamps rounded, say a 25 Hz recording's "
            "to 0.1 s? give them in full)"
        )
    return f" ({gap:.3g} m apart: two vehicles under one id?)"


def _cut_mid_write(path: Path, header: list[str], where: list[int], rows: list[list[str]],
                   lines: list[int]) -> str | None:  # fmt: skip
    """When the file's last row is cut short and the file does not end with a line break (a
    file cut while it was written, or copied before it was whole): that row taken off
    ``rows`` (and ``lines``), and what the warning says of it; else None."""
    if not rows or len(rows[-1]) >= max(where) + 1:
        return None
    with path.open("rb") as fh:
        fh.seek(-1, 2)
        if fh.read(1) in (b"\n", b"\r"):
            return None
    row, line = rows.pop(), lines.pop()
    return (f"its last line, line {line}, is cut short ({len(row)} of the header's "
            f"{len(header)} columns) and ends the file without a line break (a file cut while "
            "it was written?): that line is left out")  # fmt: skip


#: Rows converted at a time (a block's text is held in memory, not the file's).
#: Unreadable rows after which a refused file is read no further.
MAX_UNREADABLE = 10_000
_BLOCK = 1 << 16


def _block(header: list[str], where: list[int], rows: list[list[str]],
           lines: list[int]) -> tuple[np.ndarray, np.ndarray, list[tuple[int, str]]]:  # fmt: skip
    """The numbers ``(rows, 7)`` of a block of CSV ``rows`` (at file ``lines``), which rows
    miss a value (a cell of :data:`MISSING`, read as NaN), and ``(line, problem)`` of each
    row that cannot be read, its first problem as a reading from left to right finds it: a
    row cut short or with values past the header's columns, an empty scene or track id, a
    cell that is not a number or is infinite, then a negative speed or a size not above 0."""
    need, width = max(where) + 1, len(header)
    scene, track = where[0], where[1]
    empty = "column {!r} is empty; every row names its scene and track"

    def problem(row: list[str]) -> str | None:  # cut short, values slid (not trailing commas)
        if len(row) < need:
            return f"{len(row)} column(s), the header has {width} (a line cut short?)"
        if len(row) > width and any(f.strip() for f in row[width:]):
            return (f"{len(row)} column(s), the header has {width} (a comma inside a text "
                    "field that is not in quotes? its values would slide into the wrong "
                    "columns)")  # fmt: skip
        if not row[scene] or row[scene].isspace():
            return empty.format("scenario_id")
        if not row[track] or row[track].isspace():
            return empty.format("track_id")
        if "/" in row[track]:
            return (f"track_id {short_repr(row[track])} has a '/': a track of a collection of "
                    "scenes is named SCENE/ID (`--track`, `ego.track`), so such an id cannot "
                    "be told apart from one; replace the '/' (e.g. with '_')")  # fmt: skip
        return None

    bad = {k: said for k, row in enumerate(rows) if (said := problem(row))}  # row -> problem
    values = np.empty((len(rows), len(_NUMERIC)))
    for c, name in enumerate(_NUMERIC):
        at = where[c + 2]
        if bad:  # (those rows' cells may be missing or slid: read as NaN)
            raw = [row[at] if k not in bad else "nan" for k, row in enumerate(rows)]
        else:
            raw = [row[at] for row in rows]
        try:
            values[:, c] = np.array(raw, dtype=np.float64)
        except ValueError:  # an empty cell, "NA", ... or text: cell by cell
            for k, text in enumerate(raw):
                if text.strip().lower() in MISSING:
                    values[k, c] = np.nan
                elif is_number(text):
                    values[k, c] = float(text)
                else:
                    values[k, c] = np.nan
                    bad.setdefault(k, f"column {name!r} is not a number: {short_repr(text)}")
        for k in np.flatnonzero(np.isinf(values[:, c])).tolist():
            bad.setdefault(k, f"column {name!r} is {short_repr(raw[k])}; expected a finite "
                              "number")  # fmt: skip
    speed, length, size = values[:, 4], values[:, 5], values[:, 6]
    for k in np.flatnonzero((speed < 0) | (length <= 0) | (size <= 0)).tolist():
        bad.setdefault(k, f"speed_mps must be >= 0 and length_m, width_m > 0, got {speed[k]}, "
                          f"{length[k]}, {size[k]}")  # fmt: skip
    problems = [(lines[k], bad[k]) for k in sorted(bad)]
    return values, np.isnan(values).any(axis=1), problems


def _refuse_unreadable(path: Path, problems: list[tuple[int, str]]) -> None:
    """A :class:`DataError` naming the rows of ``path`` that cannot be read (``(line,
    problem)`` each, in file order): the rows of one problem together, the first
    :data:`~gridsim.traffic.track.NAMED_PROBLEMS` problems in full."""
    if len(problems) == 1:
        line, message = problems[0]
        raise DataError(f"{path}:{line}: {message}")
    if problems:
        head = f"{path}: {len(problems)} rows cannot be read:"
        if len(problems) >= MAX_UNREADABLE:  # (reading stopped there)
            head = f"{path}: {len(problems):,} rows or more cannot be read (read no further):"
        rows: dict[str, list[int]] = {}
        for line, message in problems:
            rows.setdefault(message, []).append(line)
        raise DataError(head + listed([f"{_lines(at)}: {message}" for message, at in rows.items()]))


def _lines(at: list[int]) -> str:
    """``line 7``, ``lines 2, 3, 9`` or ``lines 2, 3, 4, 5, 6 and 12 more``."""
    return f"line{'s' if len(at) > 1 else ''} {named(at)}"


#: A CSV most of whose rows miss a value (more than this share) is refused: a column not
#: filled in, or the wrong file, rather than a glitch.
MAX_MISSING_SHARE = 0.5

#: What a CSV cell that holds no value reads as (lower case, stripped): an empty cell and
#: the words spreadsheets and data frames write for a missing value.
MISSING = frozenset({"", "nan", "-nan", "na", "n/a", "#n/a", "null", "none"})


class _MissingValues:
    """The rows of a CSV left out for a missing value (:data:`MISSING`): how many of how
    many, and the first one's line and column."""

    def __init__(self) -> None:
        self.rows = self.missing = 0
        self.first: tuple[int, str] | None = None
        self.per_column = np.zeros(len(_NUMERIC), np.int64)

    def note(self, values: np.ndarray, missing: np.ndarray, lines: list[int]) -> None:
        """Count a block's rows (``values`` at file ``lines``; ``missing``: which miss one)."""
        self.rows += len(missing)
        count = int(np.count_nonzero(missing))
        if count and self.first is None:
            k = int(np.argmax(missing))
            column = _NUMERIC[int(np.argmax(np.isnan(values[k])))]
            self.first = (lines[k], column)
        self.missing += count
        if count:
            self.per_column += np.count_nonzero(np.isnan(values[missing]), axis=0)

    def _what(self) -> str:
        line, column = self.first or (0, "")
        return (f"{self.missing} of its {self.rows} rows miss a value (an empty or NaN cell; "
                f"the first at line {line}, column {column!r})")  # fmt: skip

    def refuse_most(self, path: Path) -> None:
        """A :class:`DataError` when more than :data:`MAX_MISSING_SHARE` of the rows
        miss a value (a column not filled in, or the wrong file, rather than a glitch)."""
        empty = [name for name, n in zip(_NUMERIC, self.per_column, strict=True)
                 if n == self.rows]  # fmt: skip
        if empty:
            raise DataError(f"{path}: column(s) {', '.join(map(repr, empty))} hold no value in "
                            "any row (empty or NaN cells)")  # fmt: skip
        if self.missing > MAX_MISSING_SHARE * self.rows:
            raise DataError(f"{path}: {self._what()}; fill them in, or leave out the rows "
                            "that cannot be")  # fmt: skip

    def note_text(self) -> str | None:
        """What the file's warning says of the rows left out, if any."""
        if not self.missing:
            return None
        return f"{self._what()}: those rows are left out, their tracks read without them"


#: s: a pause between two states of a track longer than this (and than ten of its usual
#: steps) ends it: what follows is another vehicle under the same id (NGSIM reuses ids)
SPLIT_GAP = 2.0


#: s: a shorter pause (and longer than three of the track's usual steps) ends the track too
#: where the vehicle comes back elsewhere than its motion on both sides takes it
#: (:func:`_reappears_elsewhere`)
SHORT_PAUSE = 0.5
#: m, and share of the move predicted: how far off the prediction a vehicle must come back
#: across a short pause to be another (the larger of the two)
REAPPEAR_OFF, REAPPEAR_SHARE = 5.0, 0.5
#: s: the span over which the velocity on each side of a pause is measured (single steps
#: carry the positions' noise: 0.1 m over 0.1 s is 1 m/s)
VELOCITY_SPAN = 0.5


def _pieces(a: np.ndarray) -> list[np.ndarray]:
    """A track's rows (sorted by time) cut where time pauses (:data:`SPLIT_GAP`), or pauses
    less and the vehicle reappears elsewhere (:data:`SHORT_PAUSE`), or where, without a
    pause, it moves on from somewhere no vehicle could reach (:func:`_handed_over`)."""
    dt = np.diff(a[:, 0])
    if not len(dt):
        return [a]
    usual = float(np.median(dt))
    long = dt > max(SPLIT_GAP, 10.0 * usual)
    short = np.flatnonzero(~long & (dt > max(SHORT_PAUSE, 3.0 * usual)))
    jumps = [k for k in short.tolist() if _reappears_elsewhere(a[:, 0], a[:, 1:3], k)]
    jumps += _handed_over(a[:, 0], a[:, 1:3])
    cuts = np.union1d(np.flatnonzero(long), np.array(jumps, dtype=np.int64)) + 1
    return np.split(a, cuts) if len(cuts) else [a]


#: s: rows away from where a track was, for less than this, before it comes back where its
#: motion takes it, are a glitch of several rows, not a vehicle (:func:`_handed_over`)
GLITCH_SPAN = 1.0


def _handed_over(t: np.ndarray, xy: np.ndarray) -> list[int]:
    """The steps ``k`` (rows ``k`` to ``k + 1``) across which an id passes to another vehicle
    without a pause: a move faster than :data:`~gridsim.traffic.track.MAX_SPEED` that neither
    row undoes (from row ``k - 1`` and to row ``k + 2`` it is as fast: not a one-row spike,
    which the glitch check names), with two rows or more on each side; a move out and one
    back within :data:`GLITCH_SPAN`, where the track goes on as if it had not left, are a
    glitch of several rows (left to the checks that refuse impossible data)."""

    def fast(i, j):
        return np.hypot(*(xy[j] - xy[i]).T) > MAX_SPEED * (t[j] - t[i])

    k = np.arange(1, len(t) - 2)  # (each side keeps two rows: one alone is no vehicle)
    cuts = k[fast(k, k + 1) & fast(k - 1, k + 1) & fast(k, k + 2)].tolist()
    glitches = {c for a, b in zip(cuts, cuts[1:], strict=False)
                if t[b + 1] - t[a + 1] < GLITCH_SPAN and not fast(a, b + 1)
                for c in (a, b)}  # fmt: skip
    return [c for c in cuts if c not in glitches]


def _reappears_elsewhere(t: np.ndarray, xy: np.ndarray, k: int) -> bool:
    """Whether the move of a track's positions ``xy`` [m] at times ``t`` [s] over the pause
    between rows ``k`` and ``k + 1`` is off what its motion on both sides predicts by more
    than :data:`REAPPEAR_OFF` and :data:`REAPPEAR_SHARE` of the prediction: the mean of the
    velocities over :data:`VELOCITY_SPAN` before and after it (from positions, not the
    heading column, which may be in degrees; without samples on one side, the other's)
    times the pause. Another vehicle under the same id (NGSIM reuses ids) comes back
    behind, ahead or beside; a vehicle whose samples drop out does not."""
    before = int(np.searchsorted(t, t[k] - VELOCITY_SPAN, side="right")) - 1
    before = min(max(before, 0), k - 1)  # (at least one step, within the track)
    after = int(np.searchsorted(t, t[k + 1] + VELOCITY_SPAN, side="left"))
    after = max(min(after, len(t) - 1), k + 2)
    sides = [(xy[b] - xy[a]) / (t[b] - t[a]) for a, b in ((before, k), (k + 1, after))
             if 0 <= a < b < len(t)]  # fmt: skip
    predicted = 0.5 * (sides[0] + sides[-1]) * (t[k + 1] - t[k])
    error = float(np.hypot(*(xy[k + 1] - xy[k] - predicted)))
    return error > max(REAPPEAR_OFF, REAPPEAR_SHARE * float(np.hypot(*predicted)))


def _warn_tracks(path: Path, split: list, single: list, resized: list,
                 repeated: list, impossible: list, rows_left_out: str) -> None:  # fmt: skip
    """One :class:`DataWarning` naming the tracks cut at a pause, those left out (a single
    state, or ``impossible`` data: each one's problem), those whose size varies, the rows
    given twice (``(count, first line)`` per track) and (``rows_left_out``, if not empty)
    the rows left out (a missing value, a last line cut short)."""
    parts = [rows_left_out] if rows_left_out else []
    if impossible:
        parts.append(impossible_note(impossible))
    if repeated:
        count = sum(n for n, _ in repeated)
        parts.append(f"{count} row(s) repeat an earlier one exactly (the first at line "
                     f"{min(first for _, first in repeated)}): each is read once")  # fmt: skip
    if resized:
        parts.append(f"{len(resized)} track(s) change size by more than 10 % from row to row "
                     f"(a vehicle has one size: its first row's is used): "
                     f"{named(resized)}")  # fmt: skip
    if split:
        cuts = [f"{tid} at t = {', '.join(f'{t:g}' for t in times)} s" for tid, times in split]
        parts.append(
            f"{len(split)} track id(s) pause more than {SPLIT_GAP:g} s (or {SHORT_PAUSE:g} s and "
            f"come back elsewhere than their motion takes them, or jump farther than a "
            f"vehicle drives) and go on as another vehicle (a reused id?), split into ID, "
            f"ID#2, ...: {named(cuts, sep='; ')}"
        )
    if single:
        parts.append(f"{len(single)} track(s) with a single state left out (at least 2 are "
                     f"needed): {named(single)}")  # fmt: skip
    if parts:
        warn_data(f"{path}: " + "; ".join(parts))


def is_number(text: str) -> bool:
    """Whether ``text`` reads as a number (``float(text)``: what a CSV cell and a scenario
    key given as text take)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


#: Unit suffixes of column names: ``speed_mph`` for ``speed_mps`` is another unit, not a typo.
_UNIT_SUFFIXES = {"s", "ms", "m", "ft", "mps", "mph", "kmh", "kph", "fps", "rad", "deg"}


def _header_layout(header: list[str]) -> str | None:
    """What is wrong with a header that is not one of columns named by commas: a comment
    line before it, or another separator; None when it is."""
    line = ",".join(header)
    if line.lstrip().startswith("#"):
        return (f"the first line is a comment ({short_repr(line)}): a trajectory CSV's first "
                "line is its header; remove the comment lines")  # fmt: skip
    for sep, name in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")):
        if sep in line:
            return f"the header is separated by {name}; separate columns with commas"
    return None


def _header_hint(header: list[str], missing: list[str]) -> str:
    """Why a header may lack the ``missing`` columns: other letter case, a misspelt name or
    another unit's."""
    if {h.strip().lower() for h in header} >= set(REQUIRED_COLUMNS):
        return " (column names are lower case, without spaces)"
    extra = [h for h in header if h not in REQUIRED_COLUMNS]
    guesses = []  # (a misspelt name, or another unit's: speed_mph for speed_mps)
    for column in missing:
        if close := difflib.get_close_matches(column, extra, n=1, cutoff=0.75):
            units = {close[0].rsplit("_", 1)[-1], column.rsplit("_", 1)[-1]}
            other = len(units) == 2 and units <= _UNIT_SUFFIXES
            guesses.append(f"is {close[0]!r} meant to be {column!r}"
                           + (", its values converted?" if other else "?"))  # fmt: skip
    return f" ({'; '.join(guesses[:3])})" if guesses else ""


def write_tracks_csv(tracks: list[Track], path: str | Path) -> Path:
    """Write ``tracks`` as a trajectory CSV (:data:`REQUIRED_COLUMNS`, and
    :data:`KIND_COLUMN` when a track has a kind) that :func:`read_tracks_csv` reads back
    exactly (floats in full precision)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    kinds = any(tr.kind for tr in tracks)
    with atomic_text(path) as fh:
        out = csv.writer(fh)
        out.writerow(REQUIRED_COLUMNS + ((KIND_COLUMN,) if kinds else ()))
        for tr in tracks:
            kind = [tr.kind] if kinds else []
            for k in range(len(tr.t)):
                values = (tr.t[k], tr.x[k], tr.y[k], tr.heading[k], tr.speed[k])
                out.writerow([tr.scenario_id, tr.track_id, *(repr(float(v)) for v in values),
                              repr(tr.length), repr(tr.width), *kind])  # fmt: skip
    return path
