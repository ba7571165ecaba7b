"""Datasets on disk: a folder with ``manifest.json`` (scenario group, seeds, sizes, versions,
shard checksums) and compressed ``shard-NNNNN.npz`` files of :data:`SHARD_SIZE` windows,
written as the windows come (:class:`ShardWriter`) and read back checked, whole or one side
of a split by track at a time."""

from __future__ import annotations

import hashlib
from dataclasses import fields
from pathlib import Path

import numpy as np

from gridsim.outputs import new_folder_problem, read_manifest, short_repr, write_json, write_npz
from neurotrajectory.data.scratch import grid_arrays
from neurotrajectory.data.windows import (
    FORMAT_VERSION,
    Dataset,
    DatasetError,
    Windows,
    held_out_tracks,
)

SHARD_SIZE = 256


def check_new_folder(out: str | Path) -> None:
    """A :class:`DatasetError` unless ``out`` can become a new output folder."""
    problem = new_folder_problem(out)
    if problem:
        raise DatasetError(f"{out}: {problem}")


def save_dataset(dataset: Dataset, out: str | Path) -> Path:
    """Write ``dataset`` into the folder ``out`` (created; must be empty if it exists)."""
    out = Path(out)
    check_new_folder(out)
    writer = ShardWriter(out)
    writer.add(dataset.windows)
    writer.finish(dataset.manifest)
    return out


