"""What the scenario families share when they build a world: the ego's parameters, files
named by a scenario (built-in or relative to it), trajectory libraries, the split of a reset
seed into independent streams, and the human profiles of generated traffic."""

from __future__ import annotations

import dataclasses
import glob
import hashlib
import time
import warnings
from functools import lru_cache
from pathlib import Path

import numpy as np

from gridsim.errors import DataError, DataWarning, ScenarioError, not_there, warn_data
from gridsim.outputs import named
from gridsim.road.polyline import Polyline
from gridsim.scenario.checks import SceneReport, feet_hint, library_report
from gridsim.scenario.family import is_recorded
from gridsim.scenario.schema import MAX_WHEELBASE_SHARE, Scenario, VehicleConfig
from gridsim.traffic.library import (
    TrajectoryLibrary,
    read_library_file,
    single_states_notes,
)
from gridsim.traffic.sources import SpeedBounds
from gridsim.traffic.track import Track
from gridsim.vehicle.kinematics import BicycleParams

#: Recorded tracks shorter than this [s] are neither human profiles nor egos.
MIN_TRACK_SECONDS = 2.0


def vehicle_params(
    cfg: VehicleConfig, length: float | None = None, width: float | None = None
) -> BicycleParams:
    """Bicycle parameters from the YAML vehicle block (angles converted to radians)."""
    length = cfg.length if length is None else length
    width = cfg.width if width is None else width
    wheelbase = min(cfg.wheelbase, MAX_WHEELBASE_SHARE * length)  # (docs/scenarios.md)
    return BicycleParams(
        wheelbase=wheelbase,
        length=length,
        width=width,
        center_offset=0.5 * wheelbase,
        v_min=cfg.v_min,
        v_max=cfg.v_max,
        a_max=cfg.a_max,
        b_max=cfg.b_max,
        delta_max=np.deg2rad(cfg.max_steer_deg),
        v_delta_max=np.deg2rad(cfg.max_steer_rate_deg),
    )


def resolve(
    scenario: Scenario, ref: str, builtin_dir: tuple[str, ...], suffix: str, key: str
) -> Path:
    """The file ``ref`` of the scenario's key ``key`` names: ``builtin:NAME`` (the shipped
    ``NAME + suffix`` in ``builtin_dir``), or a path relative to the scenario's folder; else a
    :class:`ScenarioError` naming the key, and the built-in files when one was meant."""
    from importlib import resources

    shipped = resources.files("gridsim").joinpath(*builtin_dir)

    def names() -> list[str]:  # (listed only for a message: resolve runs on every reset)
        return sorted(f.name.removesuffix(suffix) for f in shipped.iterdir()
                      if f.name.endswith(suffix))  # fmt: skip

    if ref.startswith("builtin:"):
        name = ref.split(":", 1)[1]
        entry = shipped.joinpath(name + suffix)
        if not entry.is_file():
            listed = ", ".join(f"builtin:{n}" for n in names())
            raise ScenarioError(f"{scenario.source}: {key} {ref!r}: no such built-in file (they "
                                f"are named without {suffix}): {listed}")  # fmt: skip
        return Path(str(entry))
    path = Path(ref)
    if not path.is_absolute() and scenario.base_dir is not None:
        path = scenario.base_dir / path
    if path.is_dir():
        raise ScenarioError(f"{scenario.source}: {key}: {ref!r} is a folder (resolved to "
                            f"{path}); it names one {suffix} file")  # fmt: skip
    if not path.is_file():
        meant = Path(ref).name.removesuffix(suffix)
        hint = f"; did you mean 'builtin:{meant}'?" if meant in names() else ""
        raise ScenarioError(f"{scenario.source}: {key}: file not found: {ref!r} (resolved to "
                            f"{not_there(path)}){hint}")  # fmt: skip
    return path


#: A file changed less than this long ago [s] is keyed by its content too (:func:`stamped`):
#: an edit within the file system's timestamp resolution keeps its time stamp.
RECENT_SECONDS = 2.0


