"""Compiled kernels: numba's ``njit``, compiled on first call and cached on disk.

numba is imported only by the modules that define kernels (not by ``import gridsim``). The
compiled code is cached next to the source (or in numba's user-wide cache directory when the
package directory is read-only), so that later processes load it instead of compiling; when
no cache location is writable at all, kernels are compiled once per process. ``fastmath`` is
never used: kernels must give the same bits as the NumPy code they replace. Nor is Intel's
SVML (numba would vectorise ``math`` calls with it when ``intel-cmplr-lib-rt`` is installed,
with other results than libm's): ``NUMBA_DISABLE_INTEL_SVML`` is set unless the user set it.

numba checks a cached kernel against its own source file only, not against the kernels
and constants it uses from other modules (e.g. ``polyline_kernels.project``, called by
``scripted_driver_kernels.route_leader``). So this module keeps a digest of every source
compiled code can depend on (:func:`kernel_sources`) beside the caches, and when the digest
changes (an edited kernel, another version installed over the package) deletes every cached
kernel of the package before any is loaded (:func:`drop_stale_caches`), so that the caches
beside the package never serve a stale kernel (numba's user-wide cache, used where the
package cannot be written, and ``NUMBA_CACHE_DIR`` are not watched: installed sources do not
change).

Compiling all kernels takes about 30 s; ``pip install .`` does it while it builds the package
(``gridsim compile``), so that a user's first environment starts at once. When a kernel is
compiled at run time all the same (an editable install, another CPU, another numba), one
line on stderr says so, once per process and the processes it starts (:data:`NOTICE`).
"""

from __future__ import annotations

import hashlib
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path

os.environ.setdefault("NUMBA_DISABLE_INTEL_SVML", "1")  # read when numba is first imported

import numba  # noqa: E402
from numba.core import event, types  # noqa: E402
from numba.extending import intrinsic, register_jitable  # noqa: E402

#: What a process prints (stderr) when it first compiles one of GridSim's kernels.
NOTICE = ("gridsim: compiling the simulator's kernels for this machine, once (up to "
          "about 30 s; later runs load them from the cache; `gridsim compile` does it "
          "ahead)")  # fmt: skip
#: Set in the environment once a process has printed :data:`NOTICE`: the worker processes it
#: starts then do not print it again (a trainer printed it three times).
NOTICED_VARIABLE = "GRIDSIM_COMPILE_NOTICED"

_KERNELS: list = []  # every kernel defined so far
#: Kernels compiled (not loaded from the cache) in this process, and whether the notice
#: was printed (a test session sets it, so that no test's stderr depends on the order).
_COMPILED = {"count": 0, "noticed": os.environ.get(NOTICED_VARIABLE) == "1"}


class _CompileNotice(event.Listener):
    """Counts the compilations of GridSim's kernels; prints :data:`NOTICE` at the first."""

    def on_start(self, e) -> None:
        fn = getattr(e.data.get("dispatcher"), "py_func", None)
        if fn is None or not fn.__module__.startswith("gridsim."):
            return
        if not _COMPILED["noticed"]:
            print(NOTICE, file=sys.stderr, flush=True)
            _COMPILED["noticed"] = True
            os.environ[NOTICED_VARIABLE] = "1"  # (for the processes this one starts)
        _COMPILED["count"] += 1

    def on_end(self, e) -> None:
        pass


event.register("numba:compile", _CompileNotice())

#: Where the digest of the kernel sources is kept, in the package's ``__pycache__``.
STAMP = Path("__pycache__") / "kernel_sources.sha256"
_COMPILED_CODE = re.compile(r"^@(kernel|jitable)\b|register_jitable\(|= jitable\(", re.M)
_GRIDSIM_IMPORT = re.compile(r"^from (gridsim(?:\.\w+)*) import (\([^)]*\)|[^\n]*)", re.M)


def kernel_sources(package: Path) -> list[Path]:
    """The sources compiled code of ``package`` (the ``gridsim`` folder) can depend on: every
    module that defines kernels or jitable functions, and the package's modules they import
    names from (constants are frozen into the compiled code)."""
    texts = {f: f.read_text() for f in sorted(package.rglob("*.py"))}
    compiled = [f for f, text in texts.items() if _COMPILED_CODE.search(text)]
    used = set(compiled)
    for f in compiled:
        for module, names in _GRIDSIM_IMPORT.findall(texts[f]):
            parts = module.split(".")[1:]
            used.add(_module_file(package, parts))
            for name in re.findall(r"\w+", names):  # ``from gridsim.x import y``: y a module?
                used.add(_module_file(package, [*parts, name]))
    return sorted(p for p in used if p.is_file())


def _module_file(package: Path, parts: list[str]) -> Path:
    """The file of module ``gridsim.<parts>`` (a module or a package's ``__init__.py``)."""
    module = package.joinpath(*parts).with_suffix(".py") if parts else package / "__init__.py"
    return module if module.is_file() else package.joinpath(*parts, "__init__.py")


def sources_digest(package: Path) -> str:
    """SHA-256 of :func:`kernel_sources` (their paths in the package and their bytes)."""
    h = hashlib.sha256()
    for f in kernel_sources(package):
        h.update(f.relative_to(package).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def drop_stale_caches(package: Path) -> int:
    """Delete the cached kernels (``*.nbi``, ``*.nbc``) under ``package`` unless its
    :data:`STAMP` holds the digest of today's sources, then write the stamp; how many files
    were deleted. Does nothing where the package cannot be written (numba then caches in its
    user-wide folder, keyed by the installed sources, which do not change)."""
    stamp = package / STAMP
    digest = sources_digest(package)
    try:
        if stamp.read_text().strip() == digest:
            return 0
    except OSError:
        pass  # no stamp yet: the caches, if any, are of unknown sources
    if not os.access(package, os.W_OK):
        return 0
    dropped = 0
    for cache in [*package.rglob("__pycache__/*.nbi"), *package.rglob("__pycache__/*.nbc")]:
        try:
            cache.unlink()
            dropped += 1
        except OSError:
            pass
    try:  # atomically: a process starting beside this one reads the old stamp or the new
        stamp.parent.mkdir(exist_ok=True)
        part = stamp.with_name(f"{stamp.name}.{os.getpid()}")
        part.write_text(digest + "\n")
        os.replace(part, stamp)
    except OSError:
        pass
    return dropped


drop_stale_caches(Path(__file__).parent)


def compiled_kernels() -> dict:
    """``{"kernels": defined so far, "compiled": compilations in this process}`` (cache
    loads are not compilations)."""
    return {"kernels": len(_KERNELS), "compiled": _COMPILED["count"]}


def kernel(fn: Callable) -> Callable:
    """``fn`` as a lazily compiled, disk-cached numba function (``nopython``, no fastmath)."""
    try:
        compiled = numba.njit(cache=True, nogil=True)(fn)
    except RuntimeError:  # no writable cache location
        compiled = numba.njit(nogil=True)(fn)
    _KERNELS.append(compiled)
    return compiled


def jitable(fn: Callable) -> Callable:
    """``fn`` unchanged for Python callers, compiled inline when a kernel calls it."""
    return register_jitable(fn)


@intrinsic
def fma32(typingctx, a, b, c):
    """``a * b + c`` of three float32, rounded once (a fused multiply-add: the CPU's
    instruction, or the C library's ``fmaf`` where there is none; the same bits everywhere),
    for kernels that must give the sums of BLAS and oneDNN, which fuse them."""
    f32 = types.float32
    if not (a == f32 and b == f32 and c == f32):
        return None
    return f32(f32, f32, f32), lambda context, builder, signature, args: builder.fma(*args)


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
