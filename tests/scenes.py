"""Crafted recorded scenes for tests: tracks on the straight two-lane map of
``tests/data/commonroad/straight_2018b.xml`` (lanes y in [-3.5, 0] and [0, 3.5], x in
[0, 200] m), written as a trajectory CSV and a scenario YAML."""

from pathlib import Path

import numpy as np
import yaml
from paths import COMMONROAD

from gridsim.traffic.library import REQUIRED_COLUMNS
from gridsim.traffic.track import Track

MAP = COMMONROAD / "straight_2018b.xml"


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