def stamped(path: Path) -> tuple:
    """A file as a cache key, so that a file edited on disk is read again: its path,
    modification and change times, size and inode, and, if it changed in the last
    :data:`RECENT_SECONDS` (when an edit may keep the time stamps), a digest of its content.
    A file that is not there (a broken link) is its path and that (reading it says why)."""
    try:
        st = path.stat()
    except FileNotFoundError:
        return (str(path), "not there")
    key = (str(path), st.st_mtime_ns, st.st_ctime_ns, st.st_size, st.st_ino)
    if time.time_ns() - max(st.st_mtime_ns, st.st_ctime_ns) < RECENT_SECONDS * 1e9:
        key += (hashlib.blake2b(path.read_bytes(), digest_size=16).hexdigest(),)
    return key


def map_path(scenario: Scenario) -> Path:
    """The CommonRoad file of a recorded scenario's ``road.map``."""
    return resolve(scenario, scenario.config.road.map, ("data", "ngsim", "commonroad-xml"), ".xml",
                   "road.map")  # fmt: skip


def library_for(scenario: Scenario) -> TrajectoryLibrary:
    """The tracks of ``traffic.library``: ``builtin``, ``scene`` (the recorded map file's
    dynamic obstacles) and trajectory files (CSV or CommonRoad XML)."""
    try:
        library = _library(_library_files(scenario))
    except DataError as exc:  # (none of its files can be read)
        raise DataError(f"{scenario.source}: {exc}") from None
    if library.notices:  # said once, with the first scenario that reads the library
        notices, library.notices = library.notices, ()
        for notice in notices:
            warn_data(f"{scenario.source}: {notice}")
    return library


def _library_files(scenario: Scenario) -> tuple:
    """``traffic.library`` as ``("builtin", False)`` or ``(file stamp, found)``
    (:func:`stamped`; ``found``: the file was found in a folder or glob)."""
    return tuple(("builtin", False) if f == "builtin" else (stamped(f), found)
                 for f, found in _library_refs(scenario))  # fmt: skip


def _library_refs(scenario: Scenario) -> list[tuple]:
    """``traffic.library`` as ``("builtin", False)`` or ``(path, found)`` of its files
    (``found``: in a folder or glob, not named)."""
    files: list = []
    for ref in scenario.config.traffic.library:
        if ref == "builtin":
            files.append(("builtin", False))
        elif ref == "scene":
            if not is_recorded(scenario):
                raise ScenarioError(
                    f"{scenario.source}: traffic.library 'scene' needs road.type recorded (the "
                    "tracks of its CommonRoad map file)"
                )
            files.append((map_path(scenario), False))
        else:
            paths, found = _library_paths(scenario, ref)
            files += [(f, found) for f in paths]
    return files


def matching_files(folder_or_pattern: Path | str, suffixes: tuple[str, ...]) -> list[Path]:
    """The files whose suffix (in any case) is one of ``suffixes`` in a folder, or matching a
    glob pattern (``**`` recursive), sorted; a broken link among them too (reading it then
    says so: an unmounted share's file was left out without a word). A file named twice
    (links to it, a ``**`` glob through a link to a folder above) is listed once, by its
    shortest name (not a link's, if it has one), and a warning says how many names were left
    out."""
    path = Path(folder_or_pattern)
    if path.is_dir():
        found = path.iterdir()
    else:
        found = map(Path, glob.glob(str(folder_or_pattern), recursive=True))
    named: dict[Path, Path] = {}  # each file's shortest name (the fewest folders, not a link)
    repeated = looped = 0
    for f in sorted(found, key=lambda f: (len(f.parts), f.is_symlink(), f)):
        if f.suffix.lower() not in suffixes or not (f.is_file() or f.is_symlink()):
            continue
        try:
            try:
                real = f.resolve(strict=True)
            except FileNotFoundError:  # a broken link: itself, in its real folder
                real = f.parent.resolve(strict=True) / f.name
        except (OSError, RuntimeError):  # a name through a loop of links
            looped += 1
            continue
        if real.is_dir():  # (a link to a folder)
            continue
        if real in named:
            repeated += 1
        else:
            named[real] = f
    files = sorted(named.values())
    said = []
    if repeated:
        said.append(
            f"{repeated} of its paths name files listed already (links to one file, or "
            "a '**' glob through a link to a folder above): each file is read once"
        )
    if looped:
        said.append(f"{looped} name(s) through a loop of links left out")
    if said:
        warn_data(f"{folder_or_pattern}: {'; '.join(said)}")
    return files


