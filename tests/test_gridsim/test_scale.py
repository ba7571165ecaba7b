"""Large recorded scenes: the linear-time checks of a scene's tracks equal the pairwise and
per-sample checks they replace (benchmarks/bench_scale.py measures the time)."""

import cv2
import numpy as np
import pymunk
import pytest
from scenes import MAP

from gridsim.scenario import load_scenario
from gridsim.scenario.families.recorded import (
    EXPERT_EDGE_MARGIN,
    recorded_scene,
    scene_of,
    unfit_experts,
)
from gridsim.traffic.track import Track
from gridsim.world import collision_kernels
from gridsim.world.collision import EDGE_TOLERANCE, CollisionChecker
from gridsim.world.overlaps import overlapping_tracks


def pairwise_overlaps(tracks) -> set[int]:
    """The reference: every pair of tracks, at every common time stamp, OpenCV's test."""
    bad = set()
    for i, a in enumerate(tracks):
        ta = np.round(a.t, 3)
        for j in range(i + 1, len(tracks)):
            b = tracks[j]
            tb = np.round(b.t, 3)
            for t in np.intersect1d(ta, tb):
                ka, kb = np.searchsorted(ta, t), np.searchsorted(tb, t)
                ra = ((a.x[ka], a.y[ka]), (a.length, a.width), np.rad2deg(a.heading[ka]))
                rb = ((b.x[kb], b.y[kb]), (b.length, b.width), np.rad2deg(b.heading[kb]))
                if cv2.rotatedRectangleIntersection(ra, rb)[0] != cv2.INTERSECT_NONE:
                    bad |= {i, j}
                    break
    return bad


def per_sample_edges(tracks, road) -> set[str]:
    """The reference: the world's edge test at every sample of every track."""
    bad = set()
    for a in tracks:
        checker = CollisionChecker(a.length, a.width, EDGE_TOLERANCE - EXPERT_EDGE_MARGIN)
        for k in range(len(a.t)):
            centre = np.array([a.x[k], a.y[k]])
            checker.set_boundaries(road.boundary_segments(), road.version, centre)
            none = (np.zeros(0),) * 5
            if checker.check(centre, float(a.heading[k]), none, np.zeros(0, int)).boundaries:
                bad.add(a.track_id)
                break
    return bad


def random_tracks(n: int, seed: int) -> list[Track]:
    """``n`` short tracks crowded on the straight crafted map (x in [0, 200], y in
    [-3.5, 3.5] m): some overlap each other, some reach over the road edge; time stamps
    on a 0.1 s grid with random starts, some on a shifted grid."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        m = int(rng.integers(3, 30))
        t0 = 0.1 * int(rng.integers(0, 40)) + (0.05 if rng.random() < 0.2 else 0.0)
        t = t0 + 0.1 * np.arange(m)
        x = rng.uniform(10, 190) + rng.uniform(0, 15) * 0.1 * np.arange(m)
        y = np.full(m, rng.uniform(-3.2, 3.2)) + rng.normal(0, 0.1, m)
        heading = np.full(m, rng.normal(0, 0.2))
        out.append(Track("crafted", str(i), t, x, y, heading, np.full(m, 10.0),
                         float(rng.uniform(3.5, 12.0)), float(rng.uniform(1.6, 2.6))))  # fmt: skip
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sweep_finds_the_same_overlaps_as_every_pair(seed):
    tracks = random_tracks(120, seed)
    expected = pairwise_overlaps(tracks)
    assert 5 < len(expected) < len(tracks)  # the crowd has both kinds
    assert overlapping_tracks(tracks) == expected


def test_overlaps_of_no_or_one_track():
    assert overlapping_tracks([]) == set()
    assert overlapping_tracks(random_tracks(1, 0)) == set()


def test_edge_prefilter_never_misses_a_contact():
    """Boxes the kernel calls clear of every edge are clear for pymunk too (the kernel's
    distances are exact, so it also clears most boxes that are not touching)."""
    rng = np.random.default_rng(5)
    segments = np.array([[0.0, 0.0, 30.0, 0.0], [30.0, 0.0, 40.0, 8.0], [5.0, 6.0, 5.0, 6.0]])
    n = 4000
    x, y = rng.uniform(-3, 43, n), rng.uniform(-4, 10, n)
    psi = rng.uniform(-np.pi, np.pi, n)
    length, width = rng.uniform(2, 10, n), rng.uniform(1, 3, n)
    reach = 0.5 * np.hypot(length, width) + 1.0
    near = collision_kernels.edges_near_boxes(x, y, psi, 0.5 * length, 0.5 * width, reach,
                                              segments, collision_kernels.APART)  # fmt: skip
    space = pymunk.Space()
    for x0, y0, x1, y1 in segments:
        space.add(pymunk.Segment(space.static_body, (x0, y0), (x1, y1), 0.0))
    touching = np.zeros(n, bool)
    for i in range(n):
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        hl, hw = 0.5 * length[i], 0.5 * width[i]
        box = pymunk.Poly(body, [(-hl, -hw), (hl, -hw), (hl, hw), (-hl, hw)])
        body.position, body.angle = (x[i], y[i]), psi[i]
        space.add(body, box)
        space.reindex_shapes_for_body(body)
        touching[i] = bool(space.shape_query(box))
        space.remove(body, box)
    assert touching.sum() > 200 and (~near).sum() > 200
    assert not np.any(touching & ~near)
    assert np.mean(near & ~touching) < 0.01  # a millimetre's margin flags few others


def test_unfit_experts_equal_the_per_sample_and_pairwise_checks():
    sc = load_scenario(str(MAP))
    road, _ = recorded_scene(sc)
    tracks = tuple(random_tracks(80, 7))
    unfit = unfit_experts("crafted", tracks, road)
    expected = per_sample_edges(tracks, road) | {
        tracks[i].track_id for i in pairwise_overlaps(tracks)
    }
    assert len(per_sample_edges(tracks, road)) > 3
    assert unfit == expected


@pytest.mark.parametrize("name", ["us101_4_1", "lankershim_1_1", "us101_3_3", "peachtree_4_8"])
def test_unfit_experts_of_the_shipped_scenes(name):
    sc = load_scenario(name)
    road, tracks = recorded_scene(sc)
    expected = per_sample_edges(tracks, road) | {
        tracks[i].track_id for i in pairwise_overlaps(tracks)
    }
    assert unfit_experts(scene_of(sc), tuple(tracks), road) == expected
