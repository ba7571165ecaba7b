"""A library of recorded vehicle trajectories loaded from CSV (or CommonRoad XML, see
:mod:`gridsim.traffic.commonroad`).

The CSV format is that of the shipped NGSIM file (see ``gridsim/data/ngsim/README.md``): one
row per state, columns ``scenario_id, track_id, time_s, x_m, y_m, heading_rad, speed_mps,
length_m, width_m`` (others ignored). Positions are rectangle centres in metres, headings
counter-clockwise from +x. Tracks are keyed by ``(scenario_id, track_id)``.
"""

from __future__ import annotations

import csv
from importlib import resources
from pathlib import Path

import numpy as np

from gridsim.errors import DataError
from gridsim.outputs import atomic_text, short_repr
from gridsim.traffic.commonroad import read_tracks_commonroad
from gridsim.traffic.track import Track

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
_NUMERIC = REQUIRED_COLUMNS[2:]


class TrajectoryLibrary:
    """Recorded tracks, from one or more CSV files."""

    def __init__(self, tracks: list[Track]) -> None:
        if not tracks:
            raise DataError("the trajectory library is empty")
        self.tracks = tracks
        self._by_key: dict[tuple[str, str], Track] = {}
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
        for p in paths:
            tracks += read_tracks(p)
        if not tracks:
            raise DataError(f"{', '.join(map(str, paths))}: no vehicle tracks (dynamic obstacles "
                            "with at least 2 states)")  # fmt: skip
        return cls(tracks)

    def scene(self, scenario_id: str) -> list[Track]:
        """All tracks of one recorded scene, in file order."""
        out = [t for t in self.tracks if t.scenario_id == scenario_id]
        if not out:
            known = sorted({t.scenario_id for t in self.tracks})
            raise DataError(f"no tracks for scene {scenario_id!r}; known scenes: {known}")
        return out

    def get(self, scenario_id: str, track_id: str) -> Track:
        try:
            return self._by_key[(scenario_id, str(track_id))]
        except KeyError:
            raise DataError(f"no track {track_id!r} in scene {scenario_id!r}") from None

    def select(self, min_duration: float = 0.0, max_length: float = np.inf) -> list[Track]:
        """Tracks at least ``min_duration`` seconds long and at most ``max_length`` metres."""
        return [t for t in self.tracks if t.duration >= min_duration and t.length <= max_length]


_BUILTIN: TrajectoryLibrary | None = None


def _builtin() -> TrajectoryLibrary:
    global _BUILTIN
    if _BUILTIN is None:
        ref = resources.files("gridsim") / "data" / "ngsim" / "ngsim_trajectories.csv"
        with resources.as_file(ref) as path:
            _BUILTIN = TrajectoryLibrary.from_csv(path)
    return _BUILTIN


def read_tracks(path: str | Path) -> list[Track]:
    """Tracks of a trajectory CSV, or of a CommonRoad XML file's dynamic obstacles."""
    if Path(path).suffix.lower() == ".xml":
        return read_tracks_commonroad(path)
    return read_tracks_csv(path)


def read_tracks_csv(path: str | Path) -> list[Track]:
    """Parse a trajectory CSV; raise :class:`DataError` naming the file, row and column."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"trajectory file not found: {path}")
    try:
        return _parse_tracks_csv(path)
    except UnicodeDecodeError as exc:
        raise DataError(
            f"{path}: not a UTF-8 text file (byte {exc.start}: {exc.reason}); save the CSV as UTF-8"
        ) from None


def _parse_tracks_csv(path: Path) -> list[Track]:
    with path.open(newline="", encoding="utf-8-sig") as fh:  # a BOM (Excel) is skipped
        reader = csv.DictReader(fh)
        header = reader.fieldnames or []
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing:
            raise DataError(f"{path}: missing column(s) {missing}; required: "
                            f"{list(REQUIRED_COLUMNS)}{_header_hint(header)}")  # fmt: skip
        groups: dict[tuple[str, str], list[list[float]]] = {}
        for lineno, row in enumerate(reader, start=2):
            vals = []
            for c in _NUMERIC:
                raw = row[c]
                try:
                    v = float(raw)
                except (TypeError, ValueError):
                    raise DataError(
                        f"{path}:{lineno}: column {c!r} is not a number: {short_repr(raw)}"
                    ) from None
                if not np.isfinite(v):
                    raise DataError(f"{path}:{lineno}: column {c!r} is {short_repr(raw)}; "
                                    "expected a finite number")  # fmt: skip
                vals.append(v)
            speed, length, width = vals[4:7]
            if speed < 0 or length <= 0 or width <= 0:
                raise DataError(
                    f"{path}:{lineno}: speed_mps must be >= 0 and length_m, width_m > 0, got "
                    f"{speed}, {length}, {width}"
                )
            groups.setdefault((row["scenario_id"], row["track_id"]), []).append(vals)
    if not groups:
        raise DataError(f"{path}: no data rows")
    tracks = []
    for (sid, tid), rows in groups.items():
        a = np.array(rows)
        order = np.argsort(a[:, 0], kind="stable")
        a = a[order]
        if np.any(np.diff(a[:, 0]) <= 0):
            raise DataError(f"{path}: track ({sid}, {tid}) has repeated time stamps")
        if len(a) < 2:
            raise DataError(f"{path}: track ({sid}, {tid}) has a single state; need at least 2")
        tracks.append(
            Track(
                sid,
                tid,
                a[:, 0],
                a[:, 1],
                a[:, 2],
                np.unwrap(a[:, 3]),
                a[:, 4],
                float(a[0, 5]),
                float(a[0, 6]),
                str(path),
            )
        )
    return tracks


def _header_hint(header: list[str]) -> str:
    """Why a header may lack the columns: another separator, or other letter case."""
    line = ",".join(header)
    for sep, name in ((";", "semicolons"), ("\t", "tabs"), ("|", "bars")):
        if sep in line:
            return f" (the header is separated by {name}; separate columns with commas)"
    if {h.strip().lower() for h in header} >= set(REQUIRED_COLUMNS):
        return " (column names are lower case, without spaces)"
    return ""


def write_tracks_csv(tracks: list[Track], path: str | Path) -> Path:
    """Write ``tracks`` as a trajectory CSV (:data:`REQUIRED_COLUMNS`) that
    :func:`read_tracks_csv` reads back exactly (floats in full precision)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_text(path) as fh:
        out = csv.writer(fh)
        out.writerow(REQUIRED_COLUMNS)
        for tr in tracks:
            for k in range(len(tr.t)):
                values = (tr.t[k], tr.x[k], tr.y[k], tr.heading[k], tr.speed[k])
                out.writerow([tr.scenario_id, tr.track_id, *(repr(float(v)) for v in values),
                              repr(tr.length), repr(tr.width)])  # fmt: skip
    return path
