"""The inner-city scenario: a jittered grid of two-way streets with intersections.

Nodes sit on a ``blocks_x x blocks_y`` grid with spacing ``block_size`` [m], each displaced by
up to ``jitter`` [m], so streets meet at irregular angles. Streets carry ``lanes_per_direction``
lanes each way (right-hand traffic). Routes are random walks on the street graph (no U-turns)
with a fillet arc of ``turn_radius`` at every change of direction; ``turn_probability`` is the
chance of turning at an intersection when going straight is possible.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from gridsim import libm
from gridsim.road.base import Lane, StaticRoad
from gridsim.road.polyline import Polyline


@dataclass(frozen=True)
class CityParams:
    """Geometry of the inner-city network (metres)."""

    blocks_x: int = 6
    blocks_y: int = 6
    block_size: float = 45.0
    jitter: float = 6.0
    lanes_per_direction: int = 1
    lane_width: float = 3.5
    turn_radius: float = 18.0
    turn_probability: float = 0.85
    sample_spacing: float = 1.0


def _fillet_path(nodes: np.ndarray, offset: float, radius: float, ds: float) -> np.ndarray:
    """Polyline through ``nodes`` shifted ``offset`` to the right, corners rounded by arcs."""
    seg = np.diff(nodes, axis=0)
    u = seg / np.linalg.norm(seg, axis=1, keepdims=True)
    right = np.stack([u[:, 1], -u[:, 0]], axis=1)
    starts = nodes[:-1] + offset * right
    ends = nodes[1:] + offset * right
    out = [starts[0][None]]
    cursor = starts[0]
    for k in range(len(u) - 1):
        u1, u2 = u[k], u[k + 1]
        cross = u1[0] * u2[1] - u1[1] * u2[0]
        turn = libm.arctan2(cross, float(u1 @ u2))
        # Corner: intersection of the two offset lines.
        denom = 1.0 + float(right[k] @ right[k + 1])
        corner = nodes[k + 1] + offset * (right[k] + right[k + 1]) / max(denom, 1e-6)
        if abs(turn) < 1e-3:
            continue
        t = radius * libm.tan(abs(turn) / 2)
        room = 0.45 * min(np.linalg.norm(corner - cursor), np.linalg.norm(ends[k + 1] - corner))
        r = radius if t <= room else room / libm.tan(abs(turn) / 2)
        t = r * libm.tan(abs(turn) / 2)
        a = corner - u1 * t
        sign = np.sign(turn)
        centre = a + sign * r * np.array([-u1[1], u1[0]])
        h0 = libm.arctan2(u1[1], u1[0])
        n = max(2, int(np.ceil(r * abs(turn) / ds)) + 1)
        phi = h0 + np.linspace(0.0, turn, n)
        arc = centre + sign * r * np.stack([np.sin(phi), -np.cos(phi)], axis=1)
        out.append(arc)
        cursor = arc[-1]
    out.append(ends[-1][None])
    pts = np.vstack(out)
    # Resample straight parts densely enough for lookups and rendering.
    line = Polyline(pts)
    s = np.arange(0.0, line.length, ds)
    dense, _ = line.point_at(np.append(s, line.length))
    return dense


class CityRoad(StaticRoad):
    """A street network built from :class:`CityParams` and a seed."""

    def __init__(self, params: CityParams, seed: int = 0) -> None:
        p = params
        rng = np.random.default_rng(seed)
        gx, gy = np.meshgrid(np.arange(p.blocks_x + 1), np.arange(p.blocks_y + 1), indexing="ij")
        base = np.stack([gx, gy], axis=-1).reshape(-1, 2) * p.block_size
        self.nodes = base + rng.uniform(-p.jitter, p.jitter, base.shape)
        self.params = p
        nx, ny = p.blocks_x + 1, p.blocks_y + 1
        idx = np.arange(nx * ny).reshape(nx, ny)
        edges = [(idx[i, j], idx[i + 1, j]) for i in range(nx - 1) for j in range(ny)]
        edges += [(idx[i, j], idx[i, j + 1]) for i in range(nx) for j in range(ny - 1)]
        self.edges = np.array(edges)
        self.neighbours: list[list[int]] = [[] for _ in range(len(self.nodes))]
        for a, b in edges:
            self.neighbours[a].append(int(b))
            self.neighbours[b].append(int(a))

        half = p.lanes_per_direction * p.lane_width
        polygons, markings, lanes = [], [], []
        for a, b in self.edges:
            pa, pb = self.nodes[a], self.nodes[b]
            u = (pb - pa) / np.linalg.norm(pb - pa)
            n = np.array([-u[1], u[0]])
            polygons.append(np.array([pa - half * n, pb - half * n, pb + half * n, pa + half * n]))
            inset = half + 1.0
            markings.append(np.array([pa + inset * u, pb - inset * u]))  # the centre line
            for k in range(1, p.lanes_per_direction):  # between lanes of one direction
                for side in (-k * p.lane_width * n, k * p.lane_width * n):
                    markings.append(np.array([pa + inset * u + side, pb - inset * u + side]))
            for k in range(p.lanes_per_direction):
                off = (k + 0.5) * p.lane_width
                lanes.append(Lane(Polyline(np.array([pa - off * n, pb - off * n])), p.lane_width))
                lanes.append(Lane(Polyline(np.array([pb + off * n, pa + off * n])), p.lane_width))
        # Intersections: convex hull of the street corners around each node, plus a margin
        # that leaves room for turning arcs.
        for v, nb in enumerate(self.neighbours):
            pts = []
            for w in nb:
                u = self.nodes[w] - self.nodes[v]
                u /= np.linalg.norm(u)
                n = np.array([-u[1], u[0]])
                reach = half + p.turn_radius
                c = self.nodes[v] + reach * u
                pts += [
                    c + half * n,
                    c - half * n,
                    self.nodes[v] + half * n,
                    self.nodes[v] - half * n,
                ]
            hull = cv2.convexHull(np.array(pts, dtype=np.float32))[:, 0, :].astype(np.float64)
            polygons.append(hull)
        super().__init__(lanes, polygons, markings)

    def random_route(
        self, rng: np.random.Generator, length: float, start_node: int | None = None, lane: int = 0
    ) -> Polyline:
        """A route of at least ``length`` metres along the streets, in lane ``lane`` (0 = the
        rightmost lane of its direction), as a polyline with arc length."""
        p = self.params
        if start_node is None:
            start_node = int(rng.integers(len(self.nodes)))
        prev, cur = -1, start_node
        path = [cur]
        offset = (lane + 0.5) * p.lane_width
        target = length + 2 * p.block_size
        while True:
            travelled = 0.0
            while travelled < target:
                options = [w for w in self.neighbours[cur] if w != prev]
                straight = self._straightest(prev, cur, options)
                if straight is not None and (
                    len(options) == 1 or rng.random() >= p.turn_probability
                ):
                    nxt = straight
                else:
                    turns = [w for w in options if w != straight] or options
                    nxt = turns[int(rng.integers(len(turns)))]
                travelled += float(np.linalg.norm(self.nodes[nxt] - self.nodes[cur]))
                prev, cur = cur, nxt
                path.append(cur)
            route = Polyline(
                _fillet_path(self.nodes[path], offset, p.turn_radius, p.sample_spacing)
            )
            if route.length >= length:  # fillets shorten the node path; extend if needed
                return route
            target = length - route.length + p.block_size

    def _straightest(self, prev: int, cur: int, options: list[int]) -> int | None:
        """The option that continues most nearly straight (within 30 degrees), if any."""
        if prev < 0:
            return None
        u = self.nodes[cur] - self.nodes[prev]
        best, best_cos = None, np.cos(np.deg2rad(30))
        for w in options:
            v = self.nodes[w] - self.nodes[cur]
            c = float(u @ v) / (np.linalg.norm(u) * np.linalg.norm(v))
            if c > best_cos:
                best, best_cos = w, c
        return best


def route_statistics(route: Polyline, min_curve_deg: float = 5.0) -> tuple[float, float]:
    """Fraction of length that is straight, and mean absolute angle [deg] of its curves.

    A curve is a maximal run of consecutive segments that turn; runs turning less than
    ``min_curve_deg`` in total count as straight.
    """
    h = np.unwrap(libm.arctan2(*np.diff(route.points, axis=0)[:, ::-1].T))
    seg_len = np.diff(route.s)
    dh = np.diff(h)
    turning = np.abs(dh) > 1e-4
    curve_len, angles = 0.0, []
    k = 0
    while k < len(dh):
        if not turning[k]:
            k += 1
            continue
        j = k
        while j < len(dh) and turning[j]:
            j += 1
        ang = abs(h[j] - h[k])
        if np.rad2deg(ang) >= min_curve_deg:
            angles.append(np.rad2deg(ang))
            curve_len += float(seg_len[k + 1 : j + 1].sum())
        k = j
    total = float(seg_len.sum())
    return 1.0 - curve_len / total, float(np.mean(angles)) if angles else 0.0
