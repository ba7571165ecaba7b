"""Grids too big for the memory: read into a scratch file and mapped from it (the operating
system keeps in memory what fits), so that a dataset bigger than the memory still trains and
evaluates, with the same results bit for bit."""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import fields
from pathlib import Path

import numpy as np

from gridsim.errors import warn_data
from neurotrajectory.data.windows import DatasetError, Windows

#: Grids that would take more than this share of the memory available are mapped.
MEMORY_SHARE = 0.5
#: The environment variable naming the scratch folder (default: the system's temporary one,
#: unless it lives in memory; then the dataset's own folder).
SCRATCH_ENV = "NEUROTRAJECTORY_SCRATCH"
#: Windows copied at a time into a scratch array (:func:`concat_windows`).
_CHUNK = 1024


def memory_available() -> int | None:
    """The memory [bytes] available to a new allocation (Linux's ``MemAvailable``, else the
    free pages), or None where the system does not tell (then grids stay in memory)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, OSError, ValueError):  # (macOS has no free-page count, Windows
        return None  # no sysconf)


def grid_arrays(shapes: list[tuple], dtype, what: str | Path) -> list[np.ndarray]:
    """Empty arrays of ``shapes`` for the grids of ``what`` (a dataset, one array per side of
    a split): in memory, or, when together they would take more than :data:`MEMORY_SHARE`
    of the memory available, each mapped from a scratch file (:func:`scratch_folder`; the
    file has no name, so nothing is left behind however the process ends), with a warning
    that says so. A scratch folder missing, without room or not writable is named in a
    :class:`DatasetError`."""
    size = sum(math.prod(shape) for shape in shapes) * np.dtype(dtype).itemsize
    available = memory_available()
    if available is None or size <= MEMORY_SHARE * available:
        return [np.empty(shape, dtype) for shape in shapes]
    scratch = scratch_folder(Path(what))
    big = (f"{what}: its grids take {_gb(size)}, more than {MEMORY_SHARE:.0%} of the memory "
           f"available ({_gb(available)})")  # fmt: skip
    if not scratch.is_dir():
        raise DatasetError(f"{big}; {SCRATCH_ENV} names {scratch}, which is not a folder")
    free = shutil.disk_usage(scratch).free
    if size > free:
        raise DatasetError(f"{big}, and more than the free space of the scratch folder "
                           f"{scratch} ({_gb(free)}): set {SCRATCH_ENV} to a folder with "
                           "room, or record with a larger --stride")  # fmt: skip
    arrays = [_scratch_array(shape, dtype, scratch, big) for shape in shapes]
    chosen = (f"{SCRATCH_ENV}" if os.environ.get(SCRATCH_ENV)
              else f"set {SCRATCH_ENV} to choose another folder")  # fmt: skip
    warn_data(f"{big}: they are read into a scratch file in {scratch} ({chosen}); batches "
              "read from it")  # fmt: skip
    return arrays


def scratch_folder(near: Path) -> Path:
    """Where scratch files go: :data:`SCRATCH_ENV`'s folder; else the temporary folder,
    unless it lives in memory (tmpfs: Fedora and Arch mount ``/tmp`` so), then the folder of
    ``near`` (a dataset folder, or a file in one)."""
    named = os.environ.get(SCRATCH_ENV)
    if named:
        return Path(named)
    temporary = Path(tempfile.gettempdir())
    if not _in_memory(temporary):
        return temporary
    return near if near.is_dir() else near.parent


def _in_memory(folder: Path) -> bool:
    """Whether ``folder`` lies on a file system kept in memory (Linux's ``/proc/mounts``;
    elsewhere: no)."""
    try:
        with open("/proc/mounts") as f:
            mounts = [line.split()[1:3] for line in f if len(line.split()) > 2]
    except OSError:
        return False
    path = str(folder.resolve())
    best, kind = "", ""
    for point, fs in mounts:
        inside = path == point or path.startswith(point.rstrip("/") + "/")
        if inside and len(point) > len(best):
            best, kind = point, fs
    return kind in ("tmpfs", "ramfs")


def _scratch_array(shape: tuple, dtype, scratch: Path, big: str) -> np.ndarray:
    """An array mapped from a new, nameless file in ``scratch`` whose space is reserved at
    once (a disk filled later cannot end the process half-way; ``big``: the error's start)."""
    if not math.prod(shape):  # (nothing to map)
        return np.empty(shape, dtype)
    size = math.prod(shape) * np.dtype(dtype).itemsize
    f = None
    try:  # (the file is kept open while the array lives, not closed by a with)
        f = tempfile.TemporaryFile(prefix="neurotrajectory-grids-", dir=scratch)  # noqa: SIM115
        if hasattr(os, "posix_fallocate"):
            os.posix_fallocate(f.fileno(), 0, size)
        grids = np.memmap(f, dtype=dtype, mode="w+", shape=shape)
    except OSError as exc:
        if f is not None:
            f.close()
        raise DatasetError(f"{big}; a scratch file of that size in {scratch} failed "
                           f"({exc.strerror or exc}): set {SCRATCH_ENV} to a folder with room "
                           "that you may write to") from None  # fmt: skip
    grids.scratch_file = f  # (open while the array lives; a nameless file goes with it)
    return grids


def concat_windows(parts: list[Windows], what: str) -> Windows:
    """:meth:`Windows.concat`, the grids (selections too) copied a chunk at a time into an
    array of :func:`grid_arrays` (mapped when big): the same windows, without the whole
    dataset's grids in memory."""
    parts = [p for p in parts if len(p)]
    if not parts:
        raise DatasetError("no windows were recorded")
    first = parts[0].grids
    (grids,) = grid_arrays([(sum(map(len, parts)), *first.shape[1:])], first.dtype, what)
    done = 0
    for part in parts:
        for start in range(0, len(part), _CHUNK):
            stop = min(start + _CHUNK, len(part))
            grids[done + start : done + stop] = part.grids[np.arange(start, stop)]
        done += len(part)
    rest = {f.name: np.concatenate([getattr(p, f.name) for p in parts])
            for f in fields(Windows) if f.name != "grids"}  # fmt: skip
    return Windows(grids=grids, **rest)


def _gb(size: int) -> str:
    return f"{size / 2**30:.1f} GB"
