"""A CommonRoad scenario file as it is: its lanelet map and its recorded vehicles, one of them
the ego (drawn from the seed), the others replayed around it. Give your own file as
``--file``; by default one of the shipped NGSIM scenes.

    python examples/05_commonroad_file.py [--file scene.xml] [--quick]
"""

import argparse
from importlib import resources

import gymnasium as gym

import gridsim  # noqa: F401  (registers GridSim-v0)

SHIPPED = resources.files("gridsim") / "data" / "ngsim" / "commonroad-xml" / "USA_US101-3_3_T-1.xml"

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--file", default=str(SHIPPED), help="a CommonRoad .xml file")
ap.add_argument("--quick", action="store_true", help="a short drive (for CI)")
args = ap.parse_args()

env = gym.make("GridSim-v0", scenario=args.file)
obs, info = env.reset(seed=0)
track = env.unwrapped.world.ego_track
print(f"{args.file}: the ego replays the human of track {track.track_id} "
      f"({track.duration:.1f} s recorded)")  # fmt: skip
for _ in range(20 if args.quick else 10_000):
    obs, fitness, terminated, truncated, info = env.step(info["reference_setpoints"])
    if terminated or truncated:
        break
print(f"followed the human for {info['time']:.1f} s; last step's l1 {fitness[0]:.3f} m^2")
