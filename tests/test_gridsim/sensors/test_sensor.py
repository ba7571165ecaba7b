"""Occupancy grids: geometry conventions, occlusion, footprints, orientation, mounts."""

import numpy as np
import pytest

from gridsim.render import colourise
from gridsim.sensors import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    GridSpec,
    OccupancyGridSensor,
    SensorMount,
)
from gridsim.vehicle.kinematics import box_corners

OPEN = [np.array([[-500.0, -500.0], [500.0, -500.0], [500.0, 500.0], [-500.0, 500.0]])]
NO_BOXES = np.zeros((0, 4, 2))


def rect(x0, y0, x1, y1):
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


def cell_right_up(spec: GridSpec):
    """Offsets [m] of the cell centres: right (columns) and up (rows), per the documented frame."""
    right = (np.arange(spec.cols) + 0.5 - spec.cols / 2) * spec.cell_size
    up = (spec.rows / 2 - np.arange(spec.rows) - 0.5) * spec.cell_size
    return right, up


def test_wall_appears_at_the_right_cells():
    spec = GridSpec(max_range=50.0)
    sensor = OccupancyGridSensor(spec)
    # The road ends at x = 10.2 m: the cell [10.0, 10.5] is partly road (drivable), the cell
    # [10.5, 11.0] is the first obstacle, and everything behind the wall is unknown.
    grid = sensor.render(np.zeros(2), 0.0, [rect(-100, -100, 10.2, 100)], NO_BOXES)
    right, up = cell_right_up(spec)
    row = int(np.argmin(np.abs(up - 0.25)))
    line = grid[row]
    assert np.all(line[right < 10.5] == FREE)
    assert line[np.argmin(np.abs(right - 10.75))] == OCCUPIED
    assert np.all(line[right > 11.6] == UNKNOWN)
    near = np.abs(up) < 8
    col = int(np.argmin(np.abs(right - 10.75)))
    assert np.all(grid[near, col] == OCCUPIED)  # the whole wall face in sight
    assert np.all(grid[:, right > 11.6] == UNKNOWN)


def test_out_of_range_is_unknown():
    spec = GridSpec(max_range=20.0)
    grid = OccupancyGridSensor(spec).render(np.zeros(2), 0.0, OPEN, NO_BOXES)
    right, up = cell_right_up(spec)
    r = np.hypot(right[None, :], up[:, None])
    assert np.all(grid[r < 19.5] == FREE)
    assert np.all(grid[r > 20.5] == UNKNOWN)


def test_cells_behind_a_vehicle_are_unknown():
    spec = GridSpec()
    box = box_corners(np.array([12.0]), np.array([0.0]), np.array([0.0]), 4.0, 2.0)
    grid = OccupancyGridSensor(spec).render(np.zeros(2), 0.0, OPEN, box)
    right, up = cell_right_up(spec)
    rows = np.abs(up) < 0.6
    assert np.all(grid[np.ix_(rows, (right > 0) & (right < 9.8))] == FREE)
    assert np.all(grid[np.ix_(rows, (right > 10.0) & (right < 10.4))] == OCCUPIED)  # front face
    assert np.all(grid[np.ix_(rows, (right > 11.0) & (right < 30))] == UNKNOWN)  # behind it
    assert np.all(grid[np.ix_(rows, right < -1)] == FREE)  # the other side is open


@pytest.mark.parametrize("angle_deg", [0, 45, 90])
def test_vehicle_footprint_covers_the_right_cells(angle_deg):
    spec = GridSpec()
    sensor = OccupancyGridSensor(spec)
    psi = np.deg2rad(angle_deg)
    cx, cy, length, width = 6.3, -4.1, 4.6, 1.9
    box = box_corners(np.array([cx]), np.array([cy]), np.array([psi]), length, width)
    mask = sensor.obstacle_mask(np.zeros(2), 0.0, OPEN, box)
    right, up = cell_right_up(spec)
    xx, yy = np.meshgrid(right, up)
    lon = (xx - cx) * np.cos(psi) + (yy - cy) * np.sin(psi)
    lat = -(xx - cx) * np.sin(psi) + (yy - cy) * np.cos(psi)
    half_diag = spec.cell_size * np.sqrt(0.5)
    inside = (np.abs(lon) < length / 2 - half_diag) & (np.abs(lat) < width / 2 - half_diag)
    outside = (np.abs(lon) > length / 2 + half_diag) | (np.abs(lat) > width / 2 + half_diag)
    assert np.all(mask[inside] == 1)
    assert np.all(mask[outside] == 0)
    assert mask.sum() * spec.cell_size**2 == pytest.approx(length * width, rel=0.2)


