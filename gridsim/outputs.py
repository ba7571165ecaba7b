"""Output files and folders: checks made before anything is written, and atomic writes
(a reader never sees half a file: each is written beside its place and renamed)."""

from __future__ import annotations

import errno
import fcntl
import json
import math
import os
import re
import reprlib
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from gridsim.errors import OutputError, WorkKept

#: The lock file of a folder being written (:func:`folder_lock`).
LOCK_NAME = ".lock"


def output_problem(path: str | Path, directory: bool) -> str | None:
    """Why ``path`` cannot be created (or written) as a folder (``directory``) or a file, or
    None if it can. Nothing is left behind (a probe file is created in the folder it would be
    made in and removed: permissions alone do not tell a read-only or virtual file system,
    such as /proc, from a writable one)."""
    path = Path(path)
    try:
        return _output_problem(path, directory)
    except PermissionError as exc:  # a folder on the way that may not be searched
        return f"{exc.filename or path} is not accessible ({exc.strerror})"


def _output_problem(path: Path, directory: bool) -> str | None:
    if path.is_dir() and not directory:
        return "is a folder, expected a file"
    if path.exists() and directory and not path.is_dir():
        return "is a file, expected a folder"
    if path.exists():
        target = path if directory else path.absolute().parent
    else:
        target = path.absolute().parent
        while not target.exists():
            target = target.parent
        if not target.is_dir():
            return f"{target} is a file, not a folder"
    if not os.access(target, os.W_OK | os.X_OK):
        return f"{target} is not writable"
    try:
        with tempfile.TemporaryFile(dir=target):
            pass
    except OSError as exc:
        return f"{target} is not writable ({exc.strerror or exc})"
    return None


def read_manifest(
    folder: str | Path,
    name: str,
    what: str,
    error: type[Exception],
    formats: tuple[int, ...],
    keys: tuple[str, ...] = (),
) -> dict:
    """The JSON object ``folder/name`` that makes ``folder`` a ``what`` (a run, a dataset),
    checked: it exists, parses, is an object with ``"format"`` in ``formats`` (the last is
    today's) and the ``keys``. Anything else raises ``error`` with a message that names the
    file and what is wrong."""
    folder = Path(folder)
    path = folder / name
    if not path.is_file():
        raise error(f"{folder} is not a {what} (no {name})")
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{path}: unreadable JSON ({exc})") from None
    needed = ("format", *keys)
    if not isinstance(doc, dict) or any(k not in doc for k in needed):
        kind = {dict: "an object", list: "a list", str: "a string"}.get(type(doc), repr(doc))
        if isinstance(doc, dict):
            kind += f" without {', '.join(repr(k) for k in needed if k not in doc)}"
        raise error(f"{path}: expected an object with {' and '.join(map(repr, needed))}, "
                    f"got {kind}")  # fmt: skip
    if isinstance(doc["format"], bool) or doc["format"] not in formats:
        raise error(f"{path}: format {short_repr(doc['format'])}, expected {formats[-1]}")
    return doc


#: s between a progress bar's redraws where its stream is not a terminal (a log file, a
#: pipe): a line every half minute in the log, not a redraw every tenth of a second
LOG_INTERVAL = 30.0


_CURSOR_MOVES = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


class _LogLines:
    """A progress bar's stream that is not a terminal, written a line per redraw: tqdm
    returns to the line's start (``\\r``) to redraw it, which a log keeps as one long line,
    and a message printed after a redraw was glued to it (``...23/29 [00:01<00:00,
    19.3episode/s]neurotrajectory: copying ...``)."""

    def __init__(self, stream) -> None:
        self.stream = stream

    def write(self, text: str) -> None:
        # (a bar below another moves the cursor up and back: not a line of a log)
        line = _CURSOR_MOVES.sub("", text.replace("\r", "")).rstrip()
        if line:  # (a clearing of the line, or the bar's closing line break: nothing)
            self.stream.write(line + "\n")

    def flush(self) -> None:
        self.stream.flush()

    def __getattr__(self, name: str):  # (encoding, isatty, ...: the stream's)
        return getattr(self.stream, name)


def progress_bar(*args: Any, **kwargs: Any):
    """A tqdm progress bar (its arguments), on stderr unless ``file`` says otherwise; where
    that stream is not a terminal it is first drawn after :data:`LOG_INTERVAL` seconds and
    redrawn every :data:`LOG_INTERVAL` seconds at most."""
    import sys

    from tqdm import tqdm

    stream = kwargs.get("file") or sys.stderr
    try:
        terminal = stream.isatty()
    except (AttributeError, ValueError):  # (a closed or odd stream)
        terminal = False
    if not terminal:  # (and a bar done sooner is not drawn at all: no line per short bar)
        kwargs.setdefault("mininterval", LOG_INTERVAL)
        kwargs.setdefault("maxinterval", LOG_INTERVAL)
        kwargs.setdefault("delay", LOG_INTERVAL)
        kwargs["file"] = _LogLines(stream)
    bar = tqdm(*args, **kwargs)
    if not terminal:  # a new postfix waits for the next redraw (each forced one, every epoch)
        postfix = bar.set_postfix
        bar.set_postfix = lambda *a, refresh=True, **k: postfix(*a, refresh=False, **k)
    return bar


