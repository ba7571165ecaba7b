"""The road interface shared by generated and recorded maps.

A road is a set of lanes (centre polylines with a width), a drivable area (polygons, used by
the sensor and renderer), boundary segments (used for off-road collisions) and lane markings.
All coordinates are metres in the world frame (x east, y north).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from gridsim.errors import DataError
from gridsim.road import base_kernels
from gridsim.road.polyline import Polyline

#: The most cells of a static road's drivable-area raster (1e8: 2 km x 2 km at 0.2 m; the
#: built-in maps have about 2e6).
MAX_RASTER_CELLS = 10**8
#: A static road's raster: its cell [m], and its margin [m] around the drivable polygons.
RASTER_RESOLUTION, RASTER_MARGIN = 0.2, 2.0


def raster_cells(extent, resolution: float = RASTER_RESOLUTION) -> float:
    """The cells of a static road's raster of ``extent`` ``(width, height)`` [m], its margins
    (:data:`RASTER_MARGIN`) included; a road of more than :data:`MAX_RASTER_CELLS` is
    refused."""
    return float(np.prod(np.ceil(np.asarray(extent, dtype=np.float64) / resolution) + 1))


@dataclass
class Lane:
    """One lane: its centre line (direction of travel along increasing s) and width [m]."""

    centre: Polyline
    width: float


#: Gaps between drivable polygons narrower than this [m] are closed (treated as drivable).
CLOSE_GAP = 1.0


def bbox_of(polys: list[np.ndarray]) -> np.ndarray:
    """Axis-aligned boxes ``(K, 4)`` = ``[xmin, ymin, xmax, ymax]`` of a list of point arrays."""
    if not polys:
        return np.zeros((0, 4))
    starts = np.cumsum([0] + [len(p) for p in polys[:-1]])
    points = np.concatenate(polys)
    return np.hstack([np.minimum.reduceat(points, starts), np.maximum.reduceat(points, starts)])


def near(boxes: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
    """Indices of the boxes that intersect the square of half-size ``radius`` around ``center``."""
    return base_kernels.near(boxes, float(center[0]), float(center[1]), float(radius))


class RoadTracking(NamedTuple):
    """What a compiled tick needs to follow the ego on a road that may grow (its ``road``
    argument): while the ego stays within the stretch, the road needs no Python."""

    line: tuple  # the reference line's Polyline.tracking_data()
    ref_s: np.ndarray  # the reference line's arc lengths [m]
    hint: int  # the segment the ego was tracked on
    keep_ahead: float  # road kept ahead of the ego [m]: less means grow (in Python)
    keep_behind: float  # road kept behind the ego [m]
    cut_max: float  # samples behind beyond which the road is trimmed (in Python)


class Road(ABC):
    """Abstract road. Generated roads may change as the ego drives (see :meth:`update`)."""

    #: Incremented whenever boundary segments change (collision shapes must be rebuilt).
    version: int = 0
    #: Whether the road never changes (nothing to track as the ego drives).
    static: bool = False
    #: Whether the road's edges enclose its drivable area, so that a footprint cannot leave
    #: it without touching an edge (not so where lanes are cut off at a map's border).
    enclosed: bool = True

    @property
    @abstractmethod
    def lanes(self) -> list[Lane]:
        """Lanes of the road (for a generated road, the currently generated stretch)."""

    def update(self, ego_xy: np.ndarray) -> None:  # noqa: B027 - optional hook
        """Let a generated road extend ahead of / trim behind the ego. Static roads do nothing."""

    def tracking(self) -> RoadTracking | None:
        """What a compiled world tick needs to follow the ego on a road that changes as it
        drives (:func:`~gridsim.world.world_kernels.follow_tick`'s ``road``), or None: not
        now, or never (the default; a :attr:`static` road needs none)."""
        return None

    def shared_parts(self) -> list:
        """The parts of this road that copies of a world share (never changed, the same for
        every seed; see :func:`~gridsim.scenario.build.build_world`): none by default."""
        return []

    def set_tracked(self, ego_s: float, hint: int) -> None:  # noqa: B027 - optional hook
        """Take the ego's arc length [m] and segment from a compiled tick (roads that offer
        :meth:`tracking`)."""

    @abstractmethod
    def drivable_polygons(self, center: np.ndarray, radius: float) -> list[np.ndarray]:
        """Polygons ``(K, 2)`` whose union is the drivable area within ``radius`` of ``center``
        (never modified in place once handed out: the sensor keeps their concatenation while
        the same arrays come again)."""

    @abstractmethod
    def boundary_segments(self) -> np.ndarray:
        """Road edges as segments ``(M, 4)`` = ``[x0, y0, x1, y1]``."""

    @abstractmethod
    def lane_markings(self, center: np.ndarray, radius: float) -> list[np.ndarray]:
        """Polylines of painted lane dividers near ``center`` (for rendering)."""

    @abstractmethod
    def is_drivable(self, xy: np.ndarray) -> np.ndarray:
        """Boolean array: which of the points ``(N, 2)`` lie on the drivable area."""


def _drop_open_ends(segments: np.ndarray, open_ends: np.ndarray | None, tol: float) -> np.ndarray:
    """Remove boundary segments lying along ``open_ends`` ``(E, 4)``: where a map's lanes are
    cut off at its border there is no curb, so driving out there is not a collision."""
    if open_ends is None or len(open_ends) == 0 or len(segments) == 0:
        return segments
    mid = 0.5 * (segments[:, :2] + segments[:, 2:])
    a, b = open_ends[:, :2], open_ends[:, 2:]
    ab = b - a
    t = np.einsum("mek,ek->me", mid[:, None, :] - a[None], ab) / np.maximum(
        np.sum(ab * ab, 1), 1e-12
    )
    foot = a[None] + np.clip(t, 0.0, 1.0)[..., None] * ab[None]
    dist = np.hypot(*(mid[:, None, :] - foot).transpose(2, 0, 1))
    seg_dir = segments[:, 2:] - segments[:, :2]
    cos = np.abs(seg_dir @ ab.T) / np.maximum(
        np.linalg.norm(seg_dir, axis=1)[:, None] * np.linalg.norm(ab, axis=1)[None], 1e-12
    )
    on_open_end = np.any((dist < 4 * tol) & (cos > 0.9), axis=1)
    return segments[~on_open_end]


class StaticRoad(Road):
    """A road whose geometry never changes: a city network or a recorded map.

    The drivable area is the union of ``polygons``; it is rasterised once at ``resolution``
    metres to answer :meth:`is_drivable` in O(1) and to extract the boundary of the union.
    ``open_ends`` are segments where lanes are cut off at the map's border: no boundary there.
    """

    static = True

    def __init__(
        self,
        lanes: list[Lane],
        polygons: list[np.ndarray],
        markings: list[np.ndarray] | None = None,
        resolution: float = RASTER_RESOLUTION,
        open_ends: np.ndarray | None = None,
    ) -> None:
        if not polygons:
            raise ValueError("a road needs at least one drivable polygon")
        self._lanes = lanes
        self._polygons = [np.asarray(p, dtype=np.float64) for p in polygons]
        self._poly_boxes = bbox_of(self._polygons)
        self._markings = markings or []
        self._marking_boxes = bbox_of(self._markings)
        self._res = resolution
        self._origin = self._poly_boxes[:, :2].min(axis=0) - RASTER_MARGIN
        extent = self._poly_boxes[:, 2:].max(axis=0) + RASTER_MARGIN - self._origin
        cells = raster_cells(extent, resolution)
        if not cells <= MAX_RASTER_CELLS:
            raise DataError(f"the road spans {extent[0]:.3g} m x {extent[1]:.3g} m: at "
                            f"{resolution} m a raster of {cells:.3g} cells, more than "
                            f"{MAX_RASTER_CELLS:.0e}; is a coordinate wrong?")  # fmt: skip
        w, h = (np.ceil(extent / resolution)).astype(int) + 1
        self._raster = np.zeros((h, w), np.uint8)
        for poly in self._polygons:  # one call per polygon: a multi-polygon call XORs overlaps
            cv2.fillPoly(self._raster, [self._to_px(poly)], 1, lineType=cv2.LINE_8, shift=4)
        # Close slivers between adjacent polygons (digitising gaps in recorded maps, narrower
        # than CLOSE_GAP metres): they are painted areas, not curbs.
        k = 2 * int(np.ceil(CLOSE_GAP / resolution / 2)) + 1
        self._raster = cv2.morphologyEx(self._raster, cv2.MORPH_CLOSE, np.ones((k, k), np.uint8))
        self._segments = _drop_open_ends(self._extract_boundaries(), open_ends, resolution)
        self.enclosed = open_ends is None or len(open_ends) == 0

    @property
    def lanes(self) -> list[Lane]:
        return self._lanes

    def shared_parts(self) -> list:
        """The whole road: its geometry never changes."""
        return [self]

    @property
    def bounds(self) -> np.ndarray:
        """``[xmin, ymin, xmax, ymax]`` of the drivable area [m]."""
        return np.array(
            [*self._poly_boxes[:, :2].min(axis=0), *self._poly_boxes[:, 2:].max(axis=0)]
        )

    def _to_px(self, pts: np.ndarray) -> np.ndarray:
        # Raster row r covers y in origin_y + [r, r+1) * res (row index grows with y).
        px = (pts - self._origin) / self._res - 0.5
        return np.round(px * 16).astype(np.int32)

    def _extract_boundaries(self) -> np.ndarray:
        contours, _ = cv2.findContours(self._raster, cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
        segs = []
        for c in contours:
            c = cv2.approxPolyDP(c, 0.5, closed=True)[:, 0, :].astype(np.float64)
            if len(c) < 2:
                continue
            world = (c + 0.5) * self._res + self._origin
            nxt = np.roll(world, -1, axis=0)
            segs.append(np.hstack([world, nxt]))
        return np.vstack(segs) if segs else np.zeros((0, 4))

    def drivable_polygons(self, center, radius):
        return [self._polygons[i] for i in near(self._poly_boxes, center, radius)]

    def boundary_segments(self):
        return self._segments

    def lane_markings(self, center, radius):
        if not self._markings:
            return []
        return [self._markings[i] for i in near(self._marking_boxes, center, radius)]

    def is_drivable(self, xy):
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        ij = np.floor((xy - self._origin) / self._res).astype(np.int64)
        h, w = self._raster.shape
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < w) & (ij[:, 1] >= 0) & (ij[:, 1] < h)
        out = np.zeros(len(xy), dtype=bool)
        out[inside] = self._raster[ij[inside, 1], ij[inside, 0]] > 0
        return out