def test_non_square_grid_geometry():
    spec = GridSpec(rows=40, cols=160, cell_size=0.25)
    road = [rect(0, 0, 115.1, 100)]
    grid = OccupancyGridSensor(spec).render(np.array([100.0, 50.0]), 0.3, road, NO_BOXES)
    assert grid.shape == (40, 160)
    right, up = cell_right_up(spec)
    row = int(np.argmin(np.abs(up - 0.125)))
    col = int(np.argmin(np.abs(right - 15.375)))  # first cell wholly past x = 115.1
    assert (
        grid[row, col] == OCCUPIED and grid[row, col - 1] == FREE and grid[row, col + 4] == UNKNOWN
    )
    assert np.all(grid[:, right < 15.0] == FREE)


def test_heading_up_is_north_up_rotated():
    box = box_corners(np.array([9.0, -5.0]), np.array([3.0, -7.0]), np.array([0.3, 1.2]), 4.5, 1.8)
    road = [rect(-12.1, -20.1, 25.1, 6.1)]  # edges off the cell boundaries
    north = OccupancyGridSensor(GridSpec(orientation="north_up")).render(
        np.zeros(2), 0.0, road, box
    )
    # Heading east (up = east, right = south) is the north-up image turned a quarter turn
    # counter-clockwise; heading north is the north-up grid itself.
    head_e = OccupancyGridSensor(GridSpec(orientation="heading_up")).render(
        np.zeros(2), 0.0, road, box
    )
    head_n = OccupancyGridSensor(GridSpec(orientation="heading_up")).render(
        np.zeros(2), np.pi / 2, road, box
    )
    assert np.mean(np.rot90(north, 1) == head_e) > 0.995
    assert np.mean(north == head_n) > 0.995


def test_forward_fov_mount_sees_nothing_behind():
    spec = GridSpec(mounts=(SensorMount(x=2.0, fov=np.pi),))
    grid = OccupancyGridSensor(spec).render(np.zeros(2), 0.0, OPEN, NO_BOXES)
    right, _ = cell_right_up(spec)
    assert np.all(grid[:, right < -1.5] == UNKNOWN)
    assert np.all(grid[54:74, right > 4] == FREE)
    # Front and rear fans together see all around, as in the original GridSim.
    both = GridSpec(
        mounts=(SensorMount(x=1.0, fov=np.pi), SensorMount(x=1.0, yaw=np.pi, fov=np.pi))
    )
    g2 = OccupancyGridSensor(both).render(np.zeros(2), 0.0, OPEN, NO_BOXES)
    assert np.mean(g2 == FREE) > 0.99


def test_colourise_matches_the_paper_colours():
    g = np.array([[FREE, OCCUPIED, UNKNOWN]], np.uint8)
    rgb = colourise(g)
    assert rgb.shape == (1, 3, 3)
    assert (
        tuple(rgb[0, 0]) == (0, 200, 0)
        and tuple(rgb[0, 1]) == (220, 0, 0)
        and tuple(rgb[0, 2]) == (0, 0, 0)
    )


@pytest.mark.parametrize(
    "kwargs", [{"rows": 0}, {"cell_size": -0.5}, {"orientation": "east"}, {"rays": 2}]
)
def test_bad_grid_spec_is_rejected(kwargs):
    with pytest.raises(ValueError):
        GridSpec(**kwargs)


