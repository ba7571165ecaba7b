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

from proc_cpuinfo import cpuinfo_field

if "numpy" not in sys.modules and {"avx2", "fma"} <= set(cpuinfo_field("flags").split()):
    os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")
