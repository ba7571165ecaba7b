"""Roads: polylines, the seamless generator, the city network and CommonRoad lanelet maps."""

from importlib import resources

import numpy as np
import pytest

from gridsim import libm
from gridsim.errors import DataError
from gridsim.road.city import CityParams, CityRoad, route_statistics
from gridsim.road.lanelet import load_lanelet_road
from gridsim.road.polyline import Polyline
from gridsim.road.seamless import SeamlessParams, SeamlessRoad
from gridsim.traffic.library import TrajectoryLibrary

XML = resources.files("gridsim") / "data" / "ngsim" / "commonroad-xml"
SCENES = ["USA_Lanker-1_1_T-1", "USA_Peach-4_8_T-1", "USA_US101-3_3_T-1", "USA_US101-4_1_T-1"]


def test_polyline_frenet_round_trip():
    t = np.linspace(0, np.pi, 200)
    line = Polyline(np.stack([50 * np.cos(t), 50 * np.sin(t)], axis=1))
    rng = np.random.default_rng(0)
    s = rng.uniform(1, line.length - 1, 100)
    d = rng.uniform(-3, 3, 100)
    xy, _ = line.frenet_to_world(s, d)
    s2, d2, _ = line.project(xy)
    np.testing.assert_allclose(s2, s, atol=0.05)
    np.testing.assert_allclose(d2, d, atol=0.01)
    assert line.length == pytest.approx(np.pi * 50, rel=1e-3)


def test_polyline_rejects_bad_points():
    with pytest.raises(ValueError, match="at least 2"):
        Polyline(np.zeros((1, 2)))
    with pytest.raises(ValueError, match="finite"):
        Polyline(np.array([[0, 0], [np.nan, 1]]))


def drive_along(road: SeamlessRoad, distance: float, step: float = 5.0):
    s = 0.0
    while s < distance:
        s += step
        p, _ = road.reference_line.point_at(s)
        road.update(p)


def test_seamless_is_deterministic_and_seed_dependent():
    a, b, c = (SeamlessRoad(SeamlessParams(), seed) for seed in (7, 7, 8))
    for r in (a, b, c):
        drive_along(r, 600)
    np.testing.assert_array_equal(a.lanes[0].centre.points, b.lanes[0].centre.points)
    assert not np.array_equal(a.lanes[0].centre.points[:100], c.lanes[0].centre.points[:100])


def test_seamless_memory_is_bounded():
    road = SeamlessRoad(SeamlessParams(), seed=3)
    sizes = []
    for _ in range(10):
        drive_along_from = road._ego_s
        s = drive_along_from
        while s < drive_along_from + 2000:
            s += 5.0
            road.update(road.reference_line.point_at(s)[0])
        sizes.append(road.memory_points)
    assert max(sizes) < 1000  # 20 km driven, never more than ~keep_behind + keep_ahead + slack
    assert road._ego_s > 19_000


def test_seamless_geometry_statistics_match_parameters():
    p = SeamlessParams()
    road = SeamlessRoad(p, seed=11)
    gen = road._gen
    pieces = [gen.next_piece() for _ in range(400)]
    lengths, angles = [], []
    for pts, hs in pieces:
        if len(pts) == 0:
            continue
        turn = abs(hs[-1] - hs[0])
        lengths.append((turn < 1e-9, len(pts) * p.sample_spacing))
        if turn > 1e-9:
            angles.append(np.rad2deg(turn))
    total = sum(n for _, n in lengths)
    straight = sum(n for is_straight, n in lengths if is_straight)
    assert straight / total == pytest.approx(0.6, abs=0.05)
    assert np.mean(angles) == pytest.approx(55, abs=5)


def test_seamless_lanes_are_parallel_and_on_the_road():
    p = SeamlessParams(lanes=3, lane_width=3.5)
    road = SeamlessRoad(p, seed=5)
    drive_along(road, 800)
    left = road.lanes[2].centre
    s, d, _ = left.project(road.lanes[0].centre.points[::10])
    np.testing.assert_allclose(np.abs(d), 7.0, atol=0.05)
    assert np.all(road.is_drivable(road.lanes[0].centre.points))
    normal_off = road.lanes[1].centre.points[::10] + np.array([0.0, 30.0])
    assert not np.any(
        road.is_drivable(normal_off[np.abs(road.reference_line.project(normal_off)[1]) > 6])
    )


def test_seamless_rejects_tight_curves():
    with pytest.raises(ValueError, match="curve_radius"):
        SeamlessRoad(SeamlessParams(lanes=4, lane_width=3.5, curve_radius=(7.0, 20.0)))


