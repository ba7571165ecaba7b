"""``record`` into a dataset folder: the windows written as they are recorded
(:class:`~neurotrajectory.data.storage.ShardWriter`), one side of a split copied at the end,
and checkpoints from which an interrupted recording goes on (:class:`_Checkpoints`)."""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

import numpy as np

from gridsim.errors import WorkKept
from gridsim.outputs import LOCK_NAME, as_given, empty_folder, write_json
from gridsim.scenario.collection import input_changes, same_inputs
from neurotrajectory.data import storage
from neurotrajectory.data.storage import (
    ShardWriter,
    check_new_folder,
    read_shard,
    sha256_of,
    write_shard,
)
from neurotrajectory.data.windows import (
    FORMAT_VERSION,
    GROUPS,
    WINDOW_RULES,
    DatasetError,
    GroupProgress,
    check_test_fraction,
    held_out_tracks,
    package_versions,
    record_group_into,
)

#: :func:`record_dataset`'s checkpoint of an interrupted recording, and how often one is
#: taken [s]
PROGRESS_FILE = "progress.json"
CHECKPOINT_SECONDS = 30.0
#: where a recording for a split writes the whole group, inside its folder
SPOOL = ".spool"


def record_dataset(
    out: str | Path,
    name: str,
    episodes: int,
    seed: int = 0,
    stride: int | None = None,
    duration: float | None = None,
    progress: Callable[[int], None] | None = None,
    source: str | None = None,
    goal_seconds: float | None = None,
    planned: Callable[[int], None] | None = None,
    split: tuple[str, float] | None = None,
    resume: bool = False,
    log: Callable[[str], None] | None = None,
    files: Callable[[int], None] | None = None,
) -> tuple[dict, int]:
    """:func:`record_group` written into the dataset folder ``out`` (new or empty) as the
    windows come, so that memory holds about one shard whatever the dataset's size; with
    ``split`` ``(side, test_fraction)``, only that side of :func:`split_by_track` (seed
    ``seed``) is kept: the whole group is written aside first (``out/.spool``), then that
    side of it copied. Returns the manifest written and the number of tracks kept.

    With ``resume``, the recording leaves checkpoints in ``out`` as it goes
    (:class:`_Checkpoints`), and ``out`` may hold those of an interrupted recording: one of
    the same arguments goes on from its last checkpoint (the same dataset, bit for bit, as
    one not interrupted); one of other arguments is refused and kept
    (:class:`~gridsim.errors.WorkKept`, naming them), a damaged one removed (``log`` is told
    why), and anything else in ``out`` is refused as by ``resume=False``."""
    out = Path(out)
    if split is not None:
        side, test_fraction = split
        if side not in ("train", "test"):
            raise DatasetError(f"split side must be 'train' or 'test', got {side!r}")
        check_test_fraction(test_fraction)
    spool = out / SPOOL if split else out
    state, writer, checkpoints = GroupProgress(), None, None
    stamps = group_inputs(name, source)
    if resume:
        arguments = {"name": name, "source": None if source is None else str(source),
                     "episodes": int(episodes), "seed": int(seed),
                     "stride": None if stride is None else int(stride),
                     "duration": None if duration is None else float(duration),
                     "goal_seconds": None if goal_seconds is None else float(goal_seconds),
                     "split": list(split) if split else None, "format": FORMAT_VERSION,
                     "window_rules": WINDOW_RULES,
                     "shard_size": storage.SHARD_SIZE, "versions": package_versions(),
                     "files": stamps}  # fmt: skip
        checkpoints = _Checkpoints(spool, arguments)
        found, why = checkpoints.load()
        other = out if split else out / SPOOL  # where one with(out) --split keeps its own
        if why is None and (other / PROGRESS_FILE).is_file():
            then = "without" if split else "with"
            why = f"was made {then} --split (now {'with' if split else 'without'})"
        if why and why.startswith("was made "):
            raise WorkKept(f"{out} holds an interrupted recording that {why}: give the "
                           f"arguments it was made with to go on with it, or remove {out} to "
                           "start afresh")  # fmt: skip
        if found is not None:
            state, writer = found
            if log:
                log(f"going on with the interrupted recording of the same arguments in {out}: "
                    f"{writer.count} windows kept")  # fmt: skip
        elif out.is_dir() and _ours_only(out):
            if why and log:
                log(f"starting afresh in {out}: the interrupted recording there {why}")
            empty_folder(out)
    if writer is None:
        check_new_folder(out)
        writer = ShardWriter(spool)
    if checkpoints is not None:
        checkpoints.follow(writer, state)
    manifest = record_group_into(writer, name, episodes, seed, stride, duration, progress,
                                  source, goal_seconds, planned, state, checkpoints,
                                  files)  # fmt: skip
    changed = input_changes(stamps, group_inputs(name, source))
    if changed:  # (the windows mix the contents before and after: neither dataset)
        raise DatasetError(f"{name}: files changed while they were recorded ({changed}): the "
                           f"windows in {out} mix their contents before and after the change; "
                           f"record again once they are final (remove {out} first)")  # fmt: skip
    manifest["inputs"] = stamps
    if split is None:
        done = writer.finish(manifest)
        if checkpoints is not None:
            checkpoints.remove()
        return done, len(writer.tracks)
    writer.flush()
    if log:
        log(f"copying the {side} side of the split out of the {writer.count} windows recorded")
    held = held_out_tracks(np.array(list(writer.tracks)), test_fraction, seed)
    _remove_all_but(out, {spool.name, LOCK_NAME})  # an interrupted copy's files
    kept = ShardWriter(out)
    for shard in writer.shards:
        part = read_shard(spool / shard["file"])
        kept.add(part.take(np.flatnonzero(np.isin(part.track, held) == (side == "test"))))
    split_info = {"side": side, "test_fraction": test_fraction, "seed": seed}
    done = kept.finish({**manifest, "split": split_info})
    shutil.rmtree(spool)
    return done, len(kept.tracks)


