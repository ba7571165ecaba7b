"""Exceptions raised by gridsim for bad input.

Every error that reaches a user names what is wrong (file, key path, value, expected
range). Catch :class:`GridSimError` to handle any of them.
"""

from __future__ import annotations

import os
import re
import sys
import warnings


class GridSimError(Exception):
    """Base class of all errors raised by gridsim for bad input or bad state."""


class ScenarioError(GridSimError, ValueError):
    """A scenario (YAML file, name or override) is invalid."""


class UnselectedScene(ScenarioError):
    """A recorded scene that the ``ego.track`` list, shared by a collection's scenes, names no
    track of: a collection skips it (alone, it is refused)."""


class DataError(GridSimError, ValueError):
    """A data file (trajectory CSV, CommonRoad XML) is missing, malformed or inconsistent."""


class OutputError(GridSimError):
    """An output file or folder cannot be written: it exists, is in use by another process,
    or is not writable."""


class WorkKept(OutputError):
    """Refused, but the hidden folder of a resumable output (:func:`gridsim.outputs.new_folder`)
    is kept: it holds interrupted work to go on with."""


class DataWarning(UserWarning):
    """Data that is used, but not all of it: a flawed track kept as traffic only, a file of
    a collection that is skipped. The message names the file and the reason."""


class UnfitEgoWarning(DataWarning):
    """A track named as the ego (``ego.track``) that a random ego is not drawn from: it
    overlaps another, grazes a road edge or is a long vehicle (its episodes may end at
    once). A caller that drives such tracks on purpose (``record``) says so once."""


#: The first bytes of archives a text file may be handed in as, and what to do with each.
_ARCHIVES = {b"\x1f\x8b": "gzip-compressed: decompress it first (gunzip)",
             b"PK\x03\x04": "a zip archive: extract the file from it first",
             b"BZh": "bzip2-compressed: decompress it first (bunzip2)",
             b"\xfd7zXZ": "xz-compressed: decompress it first (unxz)"}  # fmt: skip


def archive_problem(path: str | os.PathLike) -> str | None:
    """What to do with ``path`` if it is a compressed file or archive rather than the text
    file it is read as (told by its first bytes), or None."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(6)
    except OSError:
        return None
    return next((said for magic, said in _ARCHIVES.items() if head.startswith(magic)), None)


def not_there(path: str | os.PathLike) -> str:
    """``path``, and, when it or a folder on its way is a link to nothing (an unmounted share,
    a moved file), where that link points: a missing file's name in messages."""
    here = os.path.abspath(path)
    while here != os.path.dirname(here):
        if os.path.islink(here) and not os.path.exists(here):
            target = os.path.normpath(os.path.join(os.path.dirname(here), os.readlink(here)))
            what = "a link" if here == os.path.abspath(path) else f"in {here}, a link"
            return f"{path} ({what} to {target}, which is not there)"
        here = os.path.dirname(here)
    return str(path)


def flagged(flag: str, value: object, message: object) -> str:
    """``"FLAG VALUE: MESSAGE"``, an error about a command-line flag's value; where the value
    is a path that the message names already (an error about a file names it), ``"FLAG:
    MESSAGE"``, so that the path is not said twice."""
    said, text = str(value), str(message)
    path_like = os.sep in said or os.path.splitext(said)[1] != "" or os.path.exists(said)
    named = re.search(rf"(^|[\s(]){re.escape(said)}($|[\s:),])", text)  # the path, whole
    return f"{flag}: {text}" if path_like and named else f"{flag} {said}: {text}"


#: Folders whose code is not where a user's call is (their frames are skipped by
#: :func:`warn_data`): gridsim's own, and those that register themselves (neurotrajectory).
_INTERNAL: list[str] = [os.path.dirname(__file__) + os.sep]


def count_as_internal(folder: str) -> None:
    """Let :func:`warn_data` skip the frames of code in ``folder`` (a package's own)."""
    _INTERNAL.append(os.path.join(folder, ""))


def warn_data(message: str, category: type[Warning] = DataWarning) -> None:
    """Warn ``message`` at the line of the user's code that led to it: the first frame
    outside gridsim (and the packages that :func:`count_as_internal`, and gymnasium's
    ``make``), not a line deep in the loader; Python's default filter then shows it once per
    message and user line."""
    gym = sys.modules.get("gymnasium")
    skipped = (*_INTERNAL, os.path.dirname(gym.__file__) + os.sep) if gym else tuple(_INTERNAL)
    frame, level = sys._getframe(1), 2
    while frame is not None and frame.f_code.co_filename.startswith(skipped):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level - 1 if frame is None else level)
