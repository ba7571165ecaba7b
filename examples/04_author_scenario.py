"""Author a scenario: start from a built-in one with ``extends:``, change what you need,
validate it, and drive it.

    python examples/04_author_scenario.py [--quick]
"""

import argparse
import tempfile
from pathlib import Path

import gymnasium as gym

import gridsim  # noqa: F401  (registers GridSim-v0)
from gridsim.scenario import load_scenario

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--quick", action="store_true", help="a short drive (for CI)")
args = ap.parse_args()

text = """\
extends: inner_city        # everything of the built-in inner-city scenario...
name: busy_city
traffic:
  participants: 35         # ...but more traffic
simulation:
  duration: 30.0
"""
with tempfile.TemporaryDirectory() as folder:
    path = Path(folder) / "busy_city.yaml"
    path.write_text(text)
    scenario = load_scenario(path)  # validates; an error names the file, key and range
    cfg = scenario.config
    speeds = f"{cfg.traffic.v_min}-{cfg.traffic.v_max} m/s"
    print(f"{cfg.name}: {cfg.traffic.participants} participants at {speeds}, "
          f"{cfg.simulation.duration:g} s")  # fmt: skip
    env = gym.make("GridSim-v0", scenario=str(path))
    obs, info = env.reset(seed=3)
    for _ in range(20 if args.quick else 300):
        obs, fitness, terminated, truncated, info = env.step(info["reference_setpoints"])
        if terminated or truncated:
            break
    print(
        f"drove {info['time']:.1f} s; collision: {info['collision']}, off road: {info['off_road']}"
    )
