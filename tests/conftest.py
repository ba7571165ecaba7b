"""Test-session set-up: NumPy's OpenBLAS kernels pinned as the golden digests were recorded
(:mod:`openblas_pin`, imported before NumPy); the one-line notice of a kernel compiled at run
time counted as shown, so that no test's stderr depends on which test compiles first; the
temporary files the code under test leaves (crash reports, Stable-Baselines3's log folders
of the examples) kept in the session's own folder, not the system's."""

import os
import tempfile

import openblas_pin  # noqa: F401  (before NumPy)
import pytest

from gridsim import jit

jit._COMPILED["noticed"] = True


@pytest.fixture(autouse=True, scope="session")
def _temporary_files_in_the_session_folder(tmp_path_factory):
    """``tempfile``'s folder, and ``TMPDIR`` for the subprocesses, in pytest's base folder."""
    folder = str(tmp_path_factory.mktemp("tempdir"))
    before = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"], tempfile.tempdir = folder, folder
    yield
    if before[0] is None:
        os.environ.pop("TMPDIR", None)
    else:
        os.environ["TMPDIR"] = before[0]
    tempfile.tempdir = before[1]
