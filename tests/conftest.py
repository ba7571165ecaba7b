"""Test-session set-up: NumPy's OpenBLAS kernels pinned as the golden digests were recorded
(:mod:`openblas_pin`, imported before NumPy); the one-line notice of a kernel compiled at run
time counted as shown, so that no test's stderr depends on which test compiles first."""

import openblas_pin  # noqa: F401  (before NumPy)

from gridsim import jit

jit._COMPILED["noticed"] = True
