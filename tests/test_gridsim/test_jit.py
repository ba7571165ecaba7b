"""Compiled kernels: cached across processes, and still working without a cache location."""

import subprocess
import sys

import numpy as np
import pytest

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
    monkeypatch.delenv(jit.NOTICED_VARIABLE, raising=False)
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
    # the processes it starts (a trainer's workers) inherit that it was said: said once
    import subprocess
    import sys

    code = ("from types import SimpleNamespace as N; from gridsim import jit; "
            "jit._CompileNotice().on_start(N(data={'dispatcher': N(py_func=N("
            "__module__='gridsim.sensors.rays'))}))")  # fmt: skip
    child = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True)  # fmt: skip
    assert child.stderr == ""
    monkeypatch.delenv(jit.NOTICED_VARIABLE)
    child = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True)  # fmt: skip
    assert child.stderr == jit.NOTICE + "\n"


def test_gridsim_compile_readies_every_kernel_of_the_built_in_scenarios(capsys):
    from gridsim.cli import main
    from gridsim.jit import compiled_kernels

    assert main(["compile"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("compiling or loading the kernels of every built-in scenario:")
    assert f"{compiled_kernels()['kernels']} kernels ready (" in out
    # every signature a trainer meets too: the C library's functions on float32 arrays, the
    # destination curves of its prior (float32 features and times), its pooled grids
    from gridsim import libm

    before = compiled_kernels()["compiled"]
    for function, arity in libm.ARITY.items():
        function(*[np.linspace(0.1, 0.9, 3, dtype=np.float32)] * arity)
    torch = pytest.importorskip("torch")  # the trainer's extra
    from neurotrajectory.curves import CurveLimits, destination_curves
    from neurotrajectory.model import PRESETS, PopulationNet, TrajectoryNet, block_means

    ego = np.tile(np.float32([10, 0, 0, 0, 1, 0]), (3, 1))
    times = np.float32([0.5, 1.0])
    destination_curves(ego, np.ones((3, 2), np.float32), times, CurveLimits(), 5.0)
    block_means(np.zeros((2, 4, 4), np.uint8), 2)
    net = PopulationNet(PRESETS["tiny"])  # its first convolution, compiled
    genomes = torch.nn.utils.parameters_to_vector(TrajectoryNet(net.cfg).parameters())
    store = net.store(genomes.detach().repeat(2, 1))
    params = net.params(store, net.small_copy(store), np.arange(2))
    net._features_compiled(params, np.zeros((2, 2, 128, 128), np.uint8))
    assert compiled_kernels()["compiled"] == before


@pytest.mark.slow  # (a subprocess)
def test_gridsim_compile_calls_the_kernels_only_a_yielding_shadow_driver_meets():
    """The paths' look-ahead of a shadow human that gives way (``table_kernels.frenet``) is
    met rarely, so the compile drive of a few steps missed it, and an installed simulator
    compiled it mid-run ("compiling the simulator's kernels ..." on inner-city seeds 0-19):
    ``gridsim compile`` calls it itself (a fresh process: the kernel has its signature)."""
    code = ("from gridsim.cli.compile import compile_kernels\n"
            "from gridsim.traffic import table_kernels\n"
            "compile_kernels(report=lambda line: None)\n"
            "print(len(table_kernels.frenet.signatures))")  # fmt: skip
    run = subprocess.run([sys.executable, "-W", "ignore", "-c", code], capture_output=True,
                         text=True, check=True)  # fmt: skip
    assert run.stdout.split()[-1] == "1"


def _package(root):
    """A toy package: a kernel module using a jitable function and a constant of two other
    modules, an unrelated module, and cached kernels in two ``__pycache__`` folders."""
    pkg = root / "gridsim"
    (pkg / "sub" / "__pycache__").mkdir(parents=True)
    (pkg / "__pycache__").mkdir()
    (pkg / "sub" / "k_kernels.py").write_text(
        "from gridsim.helpers import step\nfrom gridsim.consts import LIMIT\n"
        "from gridsim import more\n\n"
        "@kernel\ndef go(x):\n    return step(x) + LIMIT + more.OFFSET\n"
    )
    (pkg / "more.py").write_text("OFFSET = 1\n")
    (pkg / "helpers.py").write_text("@jitable\ndef step(x):\n    return x + 1\n")
    (pkg / "consts.py").write_text("LIMIT = 3\n")
    (pkg / "unrelated.py").write_text("def f():\n    return 1\n")
    caches = [pkg / "sub" / "__pycache__" / "k_kernels.go-4.py311.nbi",
              pkg / "sub" / "__pycache__" / "k_kernels.go-4.py311.0.nbc",
              pkg / "__pycache__" / "helpers.step-1.py311.nbi"]  # fmt: skip
    return pkg, caches


def _cache(caches):
    for c in caches:
        c.write_bytes(b"cached")


def test_cached_kernels_are_dropped_when_a_source_they_depend_on_changes(tmp_path):
    pkg, caches = _package(tmp_path)
    sources = [p.relative_to(pkg).as_posix() for p in jit.kernel_sources(pkg)]
    assert sources == ["consts.py", "helpers.py", "more.py", "sub/k_kernels.py"]  # not unrelated
    _cache(caches)
    assert jit.drop_stale_caches(pkg) == 3  # caches of unknown sources (no stamp yet)
    assert (pkg / jit.STAMP).read_text().strip() == jit.sources_digest(pkg)
    _cache(caches)
    assert jit.drop_stale_caches(pkg) == 0 and all(c.exists() for c in caches)  # up to date
    (pkg / "unrelated.py").write_text("def f():\n    return 2\n")
    assert jit.drop_stale_caches(pkg) == 0  # no compiled code depends on it
    for edited in ("helpers.py", "consts.py", "more.py"):  # a callee, constants: all stale
        path = pkg / edited
        path.write_text(path.read_text().replace("1", "2").replace("3", "4"))
        assert jit.drop_stale_caches(pkg) == 3 and not any(c.exists() for c in caches)
        _cache(caches)