#: What :func:`record_dataset` writes into its folder (``.*.tmp``: a write under way).
_OURS = ("shard-*.npz", "pending-*.npz", PROGRESS_FILE, "manifest.json", SPOOL, ".*.tmp")


def _ours_only(folder: Path) -> bool:
    """Whether the folder ``folder`` holds nothing but what :func:`record_dataset` writes."""
    ours = (*_OURS, LOCK_NAME)
    return all(any(p.match(g) for g in ours) for p in folder.iterdir())


def _remove_all_but(folder: Path, keep: set[str]) -> None:
    """Remove the files :func:`record_dataset` writes (:data:`_OURS`) from ``folder`` but the
    names ``keep``: those of a copy or a checkpoint that a killed process left behind."""
    for p in folder.iterdir():
        if p.name not in keep and any(p.match(g) for g in _OURS):
            shutil.rmtree(p) if p.is_dir() and not p.is_symlink() else p.unlink()


def group_inputs(name: str, source: str | None) -> dict[str, str]:
    """SHA-256 of every file a group's windows are recorded from, by resolved path: its
    scenario files (of a folder or glob, usable or not) and the maps and track libraries they
    name, each hashed once, nothing built (:func:`~gridsim.scenario.collection.input_digest`;
    built-in scenarios and data: none). A recording is not continued, and a dataset not
    evaluated as the group, on files whose contents changed."""
    from gridsim.scenario.collection import input_digest

    if source is None and name in GROUPS:
        return {}
    stamps = input_digest(name if source is None else source)
    return {os.path.realpath(f): digest for f, digest in stamps.items()}


