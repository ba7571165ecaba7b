"""Ego collision detection with pymunk: oriented boxes against traffic and road edges.

Road edges are static pymunk segments (rebuilt when a generated road changes). Traffic
footprints are kinematic boxes, one per participant, parked far away by default: a numpy
broad phase picks the participants whose bounding circles can touch the ego, and only those
are moved into place, so the cost does not grow with the number of vehicles far away.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pymunk

from gridsim.world import collision_kernels

_PARK = (1e9, 1e9)
#: How far [m] the ego's footprint may reach over a road edge before it counts as off-road.
EDGE_TOLERANCE = 0.3
#: Road edges farther than this [m] from the ego are not loaded into pymunk.
BOUNDARY_RADIUS = 40.0
#: The edges are reloaded after the ego moved this far [m] (must stay well below the radius).
BOUNDARY_RELOAD = 20.0
#: pymunk is asked about (and given) only the road edges that pass within the ego core's
#: bounding circle plus this margin [m] (far more than any rounding: it cannot report a
#: farther one).
EDGE_QUERY_MARGIN = 1.0


@dataclass(frozen=True)
class Contact:
    """What the ego touched: ``vehicles`` (traffic indices) and ``boundary`` (edge indices)."""

    vehicles: tuple[int, ...] = ()
    boundaries: tuple[int, ...] = ()

    @property
    def any(self) -> bool:
        return bool(self.vehicles or self.boundaries)


def _box(body: pymunk.Body, length: float, width: float) -> pymunk.Poly:
    hl, hw = 0.5 * length, 0.5 * width
    return pymunk.Poly(body, [(-hl, -hw), (hl, -hw), (hl, hw), (-hl, hw)])


class BroadPhase(NamedTuple):
    """What the compiled contact pre-tests read besides the ego and the fleet."""

    edges: np.ndarray  # the road edges loaded, (M, 4)
    length: float  # the ego's box [m]
    width: float
    radius: float  # the ego box's circumradius [m]
    core_reach: float  # how far from the ego's centre an edge can touch [m]


class CollisionChecker:
    """Checks the ego's footprint (a ``length`` x ``width`` box) against the world."""

    def __init__(
        self, ego_length: float, ego_width: float, edge_tolerance: float = EDGE_TOLERANCE
    ) -> None:
        self._args = (ego_length, ego_width, edge_tolerance)
        # Against road edges, a wheel on the line is not yet off the road: a box smaller by
        # ``edge_tolerance`` on every side is tested.
        shrink = 2 * edge_tolerance
        core = (max(ego_length - shrink, 0.1), max(ego_width - shrink, 0.1))
        self._core = core
        self._space: pymunk.Space | None = None  # made on first use: see space
        self._ego_radius = 0.5 * np.hypot(ego_length, ego_width)
        self._core_reach = 0.5 * float(np.hypot(*core)) + EDGE_QUERY_MARGIN
        self._edges = np.zeros((0, 4))  # the loaded road edges' segments
        self._edge_index = np.zeros(0, np.int64)  # their indices in the road's segments
        self._boundary_shapes: dict[int, pymunk.Segment] = {}
        self._shapes: dict[int, tuple[pymunk.Body, pymunk.Poly]] = {}
        self._placed: set[int] = set()
        self._road_version = -1
        self._boundary_center = (np.inf, np.inf)

    @property
    def space(self) -> pymunk.Space:
        """The pymunk space with the ego's boxes, made on first use (a checker that never
        meets anything, such as a shadow world's, never needs one)."""
        if self._space is None:
            self._ego_body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            self._ego_shape = _box(self._ego_body, self._args[0], self._args[1])
            self._ego_core = _box(self._ego_body, *self._core)
            # The ego's two boxes share a group: a query with one does not report the other
            # (the queries skip the ego's body anyway; this spares pymunk's callback for it).
            self._ego_shape.filter = self._ego_core.filter = pymunk.ShapeFilter(group=1)
            self._space = pymunk.Space()
            self._space.add(self._ego_body, self._ego_shape, self._ego_core)
        return self._space

    @property
    def core(self) -> tuple[float, float]:
        """Length and width [m] of the box tested against road edges (the footprint less
        the edge tolerance on every side)."""
        return self._core

    @property
    def ego_box(self) -> tuple[float, float, float]:
        """The ego box's length and width [m] and its bounding circle's radius [m] (the broad
        phase's)."""
        return float(self._args[0]), float(self._args[1]), float(self._ego_radius)

    def __deepcopy__(self, memo) -> CollisionChecker:
        """A fresh checker: its pymunk space only caches shapes near the ego (edges within
        :data:`BOUNDARY_RADIUS` of where they were loaded, traffic boxes placed per check) and
        contacts come out sorted, so its results do not depend on what it loaded before."""
        return CollisionChecker(*self._args)

    def set_boundaries(self, segments: np.ndarray, version: int, center: np.ndarray) -> None:
        """Load the road-edge segments ``(M, 4)`` within :data:`BOUNDARY_RADIUS` of ``center``
        (made static pymunk shapes when first near the ego: :meth:`_load_edges`); reloads only
        when the road ``version`` changed or the ego moved more than :data:`BOUNDARY_RELOAD`
        metres since the last load."""
        if self.keeps_boundaries(version, float(center[0]), float(center[1])):
            return
        if self._boundary_shapes:
            self.space.remove(*self._boundary_shapes.values())
        mid_x = 0.5 * (segments[:, 0] + segments[:, 2])
        mid_y = 0.5 * (segments[:, 1] + segments[:, 3])
        half = 0.5 * np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
        near = np.flatnonzero(
            np.hypot(mid_x - center[0], mid_y - center[1]) - half <= BOUNDARY_RADIUS
        )
        self._boundary_shapes = {}  # the pymunk shapes made so far, by index into _edges
        self._edges, self._edge_index = np.ascontiguousarray(segments[near], np.float64), near
        self._road_version = version
        self._boundary_center = (float(center[0]), float(center[1]))

    def keeps_boundaries(self, version: int, cx: float, cy: float) -> bool:
        """Whether :meth:`set_boundaries` for road ``version`` around ``(cx, cy)`` would keep
        the edges loaded (and do nothing)."""
        bx, by = self._boundary_center
        return version == self._road_version and np.hypot(cx - bx, cy - by) < BOUNDARY_RELOAD

    def broad_phase_data(self) -> BroadPhase:
        """``(loaded edges, ego length, width, radius, core reach)``: what the broad phases of
        :meth:`check_fleet` (``collision_kernels.within_reach``) and :meth:`_query`
        (``collision_kernels.near_segments``) read besides the ego and the fleet. When no
        edge is near, every vehicle the broad phase finds is clearly apart from the ego's box
        (``collision_kernels.may_touch``) and :meth:`keeps_boundaries` holds, a check reports
        no contact (and may be skipped: boxes placed by an earlier check stay listed in
        ``_placed``, and the next check parks them)."""
        return BroadPhase(self._edges, float(self._args[0]), float(self._args[1]),
                          float(self._ego_radius), float(self._core_reach))  # fmt: skip

    def _shape_for(self, index: int, length: float, width: float) -> pymunk.Body:
        """The kinematic body of participant ``index``, its box resized if needed."""
        body, shape = self._shapes.get(index, (None, None))
        if body is None:
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            body.gridsim_index = index
            self.space.add(body)
        size = (length, width)
        if shape is None or shape.gridsim_size != size:
            if shape is not None:
                self.space.remove(shape)
            shape = _box(body, length, width)
            shape.gridsim_size = size
            self.space.add(shape)
        self._shapes[index] = (body, shape)
        return body

    def check(
        self,
        ego_center: np.ndarray,
        ego_psi: float,
        traffic: tuple[np.ndarray, ...],
        traffic_index: np.ndarray,
    ) -> Contact:
        """Contacts of the ego box centred at ``ego_center`` with heading ``ego_psi``.

        ``traffic`` is ``(x, y, psi, length, width)`` of candidate participants (centre poses);
        ``traffic_index`` their indices in the fleet, reported in :attr:`Contact.vehicles`.
        """
        x, y, psi, length, width = traffic
        everyone = np.ones(len(x), bool)
        self._place(traffic, traffic_index, self._near(ego_center, everyone, x, y, length, width))
        return self._query(ego_center, ego_psi)

    def check_fleet(self, ego_center: np.ndarray, ego_psi: float, fleet) -> Contact:
        """:meth:`check` against the active participants of ``fleet`` (a
        :class:`~gridsim.traffic.fleet.Fleet`), without gathering their footprints first."""
        f = fleet
        near = self._near(ego_center, f.active, f.x, f.y, f.length, f.width)
        if len(near) or self._placed:
            self._place((f.x, f.y, f.psi, f.length, f.width), np.arange(f.capacity), near)
        return self._query(ego_center, ego_psi)

    def _near(self, ego_center, active, x, y, length, width) -> np.ndarray:
        """The broad phase: indices of the active boxes whose bounding circle touches the
        ego's."""
        cx, cy = ego_center[0], ego_center[1]
        return collision_kernels.within_reach(active, x, y, length, width, cx, cy,
                                              self._ego_radius)  # fmt: skip

    def _place(self, traffic, traffic_index, near) -> None:
        """Move the boxes ``near`` (indices into ``traffic``) into place, park the others."""
        x, y, psi, length, width = traffic
        placed = set()
        for j in near:
            index = int(traffic_index[j])
            body = self._shape_for(index, float(length[j]), float(width[j]))
            body.position = (float(x[j]), float(y[j]))
            body.angle = float(psi[j])
            self.space.reindex_shapes_for_body(body)
            placed.add(index)
        for index in self._placed - placed:
            body = self._shapes[index][0]
            body.position = _PARK
            self.space.reindex_shapes_for_body(body)
        self._placed = placed

    def _load_edges(self, near: np.ndarray) -> None:
        """Make the loaded edges ``near`` (indices into ``_edges``) static pymunk shapes, if
        not yet done: a query reports only shapes that touch the ego, and no edge farther
        than the core's reach can."""
        static, made = self.space.static_body, self._boundary_shapes
        new = []
        for j in near.tolist():
            if j not in made:
                x0, y0, x1, y1 = self._edges[j]
                made[j] = seg = pymunk.Segment(static, (x0, y0), (x1, y1), 0.0)
                seg.gridsim_index = int(self._edge_index[j])
                new.append(seg)
        if new:
            self.space.add(*new)

    def _query(self, ego_center, ego_psi) -> Contact:
        """The contacts of the ego box with what is placed and loaded."""
        placed = self._placed
        cx, cy = float(ego_center[0]), float(ego_center[1])
        near_edges = collision_kernels.near_segments(self._edges, cx, cy, self._core_reach)
        if not placed and not len(near_edges):
            return Contact()  # nothing loaded the ego could touch
        self._load_edges(near_edges)
        space = self.space
        self._ego_body.position = (cx, cy)
        self._ego_body.angle = float(ego_psi)
        space.reindex_shapes_for_body(self._ego_body)
        ego = self._ego_body
        vehicles = [  # none can touch unless the broad phase placed one
            hit.shape.body.gridsim_index
            for hit in (space.shape_query(self._ego_shape) if placed else ())
            if hit.shape.body.body_type == pymunk.Body.KINEMATIC and hit.shape.body is not ego
        ]
        edges = [  # none unless a loaded road edge comes near
            hit.shape.gridsim_index
            for hit in (space.shape_query(self._ego_core) if len(near_edges) else ())
            if hit.shape.body.body_type == pymunk.Body.STATIC
        ]
        return Contact(tuple(sorted(vehicles)), tuple(sorted(edges)))
