"""The seamless scenario: a never-ending multi-lane road generated on the fly from a seed.

The reference line is a chain of straight pieces and circular arcs. Arcs have a random sign,
an angle drawn uniformly in ``[0.5, 1.5] x mean_curve_angle`` and a radius drawn uniformly in
``curve_radius``; straights are long enough on average that ``straight_fraction`` of the road
length is straight. Signs are chosen to keep the heading within +-75 degrees of +x, so the road
never folds back onto itself. Only ``[s_ego - keep_behind, s_ego + keep_ahead]`` is held in
memory, whatever distance is driven; the road is a pure function of its parameters and seed.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import cv2
import numpy as np

from gridsim.road.base import Lane, Road, RoadTracking, bbox_of, near
from gridsim.road.polyline import Polyline
from gridsim.seeding import copy_generator

_MAX_HEADING = np.deg2rad(75.0)
_CHUNK = 24  # reference points per drivable polygon chunk
_WINDOW = 48  # segments searched either side of the last ego position


@dataclass(frozen=True)
class SeamlessParams:
    """Geometry of the seamless road (metres, degrees)."""

    lanes: int = 3
    lane_width: float = 3.5
    straight_fraction: float = 0.6
    mean_curve_angle_deg: float = 55.0
    curve_radius: tuple[float, float] = (60.0, 150.0)
    sample_spacing: float = 1.0
    keep_behind: float = 150.0
    keep_ahead: float = 400.0


class _PieceGenerator:
    """Draws the sequence of road pieces; yields reference points with exact headings."""

    def __init__(self, p: SeamlessParams, seed: int) -> None:
        self.p = p
        self.rng = np.random.default_rng(seed)
        mean_r = 0.5 * (p.curve_radius[0] + p.curve_radius[1])
        mean_arc = mean_r * np.deg2rad(p.mean_curve_angle_deg)
        f = p.straight_fraction
        self.mean_straight = mean_arc * f / (1.0 - f) if f < 1 else 1e9
        self.next_is_straight = True
        self.pos = np.zeros(2)
        self.heading = 0.0
        self.leftover = 0.0  # distance already travelled past the last emitted sample

    def __deepcopy__(self, memo) -> _PieceGenerator:
        """A copy with its own random stream (the position array is replaced, never
        modified in place; the parameters are frozen)."""
        new = copy.copy(self)
        memo[id(self)] = new
        new.rng = copy_generator(self.rng)
        return new

    def _straight(self, length: float):
        ds = self.p.sample_spacing
        t = np.arange(ds - self.leftover, length + 1e-9, ds)
        u = np.array([np.cos(self.heading), np.sin(self.heading)])
        pts = self.pos + t[:, None] * u
        hs = np.full(len(t), self.heading)
        self.pos = self.pos + length * u
        self.leftover = length - (t[-1] if len(t) else -self.leftover)
        return pts, hs

    def _arc(self, radius: float, angle: float):
        ds = self.p.sample_spacing
        length = radius * abs(angle)
        t = np.arange(ds - self.leftover, length + 1e-9, ds)
        sign = np.sign(angle)
        centre = self.pos + sign * radius * np.array([-np.sin(self.heading), np.cos(self.heading)])
        phi = self.heading + sign * t / radius
        pts = centre + sign * radius * np.stack([np.sin(phi), -np.cos(phi)], axis=1)
        self.heading += angle
        self.pos = centre + sign * radius * np.array([np.sin(self.heading), -np.cos(self.heading)])
        self.leftover = length - (t[-1] if len(t) else -self.leftover)
        return pts, phi

    def next_piece(self) -> tuple[np.ndarray, np.ndarray]:
        p, rng = self.p, self.rng
        if self.next_is_straight or p.straight_fraction >= 1:
            self.next_is_straight = False
            return self._straight(self.mean_straight * rng.uniform(0.5, 1.5))
        self.next_is_straight = True
        angle = np.deg2rad(p.mean_curve_angle_deg) * rng.uniform(0.5, 1.5)
        radius = rng.uniform(*p.curve_radius)
        ok = [sg for sg in (-1.0, 1.0) if abs(self.heading + sg * angle) <= _MAX_HEADING]
        if len(ok) == 2:
            sign = ok[int(rng.integers(2))]
        elif ok:
            sign = ok[0]
        else:
            sign = -np.sign(self.heading) or 1.0
            angle = min(angle, abs(self.heading))
        return self._arc(radius, sign * angle)


def _simplified_segments(edge: np.ndarray, tolerance: float = 0.02) -> np.ndarray:
    """Segments ``(M, 4)`` of an edge polyline, simplified (Douglas-Peucker) to ``tolerance`` m."""
    origin = edge[0]
    pts = cv2.approxPolyDP((edge - origin).astype(np.float32)[:, None, :], tolerance, False)
    pts = pts[:, 0, :].astype(np.float64) + origin
    return np.hstack([pts[:-1], pts[1:]])


class SeamlessRoad(Road):
    """A never-ending one-way road with ``lanes`` parallel lanes, generated around the ego.

    Lane ``i`` (0 = rightmost) has its centre at lateral offset ``(i - (lanes-1)/2) * lane_width``
    from the reference line. Lane arc lengths are absolute: trimming never shifts ``s``.
    The ego starts at the origin heading +x, on a straight run-in.
    """

    def __init__(self, params: SeamlessParams, seed: int = 0) -> None:
        min_r = params.curve_radius[0]
        half = 0.5 * params.lanes * params.lane_width
        if min_r <= half + 1.0:
            raise ValueError(
                f"curve_radius minimum {min_r} m must exceed the road half-width {half} m + 1 m"
            )
        self.p = params
        self._gen = _PieceGenerator(params, seed)
        n = params.lanes
        self._offsets = (np.arange(n) - 0.5 * (n - 1)) * params.lane_width
        # Run-in: a straight from -keep_behind to the origin.
        ds = params.sample_spacing
        xs = np.arange(-params.keep_behind, 0.0 + 1e-9, ds)
        self._ref = np.stack([xs, np.zeros_like(xs)], axis=1)
        self._ref_h = np.zeros(len(xs))
        self._ref_s = xs.copy()
        self._lane_pts = self._offset_points(self._ref, self._ref_h)
        self._lane_s = np.repeat(xs[None, :], n, axis=0)
        self._ego_s = 0.0
        self._hint = None
        # Extend and trim in chunks of a quarter of the kept length (at least 100 m), so that
        # geometry (and everything derived from it) is rebuilt only every so often.
        self._chunk = max(100.0, 0.25 * (params.keep_behind + params.keep_ahead))
        self._extend_to(params.keep_ahead)
        self._rebuild()

    def __deepcopy__(self, memo) -> SeamlessRoad:
        """A copy with its own piece generator (and random stream) that shares the geometry:
        arrays and lists here are replaced when the road is extended or trimmed, never
        modified in place."""
        new = copy.copy(self)
        memo[id(self)] = new
        new._gen = copy.deepcopy(self._gen, memo)
        return new

    # -- generation -------------------------------------------------------------------------
    def _offset_points(self, pts: np.ndarray, hs: np.ndarray) -> np.ndarray:
        normal = np.stack([-np.sin(hs), np.cos(hs)], axis=1)
        return pts[None] + self._offsets[:, None, None] * normal[None]

    def _extend_to(self, s_target: float) -> None:
        new_pts, new_h = [], []
        s_end = self._ref_s[-1]
        while s_end < s_target:
            pts, hs = self._gen.next_piece()
            if len(pts):
                new_pts.append(pts)
                new_h.append(hs)
                s_end += len(pts) * self.p.sample_spacing
        if not new_pts:
            return
        pts, hs = np.vstack(new_pts), np.concatenate(new_h)
        lane_new = self._offset_points(pts, hs)
        ref_all = np.vstack([self._ref[-1:], pts])
        ref_s_new = self._ref_s[-1] + np.cumsum(np.hypot(*np.diff(ref_all, axis=0).T))
        lane_all = np.concatenate([self._lane_pts[:, -1:], lane_new], axis=1)
        seg = np.linalg.norm(np.diff(lane_all, axis=1), axis=2)
        lane_s_new = self._lane_s[:, -1:] + np.cumsum(seg, axis=1)
        self._ref = np.vstack([self._ref, pts])
        self._ref_h = np.concatenate([self._ref_h, hs])
        self._ref_s = np.concatenate([self._ref_s, ref_s_new])
        self._lane_pts = np.concatenate([self._lane_pts, lane_new], axis=1)
        self._lane_s = np.concatenate([self._lane_s, lane_s_new], axis=1)

    def _rebuild(self) -> None:
        self._ref_line = Polyline(self._ref, self._ref_s[0])
        self._lanes = []
        for i in range(self.p.lanes):
            centre = Polyline(self._lane_pts[i], self._lane_s[i, 0])
            self._lanes.append(Lane(centre, self.p.lane_width))
        # The polygons, edges and markings are derived on first use (a shadow world uses
        # none of them), into a dict that copies sharing this geometry share too.
        self._derived: dict[str, object] = {}
        self.version += 1

    def _derive(self, name: str):
        """The derived geometry ``name`` (made with all the others of its kind on first use)."""
        d = self._derived
        if name not in d:
            half = 0.5 * self.p.lanes * self.p.lane_width
            normal = np.stack([-np.sin(self._ref_h), np.cos(self._ref_h)], axis=1)
            starts = np.arange(0, len(self._ref) - 1, _CHUNK)
            if name in ("chunks", "segments"):
                left, right = self._ref + half * normal, self._ref - half * normal
                chunks = [np.vstack([left[a : a + _CHUNK + 1], right[a : a + _CHUNK + 1][::-1]])
                          for a in starts]  # fmt: skip
                d["chunks"] = chunks, bbox_of(chunks)
                d["segments"] = np.vstack([_simplified_segments(e) for e in (left, right)])
            else:
                width = self.p.lane_width
                marks = [self._ref + (o + 0.5 * width) * normal for o in self._offsets[:-1]]
                chunks = [mk[a : a + _CHUNK + 1] for mk in marks for a in starts]
                d["markings"] = chunks, bbox_of(chunks)
        return d[name]

    def update(self, ego_xy: np.ndarray) -> None:
        x, y = float(ego_xy[0]), float(ego_xy[1])
        if self._hint is None:
            s, _, seg = self._project(np.array([[x, y]]))
            self._ego_s, self._hint = float(s[0]), int(seg[0])
        else:
            self._ego_s, _, self._hint = self._ref_line.track(x, y, self._hint)
        p = self.p
        changed = False
        if self._ref_s[-1] < self._ego_s + p.keep_ahead:
            self._extend_to(self._ego_s + p.keep_ahead + self._chunk)
            changed = True
        cut = self._ref_s.searchsorted(self._ego_s - p.keep_behind)
        if cut > self._chunk / p.sample_spacing:
            self._ref, self._ref_h, self._ref_s = (
                self._ref[cut:],
                self._ref_h[cut:],
                self._ref_s[cut:],
            )
            self._lane_pts, self._lane_s = self._lane_pts[:, cut:], self._lane_s[:, cut:]
            self._hint = max(0, self._hint - int(cut))
            changed = True
        if changed:
            self._rebuild()

    def tracking(self) -> RoadTracking | None:
        """What a compiled tick needs to follow the ego as :meth:`update` does, while the road
        stays as it is: ``(reference line's tracking_data, reference arc lengths, segment
        tracked, keep_ahead, keep_behind, trim threshold [samples])``; None before the first
        :meth:`update`. See :meth:`set_tracked`."""
        if self._hint is None:
            return None
        p = self.p
        return RoadTracking(
            self._ref_line.tracking_data(),
            self._ref_s,
            self._hint,
            p.keep_ahead,
            p.keep_behind,
            self._chunk / p.sample_spacing,
        )

    def set_tracked(self, ego_s: float, hint: int) -> None:
        """The ego's arc length [m] and segment as :meth:`update` would have tracked them
        (for a compiled tick that found the road needs neither extending nor trimming)."""
        self._ego_s, self._hint = ego_s, hint

    # -- queries ----------------------------------------------------------------------------
    @property
    def lanes(self) -> list[Lane]:
        return self._lanes

    @property
    def reference_line(self) -> Polyline:
        """The road's centre line (currently generated stretch)."""
        return self._ref_line

    @property
    def lane_offsets(self) -> np.ndarray:
        """Lateral offsets [m] of the lane centres from the reference line (0 = rightmost)."""
        return self._offsets

    @property
    def half_width(self) -> float:
        return 0.5 * self.p.lanes * self.p.lane_width

    @property
    def memory_points(self) -> int:
        """Number of reference points held (bounded whatever the distance driven)."""
        return len(self._ref)

    def drivable_polygons(self, center, radius):
        chunks, boxes = self._derive("chunks")
        return [chunks[i] for i in near(boxes, center, radius)]

    def boundary_segments(self):
        return self._derive("segments")

    def lane_markings(self, center, radius):
        chunks, boxes = self._derive("markings")
        return [chunks[i] for i in near(boxes, center, radius)]

    def _project(self, xy: np.ndarray):
        """Project onto the reference line, searching near the ego first."""
        if self._hint is not None:
            s, d, seg = self._ref_line.project(xy, hint=self._hint, window=_WINDOW)
            lo, hi = self._hint - _WINDOW, self._hint + _WINDOW - 1
            if np.all((seg > lo) & (seg < hi)):
                return s, d, seg
        return self._ref_line.project(xy)

    def lane_s_near_ego(self, lane: int) -> float:
        """Arc length [m] along lane ``lane`` abreast of the ego's last projected position."""
        i = min(max(int(np.searchsorted(self._ref_s, self._ego_s)), 1), len(self._ref_s) - 1)
        t = (self._ego_s - self._ref_s[i - 1]) / (self._ref_s[i] - self._ref_s[i - 1])
        return float(
            self._lane_s[lane, i - 1] + t * (self._lane_s[lane, i] - self._lane_s[lane, i - 1])
        )

    def is_drivable(self, xy):
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        s, d, _ = self._project(xy)
        inside_s = (s >= self._ref_s[0] - 1e-6) & (s <= self._ref_s[-1] + 1e-6)
        return inside_s & (np.abs(d) <= self.half_width)
