"""Scenario collections: a folder or a glob pattern of scenario files (YAML or CommonRoad XML).

An environment made from a collection draws one of its scenarios per reset from the reset
seed (:func:`pick`). Its scenarios must agree on what fixes the spaces and the time step
(:data:`SHARED_KEYS`); they may differ in road, traffic and duration.
"""

from __future__ import annotations

import glob
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gridsim.errors import ScenarioError
from gridsim.scenario.loader import Scenario, load_scenario
from gridsim.seeding import Salt, stream

SUFFIXES = (".yaml", ".yml", ".xml")
#: Keys on which the scenarios of a collection must agree (spaces, time step).
SHARED_KEYS = ("sensor", "env", "ego.vehicle", "simulation.dt")


def scenario_files(ref: str | Path) -> list[Path] | None:
    """The scenario files of a folder (sorted by name) or of a glob pattern (sorted);
    ``None`` if ``ref`` is neither (a built-in name or a single file, or not a name or
    path at all: :func:`load_scenario` then says so)."""
    if not isinstance(ref, str | os.PathLike):
        return None
    text = str(ref)
    path = Path(text)
    if path.is_dir():
        files = [f for f in path.iterdir() if f.is_file() and f.suffix.lower() in SUFFIXES]
    elif any(c in text for c in "*?["):
        files = [Path(f) for f in glob.glob(text, recursive=True)]
        files = [f for f in files if f.is_file() and f.suffix.lower() in SUFFIXES]
    else:
        return None
    if not files:
        raise ScenarioError(f"{text}: no scenario files ({', '.join(SUFFIXES)}) in it")
    return sorted(files)


def is_collection(ref: str | Path) -> bool:
    """Whether ``ref`` names a folder or a glob pattern (not a check that it has files)."""
    text = str(ref)
    return Path(text).is_dir() or any(c in text for c in "*?[")


def _get(doc: dict, key: str) -> Any:
    for part in key.split("."):
        doc = doc[part]
    return doc


def load_collection(ref: str | Path, overrides: Mapping[str, Any] | None = None) -> list[Scenario]:
    """The scenarios of a folder or glob (or the one scenario ``ref`` names), ``overrides``
    applied to each; :class:`ScenarioError` if they disagree on :data:`SHARED_KEYS`."""
    files = scenario_files(ref)
    if files is None:
        return [load_scenario(ref, overrides)]
    scenarios = [load_scenario(f, overrides) for f in files]
    first = scenarios[0].config.model_dump()
    for sc in scenarios[1:]:
        doc = sc.config.model_dump()
        for key in SHARED_KEYS:
            if _get(doc, key) != _get(first, key):
                raise ScenarioError(
                    f"{ref}: the scenarios of a collection must agree on {key}; "
                    f"{sc.source} differs from {scenarios[0].source}"
                )
    return scenarios


def pick(scenarios: list[Scenario], seed: int) -> Scenario:
    """The scenario of a collection for an episode seed (the first if there is one)."""
    if len(scenarios) == 1:
        return scenarios[0]
    rng = stream(seed, Salt.SCENARIO_PICK)
    return scenarios[int(rng.integers(len(scenarios)))]