def named(items: list, shown: int = 5, sep: str = ", ") -> str:
    """The first ``shown`` of ``items`` joined by ``sep``, the rest counted: ``"a, b, c, d, e
    and 7 more"``."""
    more = f" and {len(items) - shown} more" if len(items) > shown else ""
    return sep.join(map(str, items[:shown])) + more


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, plural unless it is 1: ``"1 epoch"``, ``"25 epochs"``."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def rounded(data: Any, digits: int = 4) -> Any:
    """``data`` (JSON-like: dicts, lists, numbers) with every float rounded to ``digits``
    significant digits, for printing; files keep full precision. ``159.2723388671875`` ->
    ``159.3``, ``1.05e-11`` -> ``1.054e-11``."""
    if isinstance(data, float):  # (whole digits are kept: 12345.6 -> 12346.0, not 12350.0)
        whole = len(str(int(abs(data)))) if math.isfinite(data) and abs(data) >= 1 else 0
        return round(data, max(0, digits - whole)) if whole else float(f"{data:.{digits}g}")
    if isinstance(data, dict):
        return {key: rounded(value, digits) for key, value in data.items()}
    if isinstance(data, (list, tuple)):
        return [rounded(value, digits) for value in data]
    return data


def as_given(value: Any, missing: str = "none") -> str:
    """A setting's ``value`` as a command line gives it: a list's items apart, a float by
    ``:g``, None as ``missing`` (what a message says of a flag not given)."""
    if value is None:
        return missing
    if isinstance(value, tuple | list):
        return " ".join(as_given(v, missing) for v in value) or missing
    return f"{value:g}" if isinstance(value, float) else str(value)


def short_repr(value: Any) -> str:
    """``repr(value)``, cut to a readable length for an error message."""
    return reprlib.repr(value)


def new_folder_problem(path: str | Path, hint: str = "choose another --out") -> str | None:
    """Why ``path`` cannot become a new output folder (one that can be created, or an empty
    one), or None if it can; ``hint`` ends the message about a folder that is not empty."""
    problem = output_problem(path, directory=True)
    if problem is None and Path(path).is_dir() and _contents(Path(path)):
        problem = f"exists and is not empty: {hint}"
    return problem


def _contents(folder: Path) -> list[Path]:
    """What ``folder`` holds besides its lock file."""
    return [p for p in folder.iterdir() if p.name != LOCK_NAME]


def empty_folder(folder: str | Path, keep: tuple[str, ...] = ()) -> None:
    """Remove everything ``folder`` holds but its lock file and the names ``keep`` (folders
    and their contents; links, not what they point to)."""
    for p in _contents(Path(folder)):
        if p.name in keep:
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink()


def folder_holder(folder: str | Path) -> str | None:
    """Who holds ``folder`` for writing (:func:`folder_lock`: ``"pid N, since ..."``), or None
    when no process does."""
    path = Path(folder) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return os.pread(fd, 200, 0).decode(errors="replace").strip() or "unknown"
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


