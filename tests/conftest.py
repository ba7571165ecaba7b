"""Test-session set-up: NumPy's OpenBLAS kernels pinned as the golden digests were recorded
(:mod:`openblas_pin`, imported before NumPy)."""

import openblas_pin  # noqa: F401  (before NumPy)