class _Checkpoints:
    """:func:`record_dataset`'s checkpoints in the folder it writes shards into, for an
    interrupted recording to go on: ``progress.json`` (the arguments, how far the group is,
    the shards written, the track labels, and the name, count and checksum of the pending
    file) and ``pending-N.npz`` (the windows not yet in a shard), written after an episode
    when :data:`CHECKPOINT_SECONDS` have passed since the last, and after every file of the
    group. The pending file is written before the checkpoint that names it; what a
    checkpoint does not name is removed when the recording goes on."""

    def __init__(self, folder: Path, arguments: dict) -> None:
        self.folder, self.arguments = folder, arguments
        self.path = folder / PROGRESS_FILE
        self.writer: ShardWriter | None = None
        self.state: GroupProgress | None = None
        self.last, self.number = time.monotonic(), 0

    def follow(self, writer: ShardWriter, state: GroupProgress) -> None:
        self.writer, self.state = writer, state

    def __call__(self, now: bool = False) -> None:
        """A checkpoint if ``now`` or :data:`CHECKPOINT_SECONDS` have passed."""
        if not now and time.monotonic() - self.last < CHECKPOINT_SECONDS:
            return
        self.number += 1
        pending = self.writer.pending()
        doc = {"arguments": self.arguments, "state": asdict(self.state),
               "shards": self.writer.shards, "tracks": list(self.writer.tracks),
               "checkpoint": self.number, "windows": self.writer.count,
               "pending": None}  # fmt: skip
        if pending is not None:
            name = f"pending-{self.number:06d}.npz"
            write_shard(self.folder / name, pending, compressed=False)
            doc["pending"] = {"file": name, "windows": len(pending),
                              "sha256": sha256_of(self.folder / name)}  # fmt: skip
        write_json(self.path, doc)
        _remove_all_but(self.folder, self._named(doc))
        self.last = time.monotonic()

    def _named(self, doc: dict) -> set[str]:
        """What the checkpoint ``doc`` names in the folder (with the lock and the spool)."""
        pending = [doc["pending"]["file"]] if doc["pending"] else []
        return {PROGRESS_FILE, LOCK_NAME, *pending, *(s["file"] for s in doc["shards"])}

    def load(self) -> tuple[tuple[GroupProgress, ShardWriter] | None, str | None]:
        """How far the interrupted recording in the folder had gone, and a writer that goes
        on from there; or None and why not (None: there is none)."""
        if not self.path.is_file():
            return None, None
        try:
            doc = json.loads(self.path.read_text())
            differ = _differences(doc["arguments"], self.arguments)
            if differ:
                return None, f"was made with {differ}"
            state = GroupProgress(**doc["state"])
            if not all(isinstance(getattr(state, k), int)
                       for k in ("scenario", "episode", "windows")):  # fmt: skip
                raise ValueError("a count that is not an integer")
            files = [*doc["shards"], *([doc["pending"]] if doc["pending"] else [])]
            for entry in files:
                if sha256_of(self.folder / entry["file"]) != entry["sha256"]:
                    raise ValueError(f"{entry['file']} was changed or truncated")
            pending = read_shard(self.folder / doc["pending"]["file"]) if doc["pending"] else None
            counted = sum(int(e["windows"]) for e in files)
            if counted != doc["windows"] or (
                pending is not None and len(pending) != doc["pending"]["windows"]
            ):
                raise ValueError("its counts of windows disagree")  # fmt: skip
            number, tracks = int(doc["checkpoint"]), list(doc["tracks"])
        except Exception as exc:  # noqa: BLE001 - a damaged checkpoint is not used, and said
            return None, f"has a checkpoint that cannot be used ({type(exc).__name__}: {exc})"
        self.number = number
        _remove_all_but(self.folder, self._named(doc))  # files written after the checkpoint
        writer = ShardWriter(self.folder)
        writer.shards = list(doc["shards"])
        if pending is not None:
            writer.add(pending)
        writer.tracks = dict.fromkeys(tracks)
        return (state, writer), None

    def remove(self) -> None:
        self.path.unlink(missing_ok=True)
        for old in self.folder.glob("pending-*.npz"):
            old.unlink()


def _differences(then: dict, now: dict) -> str:
    """What differs between the arguments of a recording ``then`` and ``now``, in words."""
    said = []
    for key in sorted(set(then) | set(now)):
        old, new = then.get(key), now.get(key)
        if old == new or (key == "files" and same_inputs(old, new)):
            continue
        if key == "files" and not isinstance(old, dict):
            said.append("input files hashed by an older version (its scenario files only)")
        elif key == "files":
            said.append(f"other input files ({input_changes(old, new) or 'their contents'})")
        elif key == "versions":
            said.append(f"other versions ({old}, now {new})")
        elif key == "window_rules":  # (a recording of a version before them: 1)
            said.append(f"other rules for taking windows ({old or 1}, now {new}: a recorded "
                        "track's episode drives on past its destination)")  # fmt: skip
        else:
            flag = _FLAGS.get(key, key)
            if key == "name" and then.get("source") is None and now.get("source") is None:
                flag = "--scenario"  # (a group named by its --scenario, without --name)
            said.append(f"{flag} {as_given(old, 'not given')} (now {as_given(new, 'not given')})")
    return "; ".join(said)


#: The ``record`` flags of a recording's arguments (``format`` and ``shard_size`` are the
#: program's own, named as they are).
_FLAGS = {"name": "--name", "source": "--scenario", "episodes": "--episodes", "seed": "--seed",
          "stride": "--stride", "duration": "--episode-seconds",
          "goal_seconds": "--goal-seconds", "split": "--split"}  # fmt: skip


def checkpoint_windows(folder: Path) -> tuple[int, bool] | None:
    """How many windows the interrupted recording in ``folder`` kept at its last checkpoint,
    and whether they are the whole group's (recorded for a split, one side of which is
    copied at the end); None: it has none."""
    for path, whole in ((folder / PROGRESS_FILE, False), (folder / SPOOL / PROGRESS_FILE, True)):
        if path.is_file():
            return int(json.loads(path.read_text())["windows"]), whole
    return None