@contextmanager
def folder_lock(folder: str | Path, flag: str = "--out") -> Iterator[Path]:
    """Hold the folder ``folder`` (created if needed) for writing: one process at a time. A
    second one gets an :class:`~gridsim.errors.OutputError` naming the holder (its pid and
    start). The lock (``flock`` on ``folder/.lock``) ends with the block or the process,
    also a killed one; the empty lock file stays."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "unknown"
            raise OutputError(f"{flag} {folder}: in use by another process ({holder}); wait "
                              f"for it to end or choose another {flag}") from None  # fmt: skip
        os.ftruncate(fd, 0)
        stamp = time.strftime("%Y-%m-%d %H:%M:%S")
        os.pwrite(fd, f"pid {os.getpid()}, since {stamp}\n".encode(), 0)
        try:
            yield folder
        finally:
            os.ftruncate(fd, 0)
    finally:
        os.close(fd)  # releases the lock


@contextmanager
def new_folder(out: str | Path, flag: str = "--out", hint: str = "choose another --out",
               resumable: bool = False) -> Iterator[Path]:  # fmt: skip
    """A new output folder written as a whole or not at all: the block writes into a hidden
    folder beside ``out`` (which it gets), renamed to ``out`` when the block ends without an
    error and removed otherwise, so that a failed or killed command leaves ``out`` as it was.
    One process at a time (:func:`folder_lock` on the hidden folder); ``out`` must be new or
    empty (checked before and after taking the lock). ``resumable``: the block gets the
    hidden folder as an interrupted block left it (Ctrl-C, a full disk or a killed process),
    and decides what of it to keep; it is kept when the block is interrupted again, or
    refuses to go on with it (:class:`~gridsim.errors.WorkKept`)."""
    out = Path(out)
    problem = new_folder_problem(out, hint)
    if problem:
        raise OutputError(f"{flag} {out}: {problem}")
    partial = out.absolute().parent / f".{out.name}.partial"
    with folder_lock(partial, flag):
        problem = new_folder_problem(out, hint)  # another process may have finished it
        if problem:
            raise OutputError(f"{flag} {out}: {problem}")
        if not resumable:
            empty_folder(partial)  # what a killed process left
        try:
            yield partial
        except BaseException as exc:
            if not (resumable and (interrupted(exc) or isinstance(exc, WorkKept))):
                shutil.rmtree(partial, ignore_errors=True)
            raise
        (partial / LOCK_NAME).unlink()
        if out.is_dir():
            out.rmdir()  # empty (checked under the lock)
        partial.rename(out)


#: Errors of a full disk or quota, not of the program.
DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` interrupted work that can go on when the command runs again (Ctrl-C,
    a full disk or quota), rather than showing it cannot."""
    disk_full = isinstance(exc, OSError) and exc.errno in DISK_FULL
    return isinstance(exc, KeyboardInterrupt) or disk_full


def _mode_for(path: Path) -> int:
    """The permissions ``path`` keeps, or a new file gets under the process's umask."""
    if path.exists():
        return path.stat().st_mode & 0o777
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextmanager
def _beside(path: Path) -> Iterator[str]:
    """A temporary file beside ``path`` that replaces it when the block ends without an
    error (and is removed otherwise)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        try:
            yield tmp
        except OSError as exc:  # a full disk: the file it was writing named (not the hidden one)
            if exc.errno in DISK_FULL and exc.filename in (None, "", tmp):
                raise OSError(exc.errno, exc.strerror, str(path)) from exc
            raise
        os.chmod(tmp, _mode_for(path))  # mkstemp's files are private (0600)
        _sync(tmp, strict=True)  # on disk before the rename: a power cut leaves the old
        os.replace(tmp, path)  # file or the new
        _sync(path.parent)  # and the rename itself
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


#: What ``fsync`` says where a file system (or the platform: Windows, a read-only descriptor)
#: cannot sync: nothing to do.
_CANNOT_SYNC = (errno.EINVAL, errno.ENOTSUP, errno.EBADF, errno.EACCES, errno.EPERM)


def _sync(path: str | Path, strict: bool = False) -> None:
    """``fsync`` a file or a folder. Where the file system or the platform cannot, nothing
    is done (the rename is still atomic for the processes); another error of a file's sync
    (``strict``: an I/O error, a full disk on a network file system) is raised: its data may
    not be on disk, and it must not replace the file there."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError as exc:
        if strict and exc.errno not in _CANNOT_SYNC:
            raise
    finally:
        os.close(fd)


def atomic_write(path: str | Path, write: Callable[[str], Any]) -> Path:
    """Call ``write(temporary_path)``, then rename the file to ``path``: never half a file."""
    path = Path(path)
    with _beside(path) as tmp:
        write(tmp)
    return path


@contextmanager
def atomic_text(path: str | Path) -> Iterator[TextIO]:
    """A text file (``newline=""``, for :mod:`csv`) that appears at ``path``, whole, when the
    ``with`` block ends without an error."""
    with _beside(Path(path)) as tmp, open(tmp, "w", newline="") as fh:
        yield fh


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def summary_text(data: Any, indent: int = 2) -> str:
    """A command's summary as the JSON it prints: paths and names as written (``ü``, not
    ``\\u00fc``, which a user copying a path would get), unless standard output cannot
    write them (an ASCII or code-page console: then escaped, as JSON allows)."""
    text = json.dumps(data, indent=indent, ensure_ascii=False)
    try:
        text.encode(getattr(sys.stdout, "encoding", None) or "utf-8")
    except (UnicodeEncodeError, LookupError):
        return json.dumps(data, indent=indent)
    return text


def write_json(path: str | Path, data: Any, indent: int = 1) -> Path:
    """Write ``data`` as JSON to ``path`` atomically."""
    return write_text(path, json.dumps(data, indent=indent))


def write_npz(path: str | Path, compressed: bool = False, **arrays: np.ndarray) -> Path:
    """Write ``arrays`` as an ``.npz`` archive to ``path`` atomically."""
    save = np.savez_compressed if compressed else np.savez

    def write(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            save(fh, **arrays)

    return atomic_write(path, write)
