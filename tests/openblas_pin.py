"""Importing this module pins NumPy's OpenBLAS to its ``Haswell`` kernels on every CPU with AVX2
and FMA, as the golden digests were recorded (import it before NumPy; a user's own
``OPENBLAS_CORETYPE`` wins).

OpenBLAS picks its kernels by CPU model at start-up: ``Haswell`` on AVX2 CPUs and (usually) on
AMD CPUs with AVX-512, ``SkylakeX`` on Intel CPUs with AVX-512, and the two round some dot
products, norms and least-squares fits (the recorded tracks' polynomial fits and smoothing,
the city road's geometry, the warm start's ridge fit) differently in the last bit. Both the
test session (``conftest.py``) and the recorder (``golden.py`` run as a script) import it, so
that digests are recorded and checked with the same kernels. The simulator itself uses
whatever OpenBLAS picks: see docs/performance.md, bit-identity.
"""

import os
import sys

from proc_cpuinfo import cpuinfo_field

if "numpy" not in sys.modules and {"avx2", "fma"} <= set(cpuinfo_field("flags").split()):
    os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")