class ShardWriter:
    """Writes windows into ``folder`` (created) as they come: compressed shards of
    :data:`SHARD_SIZE` windows each (``shard-NNNNN.npz``), so that memory holds at most one
    shard besides what is added; :meth:`finish` writes ``manifest.json``. A shard is shorter
    only where :meth:`flush` (at :meth:`mark`, and at the end) writes what is buffered, so the
    shards hold the same windows whatever pieces they were added in."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.shards: list[dict] = []  # {"file", "windows", "sha256"} of each shard written
        self.tracks: dict[str, None] = {}  # the track labels added, in the order first seen
        self._buffer: list[Windows] = []
        self._buffered = 0

    @property
    def count(self) -> int:
        return sum(s["windows"] for s in self.shards) + self._buffered

    def add(self, windows: Windows) -> None:
        self.tracks.update(dict.fromkeys(windows.track.tolist()))
        start = 0
        while start < len(windows):  # a shard's worth at a time (a big piece is not copied)
            stop = min(start + SHARD_SIZE - self._buffered, len(windows))
            self._buffer.append(windows.rows(start, stop))
            self._buffered += stop - start
            start = stop
            if self._buffered == SHARD_SIZE:
                self._write()

    def pending(self) -> Windows | None:
        """The windows added that are not yet in a shard (None: none)."""
        return Windows.concat(self._buffer) if self._buffered else None

    def flush(self) -> None:
        """Write what is buffered as a (shorter) shard."""
        if self._buffered:
            self._write()

    def _write(self) -> None:
        part = Windows.concat(self._buffer)
        self._buffer, self._buffered = [], 0
        name = f"shard-{len(self.shards):05d}.npz"
        write_shard(self.folder / name, part)
        self.shards.append({"file": name, "windows": len(part),
                            "sha256": sha256_of(self.folder / name)})  # fmt: skip

    def mark(self) -> list:
        """Where the windows added so far end, for :meth:`rollback` (what is buffered is
        written first): ``[shards, track labels]``, as JSON keeps it."""
        self.flush()
        return [len(self.shards), list(self.tracks)]

    def rollback(self, mark: list) -> None:
        """Forget the windows added since ``mark`` (their shards are removed)."""
        shards, tracks = mark
        for shard in self.shards[shards:]:
            (self.folder / shard["file"]).unlink(missing_ok=True)
        del self.shards[shards:]
        self._buffer, self._buffered, self.tracks = [], 0, dict.fromkeys(tracks)

    def finish(self, manifest: dict) -> dict:
        """Write the last shard and ``manifest.json`` (``manifest`` with the count and the
        shards; last: a folder without it is no dataset); returns what was written."""
        self.flush()
        manifest = {**manifest, "count": self.count, "shards": self.shards}
        write_json(self.folder / "manifest.json", manifest)
        return manifest


def sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def dataset_manifest(folder: str | Path) -> dict:
    """The manifest of the dataset folder ``folder`` (checked; no window is read)."""
    folder = Path(folder)
    path = folder / "manifest.json"
    manifest = read_manifest(folder, "manifest.json", "dataset", DatasetError, (FORMAT_VERSION,),
                             keys=("shards",))  # fmt: skip
    shards = manifest["shards"]
    if not isinstance(shards, list) or not shards:
        raise DatasetError(f"{path}: 'shards' must be a non-empty list, got {short_repr(shards)}")
    for k, shard in enumerate(shards):
        if not (isinstance(shard, dict) and isinstance(shard.get("file"), str)
                and isinstance(shard.get("sha256"), str)):  # fmt: skip
            raise DatasetError(f"{path}: shards[{k}] must be an object with the strings 'file' "
                               f"and 'sha256', got {short_repr(shard)}")  # fmt: skip
    count = manifest.get("count")
    if not isinstance(count, int) or isinstance(count, bool) or count < 1:
        raise DatasetError(f"{path}: 'count' must be a positive integer, got {short_repr(count)}")
    return manifest


def load_dataset(folder: str | Path) -> Dataset:
    """Read a dataset folder written by :func:`save_dataset`, checking every shard. The
    windows are read into arrays of the manifest's count (memory: the dataset and one
    shard)."""
    folder = Path(folder)
    manifest = dataset_manifest(folder)
    (windows,) = _read_windows(folder, manifest, _checked_shards(folder, manifest))
    return Dataset(windows, manifest)


def load_split(
    folder: str | Path, test_fraction: float, seed: int
) -> tuple[dict, Windows, Windows]:
    """The manifest and ``(train, test)`` of :func:`split_by_track` of the dataset folder
    ``folder`` (the same windows in the same order), each side read straight from the shards:
    memory holds every window once (split after loading, it held them twice)."""
    folder = Path(folder)
    manifest = dataset_manifest(folder)
    files = _checked_shards(folder, manifest)
    tracks = [_shard_arrays(file, ("track",))["track"] for file in files]
    total = sum(map(len, tracks))
    if total != manifest["count"]:
        raise DatasetError(f"{folder / 'manifest.json'}: {total} windows, manifest says "
                           f"{manifest['count']}")  # fmt: skip
    held = held_out_tracks(np.concatenate(tracks), test_fraction, seed)
    test = [np.isin(t, held) for t in tracks]
    train, test = _read_windows(folder, manifest, files, [[~m for m in test], test])
    return manifest, train, test


def _checked_shards(folder: Path, manifest: dict) -> list[Path]:
    """The shard files of ``manifest``, each there and with its checksum."""
    files = []
    for shard in manifest["shards"]:
        file = folder / shard["file"]
        if not file.is_file():
            raise DatasetError(f"{folder}: shard {shard['file']} is missing")
        if sha256_of(file) != shard["sha256"]:
            raise DatasetError(f"{file}: checksum mismatch (the file was changed or truncated)")
        files.append(file)
    return files


def _read_windows(
    folder: Path, manifest: dict, files: list[Path], sides: list[list[np.ndarray]] | None = None
) -> list[Windows]:
    """The windows of the shard ``files`` in one pass over them: all of them, or for each
    side of ``sides`` (a mask per shard) those it selects, read into arrays of their
    count."""
    path = folder / "manifest.json"
    count = manifest["count"]
    if sides is None:
        sides = [[None] * len(files)]
    sizes = [
        count if any(m is None for m in masks) else int(sum(m.sum() for m in masks))
        for masks in sides
    ]
    out: list[dict[str, np.ndarray]] = [{} for _ in sides]
    labels: list[list[np.ndarray]] = [[] for _ in sides]  # (their string width varies)
    done, total = [0] * len(sides), 0
    for k, file in enumerate(files):
        whole = read_shard(file)
        total += len(whole)
        if total > count:
            raise DatasetError(f"{path}: the shards hold more windows than the manifest's "
                               f"count {count}")  # fmt: skip
        for j, masks in enumerate(sides):
            part = whole if masks[k] is None else whole.take(np.flatnonzero(masks[k]))
            n = len(part)
            for f in fields(Windows):
                value = getattr(part, f.name)
                if f.name == "track":
                    labels[j].append(value)
                    continue
                if f.name == "grids" and f.name not in out[j]:  # (nearly all the memory)
                    shapes = [(size, *value.shape[1:]) for size in sizes]
                    for side, grids in zip(out, grid_arrays(shapes, value.dtype, folder),
                                           strict=True):  # fmt: skip
                        side["grids"] = grids
                elif f.name not in out[j]:
                    out[j][f.name] = np.empty((sizes[j], *value.shape[1:]), value.dtype)
                have = out[j][f.name]
                if value.shape[1:] != have.shape[1:] or value.dtype != have.dtype:
                    raise DatasetError(f"{file}: {f.name!r} is {value.dtype} "
                                       f"{value.shape[1:]} per window, the first shard's "
                                       f"{have.dtype} {have.shape[1:]}")  # fmt: skip
                have[done[j] : done[j] + n] = value
            done[j] += n
    if total != count:
        raise DatasetError(f"{path}: {total} windows, manifest says {count}")
    return [Windows(**arrays, track=np.concatenate(tracks))
            for arrays, tracks in zip(out, labels, strict=True)]  # fmt: skip


def write_shard(file: Path, windows: Windows, compressed: bool = True) -> None:
    """``windows`` as one shard file (every array; written atomically): :func:`read_shard`
    reads it back."""
    write_npz(file, compressed=compressed,
              **{f.name: getattr(windows, f.name) for f in fields(Windows)})  # fmt: skip


def read_shard(file: Path) -> Windows:
    """One shard's windows (every array read; the checksum is the caller's)."""
    return Windows(**_shard_arrays(file, tuple(f.name for f in fields(Windows))))


def _shard_arrays(file: Path, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The arrays ``names`` of one shard (only those are read)."""
    try:
        with np.load(file) as data:
            return {name: data[name] for name in names}
    except KeyError as exc:
        raise DatasetError(f"{file}: no array {exc} (not a shard of this format)") from None
