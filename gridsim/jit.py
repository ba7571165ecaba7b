"""Compiled kernels: numba's ``njit``, compiled on first call and cached on disk.

numba is imported only by the modules that define kernels (not by ``import gridsim``). The
compiled code is cached next to the source (or in numba's user-wide cache directory when the
package directory is read-only), so that later processes load it instead of compiling; when
no cache location is writable at all, kernels are compiled once per process. ``fastmath`` is
never used: kernels must give the same bits as the NumPy code they replace. Nor is Intel's
SVML (numba would vectorise ``math`` calls with it when ``intel-cmplr-lib-rt`` is installed,
with other results than libm's): ``NUMBA_DISABLE_INTEL_SVML`` is set unless the user set it.

numba checks a cached kernel against its own source file only: after editing a kernel that
kernels in other modules call (e.g. ``polyline_kernels.project``, called by
``scripted_driver_kernels.route_leader``), delete the ``__pycache__/*.nbi`` and ``*.nbc``
files of the package (a fresh checkout has none), or the callers keep the old code.
"""

from __future__ import annotations

import os
from collections.abc import Callable

os.environ.setdefault("NUMBA_DISABLE_INTEL_SVML", "1")  # read when numba is first imported

import numba  # noqa: E402
from numba.extending import register_jitable  # noqa: E402


def kernel(fn: Callable) -> Callable:
    """``fn`` as a lazily compiled, disk-cached numba function (``nopython``, no fastmath)."""
    try:
        return numba.njit(cache=True, nogil=True)(fn)
    except RuntimeError:  # no writable cache location
        return numba.njit(nogil=True)(fn)


def jitable(fn: Callable) -> Callable:
    """``fn`` unchanged for Python callers, compiled inline when a kernel calls it."""
    return register_jitable(fn)


@jitable
def search_right(keys, k) -> int:
    """``searchsorted(keys, k, side="right") - 1`` in the sorted array ``keys`` (binary
    search; -1 when ``k`` is below every key): the segment look-up that the compiled table and
    polyline queries share."""
    lo, hi = 0, len(keys)
    while lo < hi:
        mid = (lo + hi) >> 1
        if keys[mid] <= k:
            lo = mid + 1
        else:
            hi = mid
    return lo - 1
