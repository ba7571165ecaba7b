"""Checks of output paths, made before anything is written."""

from __future__ import annotations

import os
from pathlib import Path


def output_problem(path: str | Path, directory: bool) -> str | None:
    """Why ``path`` cannot be created (or written) as a folder (``directory``) or a file, or
    None if it can. Nothing is created."""
    path = Path(path)
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
    return None


def new_folder_problem(path: str | Path) -> str | None:
    """Why ``path`` cannot become a new output folder (one that can be created, or an empty
    one), or None if it can."""
    problem = output_problem(path, directory=True)
    if problem is None and Path(path).is_dir() and any(Path(path).iterdir()):
        problem = "exists and is not empty: choose another --out"
    return problem
