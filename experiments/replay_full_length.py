"""How many tracks of recorded scenes give full-length episodes when the ego follows its own
recorded future (the reference), as ``neurotrajectory record`` drives them.

    python experiments/replay_full_length.py [SCENARIO ...]

Every track of each scene is the ego once, for its recorded duration. An episode is
full-length if it lasts the track's duration (to within :data:`NEAR_END`), ending by the
time limit or by reaching the destination at the end; otherwise it ended early by a
collision, by leaving the road, or by "destination reached" sooner (a human who stopped
short of the end of the recording is within the destination tolerance from then on).
Prints one JSON line per scene and a total.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.scenario.families.recorded import scene_of
from gridsim.scenario.loader import load_scenario
from gridsim.scenario.parts import library_for

RECORDED = ("us101_3_3", "us101_4_1", "lankershim_1_1", "peachtree_4_8")
NEAR_END = 0.5  # [s]


def outcome(scenario: str, track) -> str:
    """``full``, ``collision``, ``off_road`` or ``reached_early`` for ``track`` as the ego."""
    overrides = {"ego": {"track": track.track_id},
                 "simulation": {"duration": max(float(track.duration), 0.1)}}  # fmt: skip
    env = GridSimEnv(scenario, **overrides)
    _, info = env.reset(seed=0)
    while True:
        _, _, terminated, truncated, info = env.step(info["reference_setpoints"])
        if terminated or truncated:
            break
    if info["collision"]:
        return "collision"
    if info["off_road"]:
        return "off_road"
    if env.world.time < env.time_limit - NEAR_END - 1e-9:
        return "reached_early"
    return "full"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", default=list(RECORDED))
    args = ap.parse_args()
    total: Counter = Counter()
    for name in args.scenarios:
        sc = load_scenario(name)
        tracks = library_for(sc).scene(scene_of(sc))
        counts = Counter(outcome(name, t) for t in tracks)
        total += counts
        print(json.dumps({"scenario": name, "tracks": len(tracks), **dict(sorted(counts.items()))}))
    summary = {"scenario": "total", "tracks": sum(total.values()), **dict(sorted(total.items()))}
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