@pytest.mark.parametrize("density", [0.0, 0.01, 0.1, 0.5])
def test_compiled_ray_walk_equals_the_polar_remap(density):
    """The compiled ray walk (one cell per run of equal samples) finds the same first hits as
    remapping the whole polar image (OpenCV, nearest neighbour, outside the grid = obstacle)
    and taking the first obstacle."""
    import cv2

    from gridsim.sensors.rays import first_hits

    sensor = OccupancyGridSensor(GridSpec())
    rng = np.random.default_rng(3)
    for ou, ov in [(0, 0), (5, -3), (-64, 64)]:
        samples, runs = sensor._tables_for(ou, ov)[:2]
        obstacles = (rng.random((128, 128)) < density).astype(np.uint8)
        polar = cv2.remap(obstacles, samples, None, cv2.INTER_NEAREST,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=1)  # fmt: skip
        polar[:, -1] = 1
        hits = np.empty(len(samples), np.int64)
        first_hits(obstacles, *runs, hits)
        np.testing.assert_array_equal(hits, np.argmax(polar.view(bool), axis=1))


def _numpy_inset_half_pixel(quads):
    """The NumPy half-pixel inset that :func:`~gridsim.sensors.occupancy_kernels.pixel_quads`
    replaced (before its rounding to fixed point)."""
    sign_l = np.array([-1.0, 1.0, 1.0, -1.0])[:, None]
    sign_w = np.array([-1.0, -1.0, 1.0, 1.0])[:, None]
    e_l = quads[:, 1] - quads[:, 0]
    e_w = quads[:, 3] - quads[:, 0]
    n_l = np.linalg.norm(e_l, axis=1, keepdims=True)
    n_w = np.linalg.norm(e_w, axis=1, keepdims=True)
    u_l = e_l / np.maximum(n_l, 1e-9) * np.minimum(0.5, 0.5 * n_l)
    u_w = e_w / np.maximum(n_w, 1e-9) * np.minimum(0.5, 0.5 * n_w)
    return quads - sign_l * u_l[:, None, :] - sign_w * u_w[:, None, :]


def _random_fleet(rng, n):
    active = rng.random(n) < 0.7
    x, y = rng.uniform(-80, 80, n), rng.uniform(-80, 80, n)
    psi = rng.uniform(-10, 10, n)
    length, width = rng.uniform(0.0, 20.0, n), rng.uniform(0.0, 3.0, n)
    return active, x, y, psi, length, width


def test_compiled_footprint_corners_equal_numpy():
    """``observe``'s compiled range test and corners give the same bits as the NumPy code
    they replaced (``Fleet.footprints``, ``np.hypot``, ``box_corners``)."""
    from gridsim.sensors.occupancy_kernels import near_corners

    rng = np.random.default_rng(7)
    for n in [0, 1, 5, 40, 300]:
        active, x, y, psi, length, width = fleet = _random_fleet(rng, n)
        ex, ey = rng.uniform(-30, 30, 2)
        radius = 0.5 * np.hypot(128, 128) * 0.5
        a = active
        reach = radius + 0.5 * np.hypot(length[a], width[a])
        near = np.hypot(x[a] - ex, y[a] - ey) <= reach
        want = box_corners(x[a][near], y[a][near], psi[a][near], length[a][near],
                           width[a][near])  # fmt: skip
        got = near_corners(*fleet, float(ex), float(ey), float(radius))
        assert got.shape == want.shape and np.array_equal(got, want)


