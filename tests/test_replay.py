"""Recorded episodes as the human drove them: an ego track that waits is not "reached" at
once, but runs for its recorded duration."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.envs.reference import reference_from_track
from gridsim.traffic.library import REQUIRED_COLUMNS, Track

MAP = Path(__file__).parent / "data" / "commonroad" / "straight_2018b.xml"


def track(tid: str, x, y, heading: float = 0.0, dt: float = 0.1) -> Track:
    """A track of a car at positions ``x``, ``y`` (speeds from the positions)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    t = dt * np.arange(len(x))
    v = np.append(np.hypot(np.diff(x), np.diff(y)) / dt, 0.0)
    return Track("crafted", tid, t, x, y, np.full(len(t), heading), v, 4.5, 1.8)


def waiting(n: int = 41, moving_after: int | None = None, x0: float = 60.0) -> Track:
    """A car on the straight map's left lane that stands (sub-centimetre position noise) and,
    from sample ``moving_after``, pulls away at 2 m/s^2."""
    t = 0.1 * np.arange(n)
    along = np.zeros(n) if moving_after is None else np.maximum(t - 0.1 * moving_after, 0) ** 2
    noise = np.random.default_rng(3).uniform(-0.004, 0.004, (2, n))
    return track("ego", x0 + along + noise[0], 1.75 + noise[1])


def write_scene(tmp_path, tracks: list[Track], **keys) -> Path:
    """A recorded scenario on the straight crafted map replaying ``tracks`` (CSV)."""
    rows = [",".join(REQUIRED_COLUMNS)]
    for tr in tracks:
        for k in range(len(tr.t)):
            values = (tr.t[k], tr.x[k], tr.y[k], tr.heading[k], tr.speed[k], tr.length, tr.width)
            rows.append(",".join([tr.scenario_id, tr.track_id, *(repr(float(v)) for v in values)]))
    (tmp_path / "tracks.csv").write_text("\n".join(rows) + "\n")
    doc = {
        "name": "crafted",
        "simulation": {"duration": 30.0},
        "road": {"type": "recorded", "map": str(MAP), "scene": "crafted"},
        "traffic": {"library": ["tracks.csv"]},
        "ego": {"track": "ego"},
        **keys,
    }
    path = tmp_path / "crafted.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def drive_reference(path: Path) -> tuple[GridSimEnv, dict, bool]:
    env = GridSimEnv(str(path))
    _, info = env.reset(seed=0)
    while True:
        _, _, terminated, truncated, info = env.step(info["reference_setpoints"])
        if terminated or truncated:
            return env, info, truncated


def test_a_reference_that_never_moves_is_never_reached():
    ref = reference_from_track(waiting(), 1.35)
    assert ref.length > 0.1  # the noise adds up along the path...
    assert ref.reach < 0.02  # ...but not away from the start
    assert not ref.reached(ref.xy[0], 0.0, 2.0)
    assert not ref.reached(ref.destination, 50.0, 2.0)
    moving = reference_from_track(track("m", np.linspace(0.0, 30.0, 31), np.zeros(31)), 1.35)
    assert moving.reached(moving.destination, 30.0, 2.0)
    assert not moving.reached(moving.destination, 10.0, 2.0)  # not without driving its length


def test_an_ego_that_waits_the_whole_time_runs_for_the_recorded_duration(tmp_path):
    env, info, truncated = drive_reference(write_scene(tmp_path, [waiting()]))
    assert truncated and not info["destination_reached"]
    assert env.world.time == pytest.approx(4.0)


def test_an_ego_that_waits_then_drives_off_is_reached_only_at_the_end(tmp_path):
    env, info, _ = drive_reference(write_scene(tmp_path, [waiting(61, moving_after=30)]))
    assert not info["collision"] and not info["off_road"]
    assert env.world.time >= 6.0 - 0.5  # within the tolerance of the end, not at the start
