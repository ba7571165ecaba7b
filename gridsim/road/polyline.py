"""Polylines with arc length: point/heading at s, projection to (s, d), offsets.

All coordinates are metres in the world frame; ``d`` is the signed lateral offset, positive to
the left of the direction of travel.
"""

from __future__ import annotations

import numpy as np

from gridsim import libm
from gridsim.road import polyline_kernels as kernels


class Polyline:
    """A piecewise-linear curve through ``points`` ``(M, 2)`` with cumulative arc length ``s``.

    ``s`` starts at ``s_start`` so that a curve trimmed at its back keeps its coordinates.
    Immutable (its arrays are read-only), so copies of a world share it.
    """

    __slots__ = ("points", "s", "_seg", "_seg_len", "_seg_len_pow2", "_heading")

    def __init__(self, points: np.ndarray, s_start: float = 0.0) -> None:
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError(f"a polyline needs at least 2 points of shape (M, 2), got {pts.shape}")
        if not np.isfinite(pts).all():
            raise ValueError("polyline points must be finite")
        self._set(kernels.segments(np.ascontiguousarray(pts), float(s_start)))

    @classmethod
    def from_segments(cls, arrays: tuple[np.ndarray, ...]) -> Polyline:
        """The polyline of :func:`~gridsim.road.polyline_kernels.segments`' arrays (computed
        from finite points, e.g. by another kernel), without checking the points again."""
        line = cls.__new__(cls)
        line._set(arrays)
        return line

    def _set(self, arrays: tuple[np.ndarray, ...]) -> None:
        self.points, self._seg, self._seg_len, self._heading, self.s = arrays
        if len(self.points) < 2:
            raise ValueError("a polyline needs at least 2 distinct points")
        self._seg_len_pow2 = np.float_power(self._seg_len, 2.0)  # libm's pow (see track)
        for a in (self.points, self._seg, self._seg_len, self._seg_len_pow2, self._heading, self.s):
            a.flags.writeable = False  # immutable: copies of a world share it

    def __deepcopy__(self, memo) -> Polyline:
        return self

    @property
    def length(self) -> float:
        """Arc length [m] from the first to the last point."""
        return float(self.s[-1] - self.s[0])

    def _segment_index(self, s: np.ndarray) -> np.ndarray:
        idx = np.searchsorted(self.s, s, side="right") - 1
        return np.clip(idx, 0, len(self._seg) - 1)

    def point_at(self, s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """World points ``(..., 2)`` and headings [rad] at arc length ``s`` (extrapolated linearly
        beyond the ends)."""
        s = np.asarray(s, dtype=np.float64)
        i = self._segment_index(s)
        t = (s - self.s[i]) / self._seg_len[i]
        p = self.points[i] + t[..., None] * self._seg[i]
        return p, self._heading[i]

    def kernel_data(self) -> tuple[np.ndarray, ...]:
        """``(points, segments, segment lengths, cumulative arc length)`` for compiled code
        (:mod:`gridsim.road.polyline_kernels`)."""
        return self.points, self._seg, self._seg_len, self.s

    def tracking_data(self) -> tuple[np.ndarray, ...]:
        """:meth:`kernel_data` with the squared segment lengths (libm's ``pow``) after the
        segment lengths and the segment headings at the end: what
        :func:`~gridsim.world.scripted_driver_kernels.route_inputs` reads."""
        return self.points, self._seg, self._seg_len, self._seg_len_pow2, self.s, self._heading

    def frenet_one(self, s: float, d: float) -> tuple[float, float, float]:
        """:meth:`frenet_to_world` of one point: ``(x, y, heading)`` as floats."""
        return kernels.frenet_one(self.points, self._seg, self._seg_len, self.s, self._heading,
                                  float(s), float(d))  # fmt: skip

    def ahead_of(self, x: float, y: float, ahead: float, d: float) -> tuple[float, float, float]:
        """:meth:`frenet_one` at ``ahead`` [m] past the projection (:meth:`project`) of the
        point ``(x, y)`` [m], lateral offset ``d`` [m]."""
        return kernels.ahead_of(self.points, self._seg, self._seg_len, self.s, self._heading,
                                float(x), float(y), float(ahead), float(d))  # fmt: skip

    def frenet_to_world(self, s, d) -> tuple[np.ndarray, np.ndarray]:
        """World points and path headings for lane coordinates ``(s, d)``."""
        p, h = self.point_at(s)
        d = np.asarray(d, dtype=np.float64)
        normal = np.stack([-np.sin(h), np.cos(h)], axis=-1)
        return p + d[..., None] * normal, h

    def project(self, xy: np.ndarray, hint: int | None = None, window: int = 64):
        """Nearest point on the curve for each of ``xy`` ``(N, 2)``.

        Returns ``(s, d, segment_index)``; ``d`` is positive to the left. ``hint`` limits the
        search to ``window`` segments around a previous segment index (fast tracking).
        """
        xy = np.ascontiguousarray(np.atleast_2d(np.asarray(xy, dtype=np.float64)))
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise ValueError(f"points to project must have shape (N, 2), got {xy.shape}")
        lo, hi = 0, len(self._seg)
        if hint is not None:
            if window < 1:
                raise ValueError(f"window must be >= 1 segment, got {window}")
            hint = min(max(int(hint), 0), hi - 1)
            lo, hi = max(0, hint - window), min(hi, hint + window)
        n = len(xy)
        s, d, seg = np.empty(n), np.empty(n), np.empty(n, np.int64)
        kernels.project(self.points, self._seg, self._seg_len, self.s, xy, lo, hi, s, d, seg)
        return s, d, seg

    def track(self, x: float, y: float, hint: int) -> tuple[float, float, int]:
        """Project one point, walking from segment ``hint`` to the nearest local segment.

        For following a moving point (a few segments per call): much cheaper than
        :meth:`project`, and the same result while the point stays within a few metres of
        the curve. Returns ``(s, d, segment_index)``.
        """
        s, d, j = kernels.track(self.points, self._seg, self._seg_len, self._seg_len_pow2, self.s,
                                float(x), float(y), int(hint))  # fmt: skip
        return float(s), float(d), int(j)

    def offset(self, d: float) -> np.ndarray:
        """Points of the curve offset by ``d`` to the left (vertex normals averaged)."""
        h = self._heading
        hv = np.concatenate([[h[0]], libm.angle(np.exp(1j * h[:-1]) + np.exp(1j * h[1:])), [h[-1]]])
        half_turn = np.concatenate([[0.0], 0.5 * libm.angle(np.exp(1j * (h[1:] - h[:-1]))), [0.0]])
        scale = 1.0 / np.maximum(np.cos(half_turn), 0.2)
        normal = np.stack([-np.sin(hv), np.cos(hv)], axis=-1)
        return self.points + (d * scale)[:, None] * normal