def test_compiled_pixel_quads_equal_numpy():
    """The compiled half-pixel inset and fixed-point rounding give the same int32 corners
    as the NumPy code they replaced, for boxes mapped to pixels (north-up and heading-up
    affine maps), tiny and degenerate boxes, and arbitrary quadrilaterals."""
    from gridsim.sensors.occupancy_kernels import pixel_quads

    rng = np.random.default_rng(11)
    sensor = OccupancyGridSensor(GridSpec())
    heading_up = OccupancyGridSensor(GridSpec(orientation="heading_up"))
    for _ in range(200):
        _, x, y, psi, length, width = _random_fleet(rng, 30)
        length[:3], width[:3] = 0.0, rng.uniform(0, 0.2, 3)  # degenerate and tiny boxes
        boxes = box_corners(x, y, psi, length, width)
        ego = rng.uniform(-20, 20, 2)
        for s in (sensor, heading_up):
            a = s.world_to_pixel(ego, float(rng.uniform(-4, 4)))
            px = boxes @ a[:, :2].T + a[:, 2]
            want = np.rint(_numpy_inset_half_pixel(px) * 16).astype(np.int32)
            assert np.array_equal(pixel_quads(px), want)
        quads = rng.normal(0, 30, (30, 4, 2)) * rng.choice([1e-3, 1.0, 10.0], (30, 1, 1))
        want = np.rint(_numpy_inset_half_pixel(quads) * 16).astype(np.int32)
        assert np.array_equal(pixel_quads(quads), want)


def test_cell_states_by_ray_equal_marking_then_states():
    """``cell_states_by_ray`` (one mount: per ray its cells nearest first, up to its reach)
    equals ``mark_visible`` into a cleared grid followed by ``cell_states``."""
    from gridsim.sensors.occupancy import _STATE_LUT
    from gridsim.sensors.rays import cell_states, cell_states_by_ray, mark_visible

    rng = np.random.default_rng(5)
    sensor = OccupancyGridSensor(GridSpec())
    for ou, ov in [(0, 0), (3, -2), (-64, 64)]:
        _, _, ray, rad, by_ray = sensor._tables_for(ou, ov)
        for _ in range(20):
            obstacles = (rng.random((128, 128)) < 0.1).astype(np.uint8)
            reach = rng.uniform(-1, 200, len(sensor._theta)).astype(np.float32)
            reach[rng.random(len(reach)) < 0.1] = -np.inf
            reach[rng.random(len(reach)) < 0.1] = rad.ravel()[rng.integers(0, rad.size)]  # ties
            visible = np.zeros_like(obstacles)
            mark_visible(rad, ray, reach, visible)
            for lut in (_STATE_LUT, np.array([7, 128, 0, 255], np.uint8)):  # unseen alike or not
                want = np.empty_like(obstacles)
                cell_states(obstacles, visible, lut, want)
                got = np.empty_like(obstacles)
                cell_states_by_ray(obstacles, *by_ray, reach, lut, got)
                assert np.array_equal(got, want)


def test_north_up_pixel_map_equals_the_matrix_product():
    """The north-up world -> pixel map, built from floats and applied compiled, gives the
    same bits as the matrix products (``rot @ ego``, ``points @ a[:, :2].T + a[:, 2]``) it
    replaced; a heading-up map still goes through ``@``."""
    from gridsim.sensors.occupancy_kernels import diagonal_map

    rng = np.random.default_rng(9)
    for cell_size, rows, cols in [(0.5, 128, 128), (0.3, 64, 100), (1.0, 7, 9)]:
        sensor = OccupancyGridSensor(GridSpec(rows=rows, cols=cols, cell_size=cell_size))
        k = 1.0 / cell_size
        rot = np.array([[k, 0.0], [0.0, -k]])
        for _ in range(300):
            ego = rng.normal(0, 1, 2) * rng.choice([1e-3, 10.0, 1e4])
            t = np.array([cols / 2 - 0.5, rows / 2 - 0.5]) - rot @ ego
            want = np.hstack([rot, t[:, None]])
            a = sensor.world_to_pixel(ego, float(rng.uniform(-4, 4)))
            assert np.array_equal(a, want)
            points = ego + rng.normal(0, 40, (int(rng.integers(0, 60)), 2))
            assert np.array_equal(diagonal_map(points, a), points @ a[:, :2].T + a[:, 2])
            assert np.array_equal(sensor._to_pixels(points, a), points @ a[:, :2].T + a[:, 2])


