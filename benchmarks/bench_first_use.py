"""First use after a fresh install: ``pip install .`` of this checkout into a new virtual
environment, then, each in a new process from an empty folder, the time from ``import
gymnasium, gridsim`` through ``gym.make("GridSim-v0")``, ``reset`` and 10 steps:

- ``first``: the very first run after the install (the kernels compiled while the package
  was built, ``setup.py``);
- ``second``: the run after it;
- ``cold``: with an empty ``NUMBA_CACHE_DIR``, i.e. what the first run costs when nothing was
  compiled ahead (an editable install, another CPU).

    python benchmarks/bench_first_use.py [--keep VENV]

Target: ``first`` <= 3 s. Prints JSON lines with ``/proc/loadavg`` beside the figures; the
install itself is timed too (it includes the compilation).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

FIRST_USE = """
import time
t0 = time.perf_counter()
import gymnasium as gym
import gridsim
env = gym.make("GridSim-v0")
env.reset(seed=0)
for _ in range(10):
    env.step(env.action_space.sample())
print(time.perf_counter() - t0)
"""


def _load() -> str:
    """The 1, 5 and 15 minute load averages."""
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def _first_use(python: Path, cwd: Path, env: dict | None = None) -> float:
    out = subprocess.run([str(python), "-c", FIRST_USE], cwd=cwd, check=True, text=True,
                         capture_output=True, env={**os.environ, **(env or {})})  # fmt: skip
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", default=None, help="make the virtual environment here and keep it")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="gridsim-first-use-") as tmp:
        venv = Path(args.keep) if args.keep else Path(tmp) / "venv"
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        python = venv / "bin" / "python"
        t0 = time.perf_counter()
        subprocess.run([str(python), "-m", "pip", "install", "-q", str(ROOT)], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
        install = time.perf_counter() - t0
        print(json.dumps({"bench": "install", "seconds": round(install, 1), "load": _load()}))
        empty = Path(tmp) / "cwd"
        empty.mkdir()
        rows = {"first": _first_use(python, empty), "second": _first_use(python, empty)}
        rows["cold"] = _first_use(python, empty, {"NUMBA_CACHE_DIR": str(Path(tmp) / "nocache")})
        for name, seconds in rows.items():
            print(json.dumps({"bench": "first_use", "run": name, "seconds": round(seconds, 2),
                              "target_s": 3.0, "load": _load()}))  # fmt: skip
        print(json.dumps({"bench": "summary", "first_s": round(rows["first"], 2),
                          "cold_over_first": round(rows["cold"] / rows["first"], 1),
                          "meets_target": rows["first"] <= 3.0}))  # fmt: skip


if __name__ == "__main__":
    main()
