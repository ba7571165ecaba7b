"""Test-session set-up.

NumPy's OpenBLAS picks its kernels by CPU model at start-up: its ``Haswell`` kernels on AVX2
CPUs and on AMD CPUs with AVX-512, its ``SkylakeX`` kernels on Intel CPUs with AVX-512, and the
two round some dot products, norms and least-squares fits (the recorded tracks' polynomial fits
and smoothing, the city road's geometry) differently in the last bit. The simulator's golden
digests were recorded with the Haswell kernels, so the tests ask for them on every CPU that
has AVX2 and FMA (before NumPy is imported; a user's own setting wins). The simulator itself
uses whatever OpenBLAS picks: see docs/performance.md, bit-identity.
"""

import os
import sys
from pathlib import Path


def _cpu_flags() -> set[str]:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


if "numpy" not in sys.modules and {"avx2", "fma"} <= _cpu_flags():
    os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")