def test_city_routes_match_table_one_and_stay_on_road():
    road = CityRoad(CityParams(), seed=0)
    rng = np.random.default_rng(0)
    routes = [road.random_route(rng, 2000) for _ in range(15)]
    stats = np.array([route_statistics(r) for r in routes])
    straight, curve = stats.mean(axis=0)
    assert straight == pytest.approx(0.45, abs=0.05)
    assert curve == pytest.approx(81, abs=5)
    for r in routes:
        assert r.length >= 2000
        assert np.all(road.is_drivable(r.points))


def test_city_has_boundaries_around_blocks():
    road = CityRoad(CityParams(blocks_x=2, blocks_y=2, jitter=0.0), seed=0)
    # Block centres are not drivable; street midpoints are.
    assert not road.is_drivable(np.array([[22.5, 22.5]]))[0]
    assert road.is_drivable(np.array([[22.5, 0.0]]))[0]
    seg = road.boundary_segments()
    assert seg.shape[1] == 4 and len(seg) >= 4 * 4  # at least the four block outlines


@pytest.mark.parametrize("scene", SCENES)
def test_lanelet_maps_cover_the_recorded_trajectories(scene):
    road = load_lanelet_road(XML / f"{scene}.xml")
    tracks = TrajectoryLibrary.builtin().scene(scene)
    xy = np.concatenate([np.stack([t.x, t.y], axis=1) for t in tracks])
    assert road.is_drivable(xy).all()
    assert len(road.lanes) > 5
    assert len(road.boundary_segments()) > 10


