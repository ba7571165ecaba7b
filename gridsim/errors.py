"""Exceptions raised by gridsim for bad input.

Every error that reaches a user names what is wrong (file, key path, value, expected
range). Catch :class:`GridSimError` to handle any of them.
"""

from __future__ import annotations


class GridSimError(Exception):
    """Base class of all errors raised by gridsim for bad input or bad state."""


class ScenarioError(GridSimError, ValueError):
    """A scenario (YAML file, name or override) is invalid."""


class DataError(GridSimError, ValueError):
    """A data file (trajectory CSV, CommonRoad XML) is missing, malformed or inconsistent."""


class OutputError(GridSimError):
    """An output file or folder cannot be written: it exists, is in use by another process,
    or is not writable."""


class DataWarning(UserWarning):
    """Data that is used, but not all of it: a flawed track kept as traffic only, a file of
    a collection that is skipped. The message names the file and the reason."""


class UnfitEgoWarning(DataWarning):
    """A track named as the ego (``ego.track``) that a random ego is not drawn from: it
    overlaps another, grazes a road edge or is a long vehicle (its episodes may end at
    once). A caller that drives such tracks on purpose (``record``) says so once."""
