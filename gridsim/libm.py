"""Elementary functions of float64 and float32 numbers and arrays computed by the C library
(libm), so that a result does not depend on the CPU's vector instructions.

NumPy computes ``arctan2``, ``arctan``, ``tan``, ``exp``, ``power`` and others with its own
SIMD code on CPUs with AVX-512 (``numpy.show_runtime()`` lists ``X86_V4``); those results differ
from the C library's, and so between machines, in the last bit for a few percent of inputs. On
AVX2 CPUs NumPy calls the C library (``atan2`` for float64, ``atan2f`` for float32), as numba's
kernels and Python's ``math`` do. The simulator computes every such function that a result
depends on here (``tests/test_gridsim/test_libm.py`` compares with NumPy on AVX2 and with ``math``).

Each function takes scalars or arrays of any shape, broadcast together. float32 inputs (all of
them float32) give float32 results (libm's float function), anything else float64. Python and
float64 scalars give a Python float, float32 scalars a ``np.float32``. Non-finite inputs and
overflow give nan / inf as NumPy does (no exception); complex input is refused.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

_FLOATS = (float, np.float64)


def _apply(name: str, scalar: Callable, args: tuple):
    if all(type(a) in _FLOATS for a in args):  # the common case, without array conversions
        try:
            return scalar(*args)
        except (ValueError, OverflowError):  # math raises where libm gives nan / inf
            pass
    arrays = [np.asarray(a) for a in args]
    if any(np.iscomplexobj(a) for a in arrays):
        raise TypeError(f"gridsim.libm.{name} takes real numbers, got a complex input")
    dtype = np.float32 if all(a.dtype == np.float32 for a in arrays) else np.float64
    if dtype == np.float64 and all(a.ndim == 0 for a in arrays):
        try:
            return scalar(*(float(a) for a in arrays))
        except (ValueError, OverflowError):  # math raises where libm gives nan / inf
            pass
    from gridsim import libm_kernels  # numba only when an array first needs it

    arrays = np.broadcast_arrays(*arrays)
    out = np.empty(arrays[0].shape, dtype)
    flat = [np.array(a, dtype=dtype, order="C").reshape(-1) for a in arrays]  # own copies
    getattr(libm_kernels, name)(*flat, out.reshape(-1))
    if out.ndim == 0:
        return float(out) if dtype == np.float64 else out[()]
    return out


def _function(name: str, scalar: Callable):
    def f(*args):
        return _apply(name, scalar, args)

    f.__name__ = f.__qualname__ = name
    f.__doc__ = f"``math.{scalar.__name__}`` of each element (see the module)."
    return f


arctan2 = _function("arctan2", math.atan2)
power = _function("power", math.pow)
arctan = _function("arctan", math.atan)
tan = _function("tan", math.tan)
exp = _function("exp", math.exp)

#: Each function and how many arguments it takes (``gridsim compile`` readies each kernel
#: for both dtypes it runs on, float64 and float32).
ARITY = {arctan2: 2, power: 2, arctan: 1, tan: 1, exp: 1}


def angle(z) -> np.ndarray | float:
    """The argument of complex ``z`` [rad] (``np.angle``, with :func:`arctan2`)."""
    z = np.asarray(z)
    return arctan2(z.imag, z.real)
