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


def test_the_first_compile_of_a_gridsim_kernel_prints_one_notice(monkeypatch, capsys):
    """A compilation (not a cache load) of GridSim's own kernels is counted, and the first
    of a process prints gridsim.jit.NOTICE on stderr; other packages' kernels are not."""
    from types import SimpleNamespace

    from gridsim import jit

    monkeypatch.setattr(jit, "_COMPILED", {"count": 0, "noticed": False})
    listener = jit._CompileNotice()

    def event(module: str):
        return SimpleNamespace(data={"dispatcher": SimpleNamespace(
            py_func=SimpleNamespace(__module__=module))})  # fmt: skip

    listener.on_start(event("someone_else.kernels"))
    assert jit.compiled_kernels()["compiled"] == 0 and capsys.readouterr().err == ""
    listener.on_start(event("gridsim.world.world_kernels"))
    listener.on_start(event("gridsim.sensors.rays"))
    assert jit.compiled_kernels()["compiled"] == 2
    assert capsys.readouterr().err == jit.NOTICE + "\n"


def test_gridsim_compile_readies_every_kernel_of_the_built_in_scenarios(capsys):
    from gridsim.cli import main
    from gridsim.jit import compiled_kernels

    assert main(["compile"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("compiling or loading the kernels of every built-in scenario:")
    assert f"{compiled_kernels()['kernels']} kernels ready (" in out
