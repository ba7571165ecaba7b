"""Elementary functions of float64 numbers and arrays computed by the C library (libm), so that
a result does not depend on the CPU it was computed on.

NumPy computes ``arctan2``, ``arctan``, ``tan``, ``exp``, ``power`` and others with its own
SIMD code on CPUs with AVX-512 (``numpy.show_runtime()`` lists ``X86_V4``); those results differ
from the C library's, and so between machines, in the last bit for a few percent of inputs. On
other CPUs NumPy calls the C library, as numba's kernels and Python's ``math`` always do. The
simulator computes every such function that a result depends on here, and so gives the same bits
on every machine (``tests/test_golden.py``; ``tests/test_libm.py`` compares with ``math``).

Each function takes Python or NumPy scalars (returns a Python float) or arrays of any shape,
broadcast together (returns a float64 array).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np


def _unary(scalar: Callable[[float], float], name: str):
    def f(x):
        if np.ndim(x) == 0:
            return scalar(float(x))
        from gridsim import libm_kernels  # numba only when an array first needs it

        a = np.ascontiguousarray(x, dtype=np.float64)
        out = np.empty(a.shape)
        getattr(libm_kernels, name)(a.reshape(-1), out.reshape(-1))
        return out

    f.__name__ = f.__qualname__ = name
    f.__doc__ = f"``math.{scalar.__name__}`` of each element (see the module)."
    return f


def _binary(scalar: Callable[[float, float], float], name: str):
    def f(a, b):
        if np.ndim(a) == 0 and np.ndim(b) == 0:
            return scalar(float(a), float(b))
        from gridsim import libm_kernels

        a, b = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
        out = np.empty(a.shape)
        flat = [np.ascontiguousarray(v).reshape(-1) for v in (a, b)]
        getattr(libm_kernels, name)(*flat, out.reshape(-1))
        return out

    f.__name__ = f.__qualname__ = name
    f.__doc__ = f"``math.{scalar.__name__}`` of each pair of elements (see the module)."
    return f


arctan2 = _binary(math.atan2, "arctan2")
power = _binary(math.pow, "power")
arctan = _unary(math.atan, "arctan")
tan = _unary(math.tan, "tan")
exp = _unary(math.exp, "exp")


def angle(z) -> np.ndarray | float:
    """The argument of complex ``z`` [rad] (``np.angle``, with :func:`arctan2`)."""
    z = np.asarray(z)
    return arctan2(z.imag, z.real)