def test_lanelet_errors_name_the_file(tmp_path):
    with pytest.raises(DataError, match="not found"):
        load_lanelet_road(tmp_path / "missing.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text("<commonRoad><lanelet id='1'><leftBound></leftBound></lanelet><lanelet")
    with pytest.raises(DataError, match="bad.xml: (not well-formed|lanelet 1)"):  # streamed
        load_lanelet_road(bad)
    bad.write_text("<commonRoad><lanelet id='1'")
    with pytest.raises(DataError, match="bad.xml: not well-formed"):
        load_lanelet_road(bad)
    bad.write_text(
        "<commonRoad><lanelet id='4'><leftBound><point><x>0</x><y>a</y></point>"
        "</leftBound><rightBound/></lanelet></commonRoad>"
    )
    with pytest.raises(DataError, match="lanelet 4"):
        load_lanelet_road(bad)
    bad.write_text("<commonRoad></commonRoad>")
    with pytest.raises(DataError, match="no <lanelet>"):
        load_lanelet_road(bad)


def test_tracking_projection_equals_full_projection():
    t = np.linspace(0, np.pi, 200)
    line = Polyline(np.stack([50 * np.cos(t), 50 * np.sin(t)], axis=1))
    rng = np.random.default_rng(0)
    hint = 0
    for s in np.linspace(1, line.length - 1, 2000):
        p, _ = line.frenet_to_world(np.array([s]), np.array([rng.uniform(-3, 3)]))
        got = line.track(p[0, 0], p[0, 1], hint)
        s_ref, d_ref, _ = line.project(p)
        assert got[0] == pytest.approx(s_ref[0], abs=1e-9)
        assert got[1] == pytest.approx(d_ref[0], abs=1e-9)
        hint = got[2]


@pytest.mark.parametrize(
    "x, message",
    [
        ("1e308", r"lanelet 1 leftBound: coordinate 1e\+308 m is beyond \+-1e\+07 m"),
        ("1e6", r"far.xml: the road spans 1e\+06 m x .* more than 1e\+08"),
    ],
)
def test_far_away_map_coordinates_are_refused(tmp_path, x, message):
    def bound(name, y):
        pts = "".join(f"<point><x>{px}</x><y>{y}</y></point>" for px in ("0", "10", x))
        return f"<{name}>{pts}</{name}>"

    path = tmp_path / "far.xml"
    path.write_text(f"<commonRoad><lanelet id='1'>{bound('leftBound', 3.5)}"
                    f"{bound('rightBound', 0)}</lanelet></commonRoad>")  # fmt: skip
    with pytest.raises(DataError, match=message):
        load_lanelet_road(path)


# -- the compiled polyline queries against the NumPy code they replaced -------------------------
def _numpy_project(line: Polyline, xy, lo, hi):
    a, seg = line.points[lo:hi], np.diff(line.points, axis=0)[lo:hi]
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    rel = xy[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("nmk,mk->nm", rel, seg) / seg_len**2, 0.0, 1.0)
    dist2 = np.sum((xy[:, None, :] - (a[None] + t[..., None] * seg[None])) ** 2, axis=-1)
    j = np.argmin(dist2, axis=1)
    rows = np.arange(len(xy))
    gi = j + lo
    s = line.s[gi] + t[rows, j] * seg_len[j]
    cross = seg[j, 0] * rel[rows, j, 1] - seg[j, 1] * rel[rows, j, 0]
    return s, np.sign(cross) * np.sqrt(dist2[rows, j]), gi


def _numpy_frenet(line: Polyline, s, d):
    seg = np.diff(line.points, axis=0)
    i = np.clip(np.searchsorted(line.s, s, side="right") - 1, 0, len(seg) - 1)
    h = libm.arctan2(seg[i, 1], seg[i, 0])
    p = line.points[i] + ((s - line.s[i]) / np.hypot(*seg[i].T))[..., None] * seg[i]
    return p + d[..., None] * np.stack([-np.sin(h), np.cos(h)], axis=-1), h


def _numpy_arrays(points, s_start):
    pts = np.asarray(points, dtype=np.float64)
    seg = np.diff(pts, axis=0)
    keep = np.concatenate([[True], np.hypot(seg[:, 0], seg[:, 1]) > 1e-9])
    pts = pts[keep]
    seg = np.diff(pts, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    s = s_start + np.concatenate([[0.0], np.cumsum(seg_len)])
    return pts, seg, seg_len, libm.arctan2(seg[:, 1], seg[:, 0]), s


def _numpy_track(line: Polyline, x, y, hint):
    """The Python walk that ``Polyline.track`` compiled (its scalar ``** 2`` is libm's pow)."""
    pts, seg, seg_len, _, s = _numpy_arrays(line.points, line.s[0])
    n = len(seg)

    def foot(i):
        return float(
            ((x - pts[i, 0]) * seg[i, 0] + (y - pts[i, 1]) * seg[i, 1]) / (seg_len[i] ** 2)
        )

    i, step = min(max(int(hint), 0), n - 1), 0
    while True:
        t = foot(i)
        if t > 1.0 and i < n - 1 and step >= 0:
            i, step = i + 1, 1
        elif t < 0.0 and i > 0 and step <= 0:
            i, step = i - 1, -1
        else:
            break
    best = None
    for j in (i - 1, i, i + 1):
        if 0 <= j < n:
            t = min(max(foot(j), 0.0), 1.0)
            (ax, ay), (sx, sy) = pts[j], seg[j]
            dist = float(np.hypot(x - ax - t * sx, y - ay - t * sy))
            if best is None or dist < best[0]:
                best = (dist, j, t, float(sx * (y - ay) - sy * (x - ax)))
    dist, j, t, cross = best
    return float(s[j] + t * seg_len[j]), float(np.copysign(dist, cross)), j


def test_compiled_polyline_construction_and_walk_are_bit_identical_to_numpy():
    rng = np.random.default_rng(3)
    for _ in range(30):
        m = int(rng.integers(2, 200))
        raw = np.cumsum(rng.normal(size=(m, 2)) * rng.uniform(0.1, 40), axis=0)
        raw[rng.integers(1, m, size=m // 5)] = raw[0]  # some repeated points
        if len(np.unique(raw, axis=0)) < 2:
            continue
        start = float(rng.uniform(-50, 50))
        line = Polyline(raw, start)
        want = _numpy_arrays(raw, start)
        got = (line.points, line._seg, line._seg_len, line._heading, line.s)
        for g, w in zip(got, want, strict=True):
            assert np.array_equal(g, w)
        for _ in range(100):
            k = int(rng.integers(0, len(line.points)))
            x, y = line.points[k] + rng.normal(size=2) * 3
            hint = int(rng.integers(0, len(line.points) - 1))
            assert line.track(x, y, hint) == _numpy_track(line, float(x), float(y), hint)


def test_projection_hints_out_of_range_are_clamped_and_bad_input_refused():
    line = Polyline(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))
    for hint in (10, 500_000, -7):
        s, d, seg = line.project(np.array([[0.5, 0.2]]), hint=hint, window=4)
        assert (s[0], d[0], seg[0]) == (0.5, 0.2, 0)
    with pytest.raises(ValueError, match="window must be >= 1 segment, got 0"):
        line.project(np.array([[0.5, 0.2]]), hint=0, window=0)
    with pytest.raises(ValueError, match=r"shape \(N, 2\), got \(1, 3\)"):
        line.project(np.zeros((1, 3)))


def test_compiled_polyline_queries_are_bit_identical_to_numpy():
    rng = np.random.default_rng(7)
    for _ in range(20):
        m = int(rng.integers(2, 300))
        line = Polyline(np.cumsum(rng.normal(size=(m, 2)) * rng.uniform(0.1, 20), axis=0))
        xy = line.points[rng.integers(0, m, 50)] + rng.normal(size=(50, 2)) * 5
        hint = int(rng.integers(0, m - 1))
        lo, hi = max(0, hint - 16), min(m - 1, hint + 16)
        for args, (a, b) in [((), (0, m - 1)), ((hint, 16), (lo, hi))]:
            got = line.project(xy, *args)
            want = _numpy_project(line, xy, a, b)
            for g, w in zip(got, want, strict=True):
                assert np.array_equal(g, w)
        s = rng.uniform(line.s[0] - 10, line.s[-1] + 10, 50)
        d = rng.normal(size=50) * 3
        want_xy, want_h = _numpy_frenet(line, s, d)
        got = np.array([line.frenet_one(a, b) for a, b in zip(s, d, strict=True)])
        assert np.array_equal(got[:, :2], want_xy) and np.array_equal(got[:, 2], want_h)


def test_compiled_near_boxes_equal_numpy():
    """The compiled look-up of the boxes near a point equals the NumPy comparisons it
    replaced (boxes touching the square exactly included)."""
    from gridsim.road.base import near

    rng = np.random.default_rng(17)
    for _ in range(500):
        n = int(rng.integers(0, 80))
        lo = rng.uniform(-100, 100, (n, 2))
        boxes = np.hstack([lo, lo + rng.uniform(0, 30, (n, 2))])
        cx, cy = rng.uniform(-100, 100, 2)
        radius = float(rng.choice([45.25, rng.uniform(0, 60)]))
        boxes[: n // 4, 0] = cx + radius  # on the square's edge
        want = np.flatnonzero(
            (boxes[:, 0] <= cx + radius)
            & (boxes[:, 2] >= cx - radius)
            & (boxes[:, 1] <= cy + radius)
            & (boxes[:, 3] >= cy - radius)
        )
        assert np.array_equal(near(boxes, np.array([cx, cy]), radius), want)


def test_compiled_point_ahead_equals_project_then_frenet_one():
    """``Polyline.ahead_of`` (one kernel call) gives the bits of :meth:`Polyline.project`
    followed by :meth:`Polyline.frenet_one` at the arc length plus the distance ahead."""
    rng = np.random.default_rng(23)
    for _ in range(500):
        pts = np.cumsum(rng.normal(0, 3, (int(rng.integers(2, 12)), 2)), axis=0)
        line = Polyline(pts, float(rng.uniform(-50, 50)))
        x, y = pts[0] + rng.normal(0, 15, 2)
        ahead, d = float(rng.uniform(0, 20)), float(rng.normal(0, 2))
        s = float(line.project(np.array([[x, y]]))[0][0])
        assert line.ahead_of(x, y, ahead, d) == line.frenet_one(s + ahead, d)


@pytest.mark.parametrize(
    ("left", "right", "message"),
    [
        ([(0, 0), (0, 0)], [(0, -3), (10, -3)], "lanelet 1 leftBound: all its points coincide"),
        ([(0, 0), (10, 0)], [(0, 0), (10, 0)], "lanelet 1 has no area"),
    ],
)
def test_degenerate_lanelets_are_refused(tmp_path, left, right, message):
    def bound(points):
        return "".join(f"<point><x>{x}</x><y>{y}</y></point>" for x, y in points)

    bad = tmp_path / "deg.xml"
    bad.write_text(f"<commonRoad><lanelet id='1'><leftBound>{bound(left)}</leftBound>"
                   f"<rightBound>{bound(right)}</rightBound></lanelet></commonRoad>")  # fmt: skip
    with pytest.raises(DataError, match=f"deg.xml: {message}"):
        load_lanelet_road(bad)


def test_city_lanes_of_one_direction_are_divided_by_lines():
    """Each street has its centre line and, with L lanes per direction, L - 1 lines on each
    side between them, a lane width apart and parallel to the street."""
    one = CityRoad(CityParams(blocks_x=2, blocks_y=2, jitter=0.0), seed=0)
    two = CityRoad(CityParams(blocks_x=2, blocks_y=2, jitter=0.0, lanes_per_direction=2), seed=0)
    centre = np.array([0.0, 0.0])
    lines_one = one.lane_markings(centre, 1e6)
    lines_two = two.lane_markings(centre, 1e6)
    assert len(lines_two) == 3 * len(lines_one) == 3 * len(one.edges)
    mid, left = lines_two[0], lines_two[1]
    assert np.allclose(np.hypot(*(left - mid).T), two.params.lane_width)
    (ax, ay), (bx, by) = mid[1] - mid[0], left[1] - left[0]
    assert abs(ax * by - ay * bx) < 1e-6  # parallel
