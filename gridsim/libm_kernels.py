"""Compiled loops of :mod:`gridsim.libm`: the C library's function on every element (numba
calls libm for ``math.*``)."""

from __future__ import annotations

import math

from gridsim.jit import kernel


@kernel
def arctan2(a, b, out) -> None:
    for i in range(len(out)):
        out[i] = math.atan2(a[i], b[i])


@kernel
def power(a, b, out) -> None:
    for i in range(len(out)):
        out[i] = math.pow(a[i], b[i])


@kernel
def arctan(x, out) -> None:
    for i in range(len(out)):
        out[i] = math.atan(x[i])


@kernel
def tan(x, out) -> None:
    for i in range(len(out)):
        out[i] = math.tan(x[i])


@kernel
def exp(x, out) -> None:
    for i in range(len(out)):
        out[i] = math.exp(x[i])