@pytest.mark.parametrize("orientation", ["north_up", "heading_up"])
def test_the_sensor_pixel_map_is_the_grid_frame_then_its_pixels(orientation):
    from gridsim.frames import grid_rotation, grid_to_pixel, world_to_grid, world_to_pixel

    rng = np.random.default_rng(4)
    ego, psi = rng.normal(size=2) * 50.0, float(rng.uniform(-np.pi, np.pi))
    points = ego + rng.normal(size=(200, 2)) * 20.0
    affine = world_to_pixel(ego, psi, 96, 128, 0.5, orientation)
    direct = points @ affine[:, :2].T + affine[:, 2]
    grid = world_to_grid(points, ego, grid_rotation(orientation, psi))
    np.testing.assert_allclose(direct, grid_to_pixel(grid, 96, 128, 0.5, orientation), atol=1e-9)


def test_fused_grid_kernels_equal_the_separate_calls():
    """The one-call kernels of ``observe`` give the same bits as the calls they fuse:
    ``pixel_points`` as ``np.rint(diagonal_map(...) * 16).astype(np.int32)``, ``box_quads``
    as ``near_corners``, ``diagonal_map`` and ``pixel_quads``, and ``grid_states`` as
    ``first_hits``, the float32 reach and ``cell_states_by_ray``."""
    from gridsim.sensors.occupancy import _STATE_LUT
    from gridsim.sensors.occupancy_kernels import (
        box_quads,
        diagonal_map,
        near_corners,
        pixel_points,
        pixel_quads,
    )
    from gridsim.sensors.rays import cell_states_by_ray, first_hits, grid_states

    rng = np.random.default_rng(13)
    sensor = OccupancyGridSensor(GridSpec())
    for n in [0, 1, 5, 40, 300]:
        for _ in range(20):
            fleet = _random_fleet(rng, n)
            ego = rng.uniform(-30, 30, 2) * rng.choice([1.0, 1e3])
            fleet = (fleet[0], fleet[1] + ego[0], fleet[2] + ego[1], *fleet[3:])
            a = sensor.world_to_pixel(ego, float(rng.uniform(-4, 4)))
            ex, ey, radius = float(ego[0]), float(ego[1]), float(sensor.radius)
            boxes = near_corners(*fleet, ex, ey, radius)
            want = pixel_quads(diagonal_map(boxes.reshape(-1, 2), a).reshape(boxes.shape))
            got = box_quads(*fleet, ex, ey, radius, a)
            assert got.dtype == want.dtype and np.array_equal(got, want)
            points = ego + rng.normal(0, 40, (int(rng.integers(0, 300)), 2))
            want = np.rint(diagonal_map(points, a) * 16).astype(np.int32)
            assert np.array_equal(pixel_points(points, a), want)
    depth = np.float32(sensor._depth)
    for ou, ov in [(0, 0), (5, -3), (-64, 64)]:
        tables = sensor._tables_for(ou, ov)
        for density in [0.0, 0.01, 0.1, 0.5]:
            obstacles = (rng.random((128, 128)) < density).astype(np.uint8)
            hits = np.empty(len(sensor._theta), np.int64)
            first_hits(obstacles, *tables[1], hits)
            want = np.empty_like(obstacles)
            reach = hits.astype(np.float32) + depth
            cell_states_by_ray(obstacles, *tables[4], reach, _STATE_LUT, want)
            got, got_hits = np.empty_like(obstacles), np.empty_like(hits)
            grid_states(obstacles, *tables[1], depth, *tables[4], _STATE_LUT, got_hits, got)
            assert np.array_equal(got_hits, hits) and np.array_equal(got, want)


def test_sensors_of_one_grid_share_read_only_ray_tables():
    """Many environments in one process read one copy of the ray tables (it stays in cache);
    a sensor of another grid has its own, and nobody can write to them."""
    a, b = OccupancyGridSensor(GridSpec()), OccupancyGridSensor(GridSpec())
    other = OccupancyGridSensor(GridSpec(rows=64, cols=64))
    assert a._tables_for(0, 0) is b._tables_for(0, 0)
    assert other._tables_for(0, 0) is not a._tables_for(0, 0)
    samples, runs, ray, rad, by_ray = a._tables_for(0, 0)
    for table in (samples, *runs, ray, rad, *by_ray):
        assert not table.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        rad[0, 0] = 0.0