#: What a folder or glob of trajectory files in ``traffic.library`` takes.
TRAJECTORY_SUFFIXES = (".csv", ".xml")


def _library_paths(scenario: Scenario, ref: str) -> tuple[list[Path], bool]:
    """The trajectory files a ``traffic.library`` entry names: a file, or every ``.csv`` and
    ``.xml`` file of a folder or a glob pattern (sorted; relative to the scenario's folder);
    and whether it is a folder or glob."""
    path = Path(ref)
    pattern = ref  # (the scenario's folder escaped: its name may hold * ? [)
    if not ref.startswith("builtin:") and not path.is_absolute() and scenario.base_dir:
        path = scenario.base_dir / path
        pattern = str(Path(glob.escape(str(scenario.base_dir))) / ref)
    if path.is_dir() or any(c in ref for c in "*?["):
        files = matching_files(path if path.is_dir() else pattern, TRAJECTORY_SUFFIXES)
        if not files:
            raise ScenarioError(f"{scenario.source}: traffic.library {ref!r}: no trajectory "
                                f"files ({', '.join(TRAJECTORY_SUFFIXES)}) in {path}")  # fmt: skip
        return files, True
    return [resolve(scenario, ref, ("data", "ngsim"), ".csv", "traffic.library")], False


def input_files(scenario: Scenario) -> list[Path]:
    """The files a scenario's worlds are read from besides its own (its map and trajectory
    files; built-in data, part of the installed package, is not listed)."""
    files = [f for f, _ in _library_refs(scenario) if f != "builtin"]
    return (files + [map_path(scenario)]) if is_recorded(scenario) else files


def input_stamps(scenario: Scenario) -> tuple:
    """Stamps (:func:`stamped`) of every file a scenario's worlds are built from (its map
    and trajectory files): a cache of worlds keyed by them never serves an edited file's."""
    stamps = _library_files(scenario)
    if is_recorded(scenario):
        stamps += (stamped(map_path(scenario)),)
    return stamps


@lru_cache(maxsize=8)
def _library(files: tuple) -> TrajectoryLibrary:
    """The tracks of :func:`_library_files`: a file found in a folder or glob that cannot be
    read is skipped, all of them named in one notice (as a collection skips its unusable
    scenario files); a file named on its own is refused. The library's ``notices``: what
    :func:`library_for` says as :class:`~gridsim.errors.DataWarning` (the files' own notes,
    the files skipped), with the scenario's name."""
    tracks, skipped, notes, singles = [], [], [], []
    for f, found in files:
        if f == "builtin":
            tracks += TrajectoryLibrary.builtin().tracks
            continue
        try:
            with warnings.catch_warnings(record=True) as said:
                warnings.simplefilter("always", DataWarning)
                mine: list = []  # (a file's states of a single state: said once all are read)
                tracks += read_library_file(f[0], mine)
                singles += mine
        except DataError as exc:
            if not found:
                raise
            skipped.append((f[0], str(exc).removeprefix(f"{f[0]}: ")))
        for w in said:  # a file's notes (rows given twice, ...)
            if issubclass(w.category, DataWarning):
                notes.append(str(w.message))
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    left_out = []
    if skipped:
        lines = "\n".join(f"  - {file}: {reason}" for file, reason in skipped)
        if not tracks:
            raise DataError(f"traffic.library: none of its {len(files)} files can be read:\n"
                            f"{lines}")  # fmt: skip
        left_out.append(f"traffic.library: skipped {len(skipped)} of {len(files)} trajectory "
                        f"files that cannot be read:\n{lines}")  # fmt: skip
    with warnings.catch_warnings(record=True) as said:  # (the join's note, with the files')
        warnings.simplefilter("always", DataWarning)
        library = TrajectoryLibrary(tracks)
    notes += [str(w.message) for w in said]
    notes += single_states_notes(library.tracks, singles, library.time_origins)
    library.notices = (*left_out, *_shown_notes(notes, sum(f != "builtin" for f, _ in files)))
    library.skipped = tuple(skipped)
    return library


