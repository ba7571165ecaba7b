"""Compiled kernels: cached across processes, and still working without a cache location."""

import subprocess
import sys

import numpy as np

import gridsim.jit as jit

_CALL = (
    "import numpy as np; from gridsim.sensors.rays import mark_visible as f;"
    "f(np.zeros((4, 4), np.float32), np.zeros((4, 4), np.intp), np.zeros(3, np.float32),"
    " np.zeros((4, 4), np.uint8));"
    "print(sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values()))"
)


def test_a_second_process_loads_the_compiled_kernel_from_the_cache():
    runs = [subprocess.run([sys.executable, "-c", _CALL], capture_output=True, text=True)
            for _ in range(2)]  # fmt: skip
    assert all(r.returncode == 0 for r in runs), runs[-1].stderr
    hits, misses = map(int, runs[-1].stdout.split())
    assert (hits, misses) == (1, 0)


def test_kernels_compile_when_no_cache_location_is_writable(monkeypatch):
    njit = jit.numba.njit

    def no_cache(*args, cache=False, **kwargs):
        if cache:
            raise RuntimeError("cannot cache function: no locator available")
        return njit(*args, **kwargs)

    monkeypatch.setattr(jit.numba, "njit", no_cache)

    def twice(x):
        return 2 * x

    assert jit.kernel(twice)(np.arange(3)).tolist() == [0, 2, 4]
