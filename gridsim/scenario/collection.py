"""Scenario collections: a folder or a glob pattern of scenario files (YAML or CommonRoad XML),
or a comma-separated list of scenarios (``"us101_3_3,us101_4_1"``: built-in names, files,
folders or globs).

An environment made from a collection draws one of its scenarios per reset from the reset
seed (:func:`pick`). Its scenarios must agree on what fixes the spaces and the time step
(:data:`SHARED_KEYS`); they may differ in road, traffic and duration.

Real collections hold files that cannot be used (a scene with no track to drive, impossible
data): they are skipped, every one named with its reason in one
:class:`~gridsim.errors.DataWarning` (:func:`usable_files`); a collection fails only when no
file is usable, or when a YAML scenario file of it does not load (a key misspelt, a value out
of range: the author's mistake, not the data's, would drop the scenario without a word).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gridsim.errors import DataError, GridSimError, ScenarioError, UnselectedScene, warn_data
from gridsim.outputs import counted, named
from gridsim.scenario.build import build_world
from gridsim.scenario.loader import (
    check_reference,
    load_scenario,
    names_a_file,
    scenario_document,
)
from gridsim.scenario.parts import matching_files
from gridsim.scenario.schema import Scenario
from gridsim.seeding import Salt, stream

SUFFIXES = (".yaml", ".yml", ".xml")
#: Keys on which the scenarios of a collection must agree (spaces, time step).
SHARED_KEYS = ("sensor", "env", "ego.vehicle", "simulation.dt")


_YAML = (".yaml", ".yml")


def scenario_files(ref: str | Path) -> list[Path] | None:
    """The scenario files of a folder (sorted by name), of a glob pattern (sorted) or of a
    comma-separated list (in its order; a built-in name is given as ``Path(name)``);
    ``None`` if ``ref`` is none of these (a built-in name or a single file, or not a name or
    path at all: :func:`load_scenario` then says so)."""
    if not isinstance(ref, str | os.PathLike):
        return None
    check_reference(ref)  # ("" is no folder: Path("") is the current one)
    text = str(ref)
    path = Path(text)
    if path.is_dir():
        files = matching_files(path, SUFFIXES)
        # YAML scenario files one level down (XML there is more often a map: `gridsim import`
        # puts them in maps/)
        nested = {d.name: sorted({f.suffix.lower() for f in matching_files(d, _YAML)})
                  for d in path.iterdir() if d.is_dir()}  # fmt: skip
        nested = {name: suffixes for name, suffixes in nested.items() if suffixes}
        if nested:
            suffixes = sorted({s for found in nested.values() for s in found})
            globs = " or ".join(f"'{path / '**' / ('*' + s)}'" for s in suffixes)
            warn_data(
                f"{text}: its subfolders {', '.join(sorted(nested))} hold scenario "
                "files that are not read (a folder is read without its subfolders; "
                f"for all, give the glob {globs})"
            )
    elif _is_list(text):
        return _listed_files(text)
    elif any(c in text for c in "*?["):
        files = matching_files(text, SUFFIXES)
    else:
        return None
    if not files:
        what = "in it" if path.is_dir() else "match the pattern"
        raise ScenarioError(f"{text}: no scenario files ({', '.join(SUFFIXES)}) {what}")
    named = _files_named_by(files)  # a YAML's map beside it is its data, not a scenario
    return sorted(f for f in files if f.suffix.lower() != ".xml" or f.resolve() not in named)


def _files_named_by(files: list[Path]) -> set[Path]:
    """The files (resolved) the YAML scenario files among ``files`` name as their map
    (``road.map``) or track library (``traffic.library``), relative to each YAML file; a
    YAML file that cannot be read names none (loading it says why)."""
    named = set()
    for f in files:
        if f.suffix.lower() not in _YAML:
            continue
        try:
            doc = scenario_document(f)  # (the loader's bounds: a hostile file is refused)
        except ScenarioError:
            continue
        if not isinstance(doc, dict):
            continue
        road, traffic = doc.get("road"), doc.get("traffic")
        refs = [road.get("map")] if isinstance(road, dict) else []
        library = traffic.get("library") if isinstance(traffic, dict) else None
        refs += library if isinstance(library, list) else [library]
        named |= {(f.parent / r).resolve() for r in refs if isinstance(r, str) and r}
    return named


def _is_list(text: str) -> bool:
    """Whether ``text`` is a comma-separated list of scenarios (not a path with a comma)."""
    return "," in text and not Path(text).exists()


def absolute_ref(ref: str) -> str:
    """``ref`` (a scenario reference: a built-in name, a file, folder or glob, or a
    comma-separated list of them) with every item that is a path made absolute, built-in
    names as they are: what a run keeps, so that it finds its files from any folder."""
    text = str(ref)
    items = [i.strip() for i in text.split(",")] if _is_list(text) else [text]
    return ",".join(os.path.abspath(item) if is_collection(item) or names_a_file(item) else item
                    for item in items)  # fmt: skip


def _listed_files(text: str) -> list[Path]:
    """The scenarios of a comma-separated list, each item's files in turn (a built-in name
    or a file as itself); a :class:`ScenarioError` for an empty or repeated item."""
    items = [item.strip() for item in text.split(",")]
    if not all(items):
        raise ScenarioError(f"{text!r}: an empty item in a comma-separated list of scenarios")
    files: list[Path] = []
    for item in items:
        found = scenario_files(item)
        files += [Path(item)] if found is None else found
    repeated = sorted({str(f) for f in files if files.count(f) > 1})
    if repeated:
        raise ScenarioError(f"{text!r}: {', '.join(repeated)} listed more than once")
    return files


def is_collection(ref: str | Path) -> bool:
    """Whether ``ref`` names a folder, a glob pattern or a comma-separated list (not a check
    that it has files)."""
    text = str(ref)
    return Path(text).is_dir() or any(c in text for c in "*?[") or _is_list(text)


def _get(doc: dict, key: str) -> Any:
    for part in key.split("."):
        doc = doc[part]
    return doc


def usable_files(
    ref: str | Path, overrides: Mapping[str, Any] | None = None, read_data: bool = True
) -> tuple[list[Scenario], list[tuple[Path, str]]]:
    """``(scenarios, skipped)``: the files of the folder or glob ``ref`` that load and build
    a world (with ``overrides``), and ``(file, reason)`` for every other one. A
    :class:`~gridsim.errors.DataWarning` names the skipped files; a :class:`ScenarioError`
    names them all if none is usable. A YAML file (or a built-in name of a list) that fails
    otherwise than by its recorded
    data (a :class:`~gridsim.errors.DataError`: impossible values, no track to drive) is its
    author's mistake (a misspelt key, a library file not found, an ego track not in the
    scene): a :class:`ScenarioError` names every such file. Without ``read_data`` only the
    scenario files are checked: their maps and recordings are not read (a listing of a
    folder of large CSVs)."""
    files = scenario_files(ref)
    if files is None:
        raise ScenarioError(f"{ref}: not a folder or a glob pattern of scenario files")
    scenarios, skipped, mistakes = [], [], []
    for f in files:
        try:
            sc = load_scenario(f, overrides, shared=True)  # (an override read by some only)
            if read_data:
                build_world(sc, seed=0)  # resolves maps and libraries, checks the recorded data
        except GridSimError as exc:
            # an XML file is data as it is; a YAML file or a name given is the author's
            mistake = f.suffix.lower() != ".xml" and not isinstance(
                exc, (DataError, UnselectedScene)
            )  # (a scene the shared ego.track skips)
            (mistakes if mistake else skipped).append((f, str(exc)))
            continue
        scenarios.append(sc)
    if mistakes:
        raise ScenarioError(
            f"{ref}: {counted(len(mistakes), 'scenario file')} of the collection "
            f"{'does' if len(mistakes) == 1 else 'do'} not load (a collection skips files whose "
            "recorded data cannot be used, not a scenario's mistakes):\n" + skipped_lines(mistakes)
        )
    report_skipped(str(ref), skipped, len(files), bool(scenarios))
    if not read_data:
        return scenarios, skipped
    used = [f for f in files if f not in {g for g, _ in skipped}]
    pairs = list(zip(used, scenarios, strict=True))
    for first, again, scene in repeated_recordings(pairs):
        warn_data(
            f"{ref}: {again} replays the same recording as {first} (scene {scene}, the "
            "same tracks and ego tracks): its episodes and windows count twice"
        )
    for said in shared_names_messages(shared_track_names(pairs)):
        warn_data(f"{ref}: {said}")
    return scenarios, skipped


def shared_names_messages(found: list[tuple[Path, Path, str, list]]) -> list[str]:
    """What :func:`shared_track_names` found, and what to do: one message per first file and
    scene (a folder of 32 recordings of one site said it 31 times)."""
    grouped: dict[tuple[Path, str], list[tuple[Path, list]]] = {}
    for first, other, scene, ids in found:
        grouped.setdefault((first, scene), []).append((other, ids))
    out = []
    for (first, scene), others in grouped.items():
        ids = max((ids for _, ids in others), key=len)
        if len(others) == 1:
            said = (f"{others[0][0]} and {first} are other recordings of scene {scene} with "
                    f"{len(ids)} track id(s) in common ({named(ids)})")  # fmt: skip
        else:
            said = (f"{len(others)} files ({named([o for o, _ in others])}) are other "
                    f"recordings of scene {scene} than {first}, each with track ids in common "
                    f"with it (up to {len(ids)}: {named(ids)})")  # fmt: skip
        out.append(f"{said}: windows, the train/test split by track and --track name a track "
                   "SCENE/ID, so they would be taken for the same vehicles; give each "
                   "recording its own scene (its CSV's scenario_id and the scenario's "
                   "road.scene)")  # fmt: skip
    return out


def shared_track_names(pairs: list[tuple[Path, Scenario]]) -> list[tuple[Path, Path, str, list]]:
    """``(first file, other file, scene, ids)`` for each recorded scenario of ``pairs``
    (file, scenario) whose scene has track ``ids`` in common with an earlier file's while
    their tracks differ (another recording whose ids restart; a copy is
    :func:`repeated_recordings`'s)."""
    seen: dict[str, list[tuple[Path, dict]]] = {}
    out = []
    for path, _, scene, mine in _recorded_tracks(pairs):
        for first, theirs in seen.get(scene, []):
            common = sorted(k for k in mine.keys() & theirs.keys() if mine[k] != theirs[k])
            if common:
                out.append((first, path, scene, common))
                break
        seen.setdefault(scene, []).append((path, mine))
    return out


def repeated_recordings(pairs: list[tuple[Path, Scenario]]) -> list[tuple[Path, Path, str]]:
    """``(first file, repeating file, scene)`` for each recorded scenario of ``pairs`` (file,
    scenario) that replays the same tracks (ids, and every sample and size) with the same
    ``ego.track`` as an earlier one: copies of a recording under other names (a CSV saved
    again with a BOM or other line ends)."""
    seen: dict[tuple, Path] = {}
    out = []
    for path, scenario, scene, tracks in _recorded_tracks(pairs):
        ego = scenario.config.ego.track
        key = (scene, ego if isinstance(ego, str) else tuple(ego),
               tuple(sorted(tracks.items())))  # fmt: skip
        if key in seen:
            out.append((seen[key], path, scene))
        else:
            seen[key] = path
    return out


def _recorded_tracks(pairs: list[tuple[Path, Scenario]]):
    """``(file, scenario, scene, {track id: digest of its samples and size})`` of each
    recorded scenario of ``pairs`` (file, scenario): what tells its tracks from another
    recording's (every sample counts: a copy with one glitch or one size changed is another
    recording)."""
    from gridsim.scenario.families.recorded import recorded_scene, scene_of
    from gridsim.scenario.family import is_recorded

    for path, scenario in pairs:
        if is_recorded(scenario):
            _, tracks = recorded_scene(scenario, check=False)
            yield (
                path,
                scenario,
                scene_of(scenario),
                {t.track_id: _track_digest(t) for t in tracks},
            )


def _track_digest(track) -> bytes:
    """A digest of a track's samples and size (as read: a file saved again with other line
    ends or a BOM gives the same)."""
    h = hashlib.blake2b(digest_size=16)
    for values in (track.t, track.x, track.y, track.heading, track.speed,
                   np.array([track.length, track.width])):  # fmt: skip
        h.update(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return h.digest()


def report_skipped(
    where: str,
    skipped: list[tuple[Path, str]],
    total: int,
    any_used: bool,
    phrases: tuple[str, str] = ("can be used", "cannot be used"),
    error: type[Exception] = ScenarioError,
) -> None:
    """Name the ``skipped`` files (``(file, reason)``) of ``total`` scenario files in one
    :class:`~gridsim.errors.DataWarning`, or raise ``error`` naming them all when none was
    used. ``phrases``: what the used files did and the skipped ones did not."""
    if not skipped:
        return
    lines = skipped_lines(skipped)
    if not any_used:
        raise error(f"{where}: none of its {total} scenario files {phrases[0]}:\n{lines}")
    warn_data(
        f"{where}: skipped {len(skipped)} of {total} scenario files that {phrases[1]}:\n{lines}"
    )


#: Lines of one skipped file's reason shown (the rest: ``gridsim validate FILE``).
REASON_LINES = 6


def skipped_lines(skipped: list[tuple[Path, str]]) -> str:
    """``  - FILE: REASON`` per skipped file (without a leading copy of the file name), the
    reason's further lines indented under it, at most :data:`REASON_LINES` of them."""
    out = []
    for f, reason in skipped:
        lines = (reason or "unknown").splitlines() or ["unknown"]
        out.append(f"  - {f}: {lines[0].removeprefix(f'{f}: ')}")
        out += [f"      {line.strip()}" for line in lines[1:REASON_LINES]]
        if len(lines) > REASON_LINES:
            out.append(f"      (+{len(lines) - REASON_LINES} more lines: gridsim validate {f})")
    return "\n".join(out)


def load_collection(ref: str | Path, overrides: Mapping[str, Any] | None = None) -> list[Scenario]:
    """The usable scenarios of a folder or glob (:func:`usable_files`; or the one scenario
    ``ref`` names), ``overrides`` applied to each; :class:`ScenarioError` if they disagree on
    :data:`SHARED_KEYS`."""
    return [sc for _, sc in load_usable(ref, overrides)[0]]


def load_usable(
    ref: str | Path, overrides: Mapping[str, Any] | None = None
) -> tuple[list[tuple[str, Scenario]], list[tuple[Path, str]]]:
    """:func:`load_collection` with each scenario's file (as a reference to load it by: a
    file's path, a built-in name; ``ref`` itself for one scenario) and the files skipped
    (``(file, reason)``, named in a warning already)."""
    files = scenario_files(ref)
    if files is None:
        one = load_scenario(ref, overrides)
        check_track_scenes([one])
        return [(str(ref), one)], []
    scenarios, skipped = usable_files(ref, overrides)
    check_agreement(ref, scenarios)
    check_track_scenes(scenarios, some_skipped=bool(skipped))
    gone = {f for f, _ in skipped}
    return list(zip([str(f) for f in files if f not in gone], scenarios, strict=True)), skipped


def input_digest(ref: str | Path, overrides: Mapping[str, Any] | None = None) -> dict[str, str]:
    """SHA-256 (hex) of every file the scenarios of ``ref`` are read from, by path: the
    scenario files (all that a folder or glob matches, usable or not) and the map and
    trajectory files they name. Built-in scenarios and data (the installed package's) are
    not listed. Nothing is built: the files are found from the scenarios' keys."""
    from gridsim.scenario.parts import input_files

    files = scenario_files(ref)
    refs = files if files is not None else [Path(str(ref))]
    found = list(refs)
    for one in refs:
        try:
            found += input_files(load_scenario(one, overrides))
        except GridSimError:  # (a file that does not load is hashed as it is)
            continue
    package = Path(__file__).resolve().parents[1]  # gridsim's own data: installed, not input
    return {str(f): _sha256(f) for f in sorted(set(found), key=str)
            if f.is_file() and not f.resolve().is_relative_to(package)}  # fmt: skip


def same_inputs(then, now) -> bool:
    """Whether :func:`input_digest` ``then`` and ``now`` (path -> digest) name files of the same
    contents (their paths may differ: a project moved)."""
    if not isinstance(then, dict) or not isinstance(now, dict):
        return then == now
    return sorted(then.values()) == sorted(now.values())


def input_changes(then, now) -> str:
    """The files whose :func:`input_digest` differ between ``then`` and ``now`` (path ->
    digest), in words: ``"changed: A; removed: B"`` (``""``: none, or digests of another
    form, as an older version kept them)."""
    if not isinstance(then, dict) or not isinstance(now, dict):
        return ""
    said = []
    changed = [f for f in then.keys() & now.keys() if then[f] != now[f]]
    removed, added = then.keys() - now.keys(), now.keys() - then.keys()
    for what, files in (("changed", changed), ("removed", removed), ("added", added)):
        if files:
            shown = ", ".join(sorted(files)[:3]) + (", ..." if len(files) > 3 else "")
            said.append(f"{what}: {shown}")
    return "; ".join(said)


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def check_track_scenes(scenarios: list[Scenario], some_skipped: bool = False) -> None:
    """A :class:`ScenarioError` for an ``ego.track`` name ``SCENE/ID`` whose scene is none of
    the recorded ``scenarios``' (a collection's scenes share one list, so a name of another
    scene is kept; one of no scene is a misspelt scene, and was dropped without a word). When
    files of the collection were skipped (``some_skipped``), the scene may be a skipped
    file's: a :class:`~gridsim.errors.DataWarning` says so instead."""
    from gridsim.scenario.families.recorded import scene_of
    from gridsim.scenario.family import is_recorded
    from gridsim.traffic.track import track_name

    recorded = [sc for sc in scenarios if is_recorded(sc)]
    prefixes = tuple({track_name(scene_of(sc), "") for sc in recorded})
    for sc in recorded:
        wanted = sc.config.ego.track
        names = [wanted] if isinstance(wanted, str) else list(wanted)
        odd = [n for n in names if "/" in n and not n.startswith(prefixes)]
        if odd:
            scenes = ", ".join(sorted(p.rstrip("/") for p in prefixes))
            said = (f"{sc.source}: ego.track names {counted(len(odd), 'track')} of no scene "
                    f"here: {', '.join(odd[:5])}; the scene(s): {scenes} (a track is ID, or "
                    "SCENE/ID)")  # fmt: skip
            if some_skipped:
                warn_data(f"{said}; they may be of a skipped file's scene: not driven")
                continue
            raise ScenarioError(said)


def check_agreement(ref: str | Path, scenarios: list[Scenario]) -> None:
    """:class:`ScenarioError` naming the first key of :data:`SHARED_KEYS` on which the
    ``scenarios`` of the collection ``ref`` disagree, and both values."""
    first = scenarios[0].config.model_dump()
    for sc in scenarios[1:]:
        doc = sc.config.model_dump()
        for key in SHARED_KEYS:
            if _get(doc, key) != _get(first, key):
                where, mine, theirs = _difference(_get(doc, key), _get(first, key), key)
                raise ScenarioError(
                    f"{ref}: the scenarios of a collection must agree on {key}; "
                    f"{sc.source} has {where} = {mine!r}, {scenarios[0].source} {theirs!r}"
                )


def _difference(a: Any, b: Any, key: str) -> tuple[str, Any, Any]:
    """The first key (dotted, under ``key``) whose values differ between ``a`` and ``b``, and
    the two values."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b), key=str):
            if a.get(k) != b.get(k):
                return _difference(a.get(k), b.get(k), f"{key}.{k}")
    return key, a, b


def pick(scenarios: list[Scenario], seed: int) -> Scenario:
    """The scenario of a collection for an episode seed (the first if there is one)."""
    if len(scenarios) == 1:
        return scenarios[0]
    rng = stream(seed, Salt.SCENARIO_PICK)
    return scenarios[int(rng.integers(len(scenarios)))]