#: A library's file notes shown in full; those of more files are named in one line.
NOTES_SHOWN = 5


def _shown_notes(notes: list[str], files: int) -> list[str]:
    """The trajectory files' own notes, as they were for a few files; for many (a library
    of one CSV per vehicle), one with the first :data:`NOTES_SHOWN` in full and the other
    files named (a warning per file filled a screen per hundred files)."""
    if len(notes) <= NOTES_SHOWN:
        return notes
    noted = [note.split(": ", 1)[0] for note in notes]  # each note's file
    said = len(set(noted))
    rest = list(dict.fromkeys(noted[NOTES_SHOWN:]))
    shown = "\n".join(f"  - {note}" for note in notes[:NOTES_SHOWN])
    return [f"traffic.library: {said} of its {files} trajectory files have notes; the "
            f"first {NOTES_SHOWN}:\n{shown}\n  and likewise: {named(rest, 10)}"]  # fmt: skip


def seed_streams(seed: int) -> tuple[int, np.random.Generator, np.random.Generator]:
    road_ss, traffic_ss, ego_ss = np.random.SeedSequence(seed).spawn(3)
    return (
        int(road_ss.generate_state(1)[0]),
        np.random.default_rng(traffic_ss),
        np.random.default_rng(ego_ss),
    )


def synthetic_tracks(scenario: Scenario) -> list[Track]:
    """Library tracks usable as human profiles (>= 2 s long, not longer than the limit, not
    flawed: :func:`library_data_report`; its problems refuse the scenario, its warnings are
    shown)."""
    tracks = _profile_tracks(scenario)
    report = library_data_report(scenario, tracks)
    if report.problems:
        raise DataError(report.refusal(scenario.source))
    if report.warnings:  # shown once per message and place (Python's default filter)
        warn_data("\n".join(report.warnings))
    return [t for t in tracks if t.track_id not in report.flawed] if report.flawed else tracks


def library_data_report(scenario: Scenario, tracks: list[Track] | None = None) -> SceneReport:
    """The plausibility report of the library tracks a generated road takes its speed
    profiles from (:func:`~gridsim.scenario.checks.library_report`; ``tracks``: them, if
    already selected), with a warning when their sizes look like feet (a raised
    ``traffic.max_vehicle_length`` lets them through)."""
    tracks = _profile_tracks(scenario) if tracks is None else tracks
    return _library_data_report(tuple(tracks), scenario.source)


@lru_cache(maxsize=16)
def _library_data_report(tracks: tuple[Track, ...], source: str) -> SceneReport:
    """:func:`library_data_report` of a selection, made once per library and scenario (every
    reset of a generated road draws from it: 1.6 ms each time on the built-in library)."""
    selection = list(tracks)
    report = library_report(selection, source)
    hint = feet_hint(selection)
    if hint:
        said = f"{source}: traffic.library: {hint}"
        report = dataclasses.replace(report, warnings=(*report.warnings, said))
    return report


def _profile_tracks(scenario: Scenario) -> list[Track]:
    """The library's tracks >= 2 s long and not longer than the limit."""
    t = scenario.config.traffic
    library = library_for(scenario)
    tracks = library.select(min_duration=MIN_TRACK_SECONDS, max_length=t.max_vehicle_length)
    if not tracks:
        raise ScenarioError(
            f"{scenario.source}: traffic.library has no track of >= 2 s and <= "
            f"{t.max_vehicle_length} m (traffic.max_vehicle_length)"
            + (f"; {hint}" if (hint := feet_hint(library.select())) else "")
        )
    return tracks


def road_lane_width(scenario: Scenario) -> float:
    """Lane width [m] of a generated road (3.5 m for recorded maps)."""
    return float(getattr(scenario.config.road, "lane_width", 3.5))


def speed_bounds(scenario: Scenario) -> SpeedBounds:
    t = scenario.config.traffic
    return SpeedBounds(t.v_min, t.v_max, t.a_max)


def fixed_route(route: Polyline) -> Polyline:
    return route
