"""Ego-centred occupancy grids from a simulated range sensor, with occlusion.

**Grid frame.** The grid is ``rows x cols`` cells of ``cell_size`` metres, centred on the ego's
reference point (rear-axle centre). Array index ``[r, c]``: rows grow *down*, columns grow
*right*. The cell centre of ``[r, c]`` lies ``right = (c + 0.5 - cols/2) * cell_size`` and
``up = (rows/2 - r - 0.5) * cell_size`` metres from the ego. With ``orientation="north_up"``
(the default, as in the paper) *up* is world +y (north) and *right* world +x (east); with
``"heading_up"`` *up* is the ego's heading and *right* the ego's right-hand side.

**Cell values** (uint8): :data:`FREE` = 0 (seen, empty), :data:`UNKNOWN` = 128 (not seen:
occluded behind the first hit, out of range, outside every mount's field of view),
:data:`OCCUPIED` = 255 (seen obstacle: a vehicle footprint or non-drivable ground). Divided by
255 they read 0 / 0.5 / 1.

**Sensing.** Each mount casts ``rays`` rays over 360 degrees (limited to its ``fov``) out to
``max_range`` metres. Along a ray, cells before the first obstacle are free; obstacle cells up
to ``hit_depth`` metres beyond the first hit are occupied; everything farther is unknown. The
union over mounts is returned. Rays are sampled every ``ray_step`` cells at precomputed whole
cells and walked up to their first obstacle (:mod:`gridsim.sensors.rays`), so the cost does not
depend on the number of vehicles. Mount positions are snapped to whole cells.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np

from gridsim import libm
from gridsim.frames import world_to_pixel
from gridsim.sensors.occupancy_kernels import (
    box_quads,
    diagonal_map,
    near_corners,
    pixel_points,
    pixel_quads,
)
from gridsim.sensors.rays import (
    cell_states,
    cell_states_by_ray,
    first_hits,
    grid_states,
    index_dtype,
    mark_visible,
    ray_cells,
    ray_runs,
)

FREE, UNKNOWN, OCCUPIED = 0, 128, 255
# obstacle + 2 * visible -> cell state
_STATE_LUT = np.array([UNKNOWN, UNKNOWN, FREE, OCCUPIED], np.uint8)
_NO_QUADS = np.zeros((0, 4, 2), np.int32)


def _is_diagonal(a: np.ndarray) -> bool:
    """Whether the affine map ``a`` ``(2, 3)`` only scales and shifts (a north-up grid's)."""
    return a[0, 1] == 0.0 and a[1, 0] == 0.0


@lru_cache(maxsize=256)
def ray_tables(rows: int, cols: int, cell_size: float, max_range: float, rays: int,
               ray_step: float, ou: int, ov: int) -> tuple:  # fmt: skip
    """Ray samples ``(rays, samples, 2)`` (whole cells, column and row), their walk tables
    (:func:`~gridsim.sensors.rays.ray_runs`), per-cell (ray, radius) tables and the cells of
    each ray (:func:`~gridsim.sensors.rays.ray_cells`) of a ``rows x cols`` grid of
    ``cell_size`` [m] seen by ``rays`` rays sampled every ``ray_step`` cells out to
    ``max_range`` [m] from a mount ``(ou, ov)`` cells off the grid centre.

    Cached and shared by every sensor of the same grid (mounts snap to whole cells): many
    environments in one process read one copy, which stays in cache. The arrays are
    read-only."""
    # Rays need not reach past the farthest cell of the grid.
    reach = min(max_range / cell_size, 0.5 * np.hypot(rows, cols) + 1.0)
    n_r = int(np.ceil(reach / ray_step)) + 2
    theta = np.arange(rays) * (2 * np.pi / rays)
    r = np.arange(n_r) * ray_step
    # Sample offsets in pixels (u right, v down) along rays at angle theta from "right",
    # counter-clockwise towards "up".
    du_ray = (np.cos(theta)[:, None] * r[None]).astype(np.float32)
    dv_ray = (-np.sin(theta)[:, None] * r[None]).astype(np.float32)
    u0, v0 = cols / 2 - 0.5 + ou, rows / 2 - 0.5 + ov
    samples, _ = cv2.convertMaps(
        du_ray + np.float32(u0), dv_ray + np.float32(v0), cv2.CV_16SC2, nninterpolation=True
    )
    v, u = np.mgrid[0:rows, 0:cols].astype(np.float64)
    du, dv = u - u0, v - v0
    ang = np.mod(libm.arctan2(-dv, du), 2 * np.pi)
    ray = (np.rint(ang / (2 * np.pi) * rays).astype(np.intp) % rays).astype(index_dtype(rays))
    rad = (np.hypot(du, dv) / ray_step).astype(np.float32)
    rad[rad > max_range / cell_size / ray_step] = np.inf  # out of range: never visible
    tables = (samples, ray_runs(samples, rows, cols), ray, rad, ray_cells(ray, rad, rays))
    for a in (samples, ray, rad, *tables[1], *tables[4]):
        a.setflags(write=False)
    return tables


@dataclass(frozen=True)
class SensorMount:
    """A sensor on the ego: position [m] in the body frame (x forward, y left of the rear
    axle), direction ``yaw`` [rad] from the heading, field of view ``fov`` [rad]."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    fov: float = 2 * np.pi


@dataclass(frozen=True)
class GridSpec:
    """Size and orientation of the occupancy grid."""

    rows: int = 128
    cols: int = 128
    cell_size: float = 0.5
    orientation: str = "north_up"
    max_range: float = 50.0
    rays: int = 720
    hit_depth: float = 0.5
    ray_step: float = 0.5
    mounts: tuple[SensorMount, ...] = field(default_factory=lambda: (SensorMount(),))

    def __post_init__(self) -> None:
        if self.rows <= 0 or self.cols <= 0 or self.cell_size <= 0:
            raise ValueError(
                f"grid size must be positive, got {self.rows}x{self.cols} at {self.cell_size} m"
            )
        if self.orientation not in ("north_up", "heading_up"):
            raise ValueError(
                f"orientation must be 'north_up' or 'heading_up', got {self.orientation!r}"
            )
        if self.max_range <= 0 or self.rays < 8 or self.hit_depth < 0 or not self.mounts:
            raise ValueError("need max_range > 0, rays >= 8, hit_depth >= 0 and at least one mount")
        if not 0.1 <= self.ray_step <= 2.0:
            raise ValueError(f"ray_step must be in [0.1, 2] cells, got {self.ray_step}")


class OccupancyGridSensor:
    """Renders :class:`GridSpec` grids from the drivable area and vehicle footprints."""

    def __init__(self, spec: GridSpec | None = None) -> None:
        self.spec = spec = spec or GridSpec()
        rows, cols = spec.rows, spec.cols
        self._theta = np.arange(spec.rays) * (2 * np.pi / spec.rays)
        self._depth = spec.hit_depth / spec.cell_size / spec.ray_step
        #: Half the grid's diagonal [m]: what lies farther from the ego is not in the grid.
        self.radius = 0.5 * np.hypot(rows, cols) * spec.cell_size
        self._obstacles = np.empty((rows, cols), np.uint8)
        self._visible = np.empty((rows, cols), np.uint8)
        self._hits = np.empty(spec.rays, np.int64)
        self._last_polygons: tuple[list[np.ndarray], np.ndarray | None] = ([], None)

    def _tables_for(self, ou: int, ov: int):
        """The ray tables (:func:`ray_tables`) of this sensor's grid for a mount ``(ou, ov)``
        cells off the grid centre."""
        s = self.spec
        return ray_tables(s.rows, s.cols, s.cell_size, s.max_range, s.rays, s.ray_step, ou, ov)

    # -- geometry ----------------------------------------------------------------------------
    def world_to_pixel(self, ego_xy: np.ndarray, ego_psi: float) -> np.ndarray:
        """Affine map ``(2, 3)``: world metres -> pixel coordinates (u = column, v = row)."""
        s = self.spec
        return world_to_pixel(ego_xy, ego_psi, s.rows, s.cols, s.cell_size, s.orientation)

    @staticmethod
    def _to_pixels(points: np.ndarray, a: np.ndarray) -> np.ndarray:
        """``points`` ``(N, 2)`` [m, world] mapped by the affine map ``a`` ``(2, 3)`` to pixel
        coordinates. A diagonal map (north-up) is compiled: each coordinate is one product
        plus an exact zero, the same bits as the BLAS product that other maps go through."""
        if _is_diagonal(a):
            return diagonal_map(points, a)
        return points @ a[:, :2].T + a[:, 2]

    def _corner_quads(self, boxes: np.ndarray, a: np.ndarray) -> np.ndarray:
        """The footprints ``boxes`` ``(N, 4, 2)`` [m, world] mapped by ``a`` as
        :func:`~gridsim.sensors.occupancy_kernels.pixel_quads` (int32 ``(N, 4, 2)``)."""
        if not len(boxes):
            return _NO_QUADS
        return pixel_quads(self._to_pixels(boxes.reshape(-1, 2), a).reshape(boxes.shape))

    def cell_centers(self, ego_xy: np.ndarray, ego_psi: float) -> np.ndarray:
        """World coordinates ``(rows, cols, 2)`` [m] of every cell centre."""
        inv = cv2.invertAffineTransform(self.world_to_pixel(ego_xy, ego_psi))
        v, u = np.mgrid[0 : self.spec.rows, 0 : self.spec.cols].astype(np.float64)
        x = inv[0, 0] * u + inv[0, 1] * v + inv[0, 2]
        y = inv[1, 0] * u + inv[1, 1] * v + inv[1, 2]
        return np.stack([x, y], axis=-1)

    # -- rendering ----------------------------------------------------------------------------
    def obstacle_mask(
        self, ego_xy, ego_psi, drivable: list[np.ndarray], boxes: np.ndarray
    ) -> np.ndarray:
        """Ground truth ``(rows, cols)`` uint8: 1 where a cell is an obstacle, else 0.

        A cell is a vehicle obstacle if its centre lies inside a footprint of ``boxes``
        ``(N, 4, 2)``; it is drivable if any part of it lies on a ``drivable`` polygon (road
        edges are rounded outwards by up to half a cell).
        """
        a = self.world_to_pixel(ego_xy, ego_psi)
        return self._fill(a, drivable, self._corner_quads(boxes, a))

    def _fill(self, a: np.ndarray, drivable: list[np.ndarray], quads: np.ndarray) -> np.ndarray:
        """:meth:`obstacle_mask` for the world -> pixel map ``a`` given the footprints as
        :func:`~gridsim.sensors.occupancy_kernels.pixel_quads` (int32 ``(N, 4, 2)``)."""
        m = self._obstacles
        m.fill(1)
        if drivable:
            points = self._concatenated(drivable)
            if _is_diagonal(a):
                px = pixel_points(points, a)
            else:
                px = np.rint(self._to_pixels(points, a) * 16).astype(np.int32)
            start = 0
            for poly in drivable:  # one call per polygon: a multi-polygon call XORs overlaps
                cv2.fillPoly(m, [px[start : start + len(poly)]], 0, cv2.LINE_8, shift=4)
                start += len(poly)
        # Each side of a footprint is moved half a pixel inwards (pixel_quads): OpenCV's fill
        # covers every pixel an edge touches, the inset turns that into "cells whose centre
        # lies inside the footprint" (exactly for axis-aligned boxes).
        for quad in quads:
            cv2.fillConvexPoly(m, quad, 1, cv2.LINE_8, shift=4)
        return m

    def _concatenated(self, polygons: list[np.ndarray]) -> np.ndarray:
        """``np.concatenate(polygons)``, kept while the same polygon arrays come again (a
        road hands out the same ones until it changes; they are never modified in place)."""
        last, points = self._last_polygons
        if len(last) != len(polygons) or any(
            a is not b for a, b in zip(last, polygons, strict=True)
        ):
            points = np.concatenate(polygons)
            self._last_polygons = (list(polygons), points)
        return points

    def render(
        self, ego_xy, ego_psi, drivable: list[np.ndarray], boxes: np.ndarray, out=None
    ) -> np.ndarray:
        """The occupancy grid (values :data:`FREE`, :data:`UNKNOWN`, :data:`OCCUPIED`), in
        ``out`` (uint8 ``(rows, cols)``, C-contiguous) if given."""
        obstacles = self.obstacle_mask(ego_xy, ego_psi, drivable, boxes)
        return self._states(obstacles, ego_psi, out)

    def observe(self, world, out: np.ndarray | None = None) -> np.ndarray:
        """The occupancy grid around the ego of ``world`` (a :class:`~gridsim.world.World`:
        its ego pose, its fleet's footprints and its road's drivable polygons), in ``out``
        if given (see :meth:`render`)."""
        ego_xy, psi = world.ego[:2], float(world.ego[2])
        radius = self.radius
        f = world.traffic.fleet
        near = (f.active, f.x, f.y, f.psi, f.length, f.width, float(ego_xy[0]), float(ego_xy[1]),
                float(radius))  # fmt: skip
        a = self.world_to_pixel(ego_xy, psi)
        if _is_diagonal(a):  # north-up: corners to pixels in one call
            quads = box_quads(*near, a)
        else:
            boxes = near_corners(*near)
            quads = self._corner_quads(boxes, a)
        obstacles = self._fill(a, world.road.drivable_polygons(ego_xy, radius), quads)
        return self._states(obstacles, psi, out)

    def _states(self, obstacles: np.ndarray, ego_psi: float, out=None) -> np.ndarray:
        """The cell states seen from the mounts given the ``obstacles`` mask (see
        :meth:`render`)."""
        grid = np.empty_like(obstacles) if out is None else out
        mounts = self.spec.mounts
        if len(mounts) == 1 and mounts[0].fov >= 2 * np.pi:
            tables = self._tables_for(*self._mount_cell(mounts[0], ego_psi))
            grid_states(obstacles, *tables[1], np.float32(self._depth), *tables[4], _STATE_LUT,
                        self._hits, grid)  # fmt: skip
            return grid
        if len(mounts) == 1:
            tables, reach = self._reach_from(mounts[0], obstacles, ego_psi)
            cell_states_by_ray(obstacles, *tables[4], reach, _STATE_LUT, grid)
            return grid
        visible = self._visible
        visible.fill(0)
        for mount in mounts:
            tables, reach = self._reach_from(mount, obstacles, ego_psi)
            mark_visible(tables[3], tables[2], reach, visible)
        cell_states(obstacles, visible, _STATE_LUT, grid)
        return grid

    def _mount_cell(self, mount: SensorMount, ego_psi: float) -> tuple[int, int]:
        """Where ``mount`` sits in the grid [whole cells off the centre: column, row]."""
        s = self.spec
        ou = ov = 0  # a mount at the rear axle, whatever the heading
        if mount.x != 0.0 or mount.y != 0.0:
            up_dir = self._up_dir(ego_psi)
            c, sn = np.cos(up_dir), np.sin(up_dir)
            mx, my = mount.x * c - mount.y * sn, mount.x * sn + mount.y * c
            # round: to the nearest even on ties, as np.rint
            ou = min(max(round(mx / s.cell_size), -(s.cols // 2)), s.cols // 2)
            ov = min(max(round(-my / s.cell_size), -(s.rows // 2)), s.rows // 2)
        return ou, ov

    def _up_dir(self, ego_psi: float) -> float:
        """The direction of the heading in the grid [rad]."""
        return ego_psi if self.spec.orientation == "north_up" else np.pi / 2

    def _reach_from(self, mount: SensorMount, obstacles: np.ndarray, ego_psi: float):
        """The tables of ``mount`` (:meth:`_tables_for`) and per ray how far [samples] it sees
        (see :func:`~gridsim.sensors.rays.mark_visible`)."""
        up_dir = self._up_dir(ego_psi)
        ou, ov = self._mount_cell(mount, ego_psi)
        tables = self._tables_for(ou, ov)
        first_hits(obstacles, *tables[1], self._hits)
        reach = self._hits.astype(np.float32) + np.float32(self._depth)
        if mount.fov < 2 * np.pi:
            off = libm.angle(np.exp(1j * (self._theta - (up_dir + mount.yaw))))
            reach[np.abs(off) > 0.5 * mount.fov] = -np.inf
        return tables, reach
