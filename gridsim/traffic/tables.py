"""Many piecewise-linear tables in flat arrays, evaluated for many (table, x) pairs at once.

Used for recorded profiles (functions of time) and for vehicle paths (points as functions of
arc length): one ``searchsorted`` locates every query, whatever the number of tables.
"""

from __future__ import annotations

import copy

import numpy as np

from gridsim import libm
from gridsim.traffic import table_kernels

_GAP = 1.0  # separation of tables on the shared key axis


def checked_table(x: np.ndarray, y: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """A table's knots ``x`` and values ``y`` as :class:`TableBank` stores them (float64, ``y``
    of shape ``(len(x), width)``); a ValueError unless ``x`` has >= 2 strictly increasing
    knots."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64).reshape(len(x), width)
    if len(x) < 2 or np.any(np.diff(x) <= 0):
        raise ValueError("a table needs >= 2 strictly increasing knots")
    return x, y


class TableBank:
    """Tables ``x_k -> y_k`` (``y`` of width ``width``) stored back to back.

    Tables are addressed by slot; :meth:`set` replaces one, and the flat arrays are rebuilt
    lazily on the next lookup. ``x`` must be strictly increasing within a table.
    """

    def __init__(self, width: int) -> None:
        self.width = width
        self._x: list[np.ndarray | None] = []
        self._y: list[np.ndarray | None] = []
        self._free: list[int] = []
        self._dirty, self._size = True, None

    def __len__(self) -> int:
        return len(self._x)

    def __deepcopy__(self, memo) -> TableBank:
        """A copy with its own lists of tables that shares the arrays: tables are replaced,
        never modified in place, and the flat arrays are rebuilt, not updated."""
        new = copy.copy(self)
        memo[id(self)] = new
        for name, value in vars(self).items():
            if isinstance(value, list):
                setattr(new, name, list(value))
        return new

    def add(self, x: np.ndarray, y: np.ndarray) -> int:
        """Store a table; returns its slot id."""
        slot = self._free.pop() if self._free else len(self._x)
        if slot == len(self._x):
            self._x.append(None)
            self._y.append(None)
        self.set(slot, x, y)
        return slot

    def set(self, slot: int, x: np.ndarray, y: np.ndarray) -> None:
        self._x[slot], self._y[slot] = checked_table(x, y, self.width)
        self._dirty, self._size = True, None

    def extend(self, tables: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """Append tables already checked (:func:`checked_table` of this width), in order
        (their slots follow on; arrays shared, as :meth:`add` keeps them): a scene of thousands
        of tracks is added at once."""
        if not tables:
            return
        if self._free:
            raise ValueError("extend appends to a bank without free slots")
        self._x.extend(x for x, _ in tables)
        self._y.extend(y for _, y in tables)
        self._dirty, self._size = True, None

    def remove(self, slot: int) -> None:
        self._x[slot] = self._y[slot] = None
        self._free.append(slot)
        self._dirty, self._size = True, None

    @property
    def nbytes(self) -> int:
        """The memory [bytes] of the tables and of the arrays derived from them (counted
        once until they change: a scene's bank holds thousands of tables)."""
        if self._size is None:
            total = 0
            for value in vars(self).values():
                if isinstance(value, np.ndarray):
                    total += value.nbytes
                elif isinstance(value, list):
                    total += sum(a.nbytes for a in value if isinstance(a, np.ndarray))
            self._size = total
        return self._size

    def x_range(self, slot: int) -> tuple[float, float]:
        x = self._x[slot]
        return float(x[0]), float(x[-1])

    def _rebuild(self) -> None:
        # An empty bank gets a placeholder table, so that the kernels always get arrays
        # (a fleet hands them over even when no participant is active); so does a freed slot.
        empty = (np.array([0.0, 1.0]), np.zeros((2, self.width)))
        tables = list(zip(self._x, self._y, strict=True)) if self._x else [(None, None)]
        tables = [empty if x is None else (x, y) for x, y in tables]
        lengths = np.array([len(x) for x, _ in tables], dtype=np.int64)
        xs = np.concatenate([x for x, _ in tables])
        self._ys = np.concatenate([y for _, y in tables])
        self._keys, self._slope = np.empty_like(xs), np.empty_like(self._ys)
        self._base = np.empty(len(tables))
        self._first, self._last = (np.empty(len(tables), np.int64) for _ in range(2))
        table_kernels.flat_tables(xs, lengths, self._ys, _GAP, self._keys, self._slope,
                                  self._base, self._first, self._last)  # fmt: skip
        self._lo = np.array([x[0] if x is not None else 0.0 for x in self._x])
        self._hi = np.array([x[-1] if x is not None else 1.0 for x in self._x])
        self._build_buckets()
        self._bank = (self._keys, self._base, self._first, self._last, self._lo, self._hi,
                      self._bucket_count, self._bucket_width)  # fmt: skip
        self._dirty, self._size = False, None
        self._on_rebuild()

    def _build_buckets(self) -> None:
        """Index the key axis in buckets narrower than most segments, so that a lookup is
        one bucket read and one comparison instead of a binary search (which costs ~80 ns a
        query on unsorted queries, more than everything else in a lookup)."""
        keys = self._keys
        step = np.diff(keys)
        width = float(np.percentile(step, 5)) if len(step) else 1.0
        span = float(keys[-1] - keys[0]) if len(keys) else 1.0
        self._bucket_width = max(width, span / 2_000_000, 1e-9)
        edges = keys[0] + self._bucket_width * np.arange(int(span / self._bucket_width) + 3)
        # _bucket_count[b] = number of keys <= the lower edge of bucket b.
        self._bucket_count = np.empty(len(edges), np.int64)
        table_kernels.counts_up_to(keys, edges, self._bucket_count)

    def _on_rebuild(self) -> None:
        """Hook for subclasses that derive per-segment data."""

    def ranges(self, slots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last knot ``x`` of each table in ``slots``."""
        if self._dirty:
            self._rebuild()
        return self._lo[slots], self._hi[slots]

    def kernel_data(self) -> tuple:
        """The flat arrays that :func:`~gridsim.traffic.table_kernels.lookup` reads: the
        bank's index, the knot values and the slopes."""
        if self._dirty:
            self._rebuild()
        return self._bank, self._ys, self._slope

    def _queries(self, slots, x) -> tuple[tuple, np.ndarray, np.ndarray, bool]:
        """The bank's flat arrays for the kernels, queries as 1-D arrays, and whether to
        locate them through the bucket index."""
        if self._dirty:
            self._rebuild()
        slots = np.asarray(slots, dtype=np.int64)
        x = np.asarray(x, dtype=np.float64)
        if slots.shape != x.shape or slots.ndim != 1:
            slots, x = (np.ascontiguousarray(a).ravel() for a in np.broadcast_arrays(slots, x))
        return self._bank, slots, x, len(x) > table_kernels.SMALL_QUERY

    def lookup(self, slots: np.ndarray, x: np.ndarray, clamp: bool = True) -> np.ndarray:
        """Values ``(N, width)`` at ``x`` in tables ``slots``, interpolated linearly.

        With ``clamp`` the argument is clamped to each table's range; otherwise the end
        segments are extended linearly.
        """
        bank, slots, x, buckets = self._queries(slots, x)
        out = np.empty((len(x), self.width))
        table_kernels.lookup(bank, self._ys, self._slope, slots, x, clamp, buckets, out)
        return out


class PathBank(TableBank):
    """Vehicle paths: polylines parameterised by arc length ``s`` [m].

    Paths may belong to a *corridor*: parallel lanes of one road, whose vehicles keep their
    lane (their leader is the next vehicle on their own lane). Corridor ``-1`` means none.
    """

    def __init__(self) -> None:
        super().__init__(width=2)
        self._corridor: list[int] = []
        self._corridor_arr = np.zeros(0, np.int64)
        self._all_in_corridors = True
        self._corridors_stale = False  # paths added since the array was made

    def add_path(self, points: np.ndarray, s: np.ndarray, corridor: int = -1) -> int:
        slot = self.add(s, points)
        while len(self._corridor) <= slot:
            self._corridor.append(-1)
        self._corridor[slot] = corridor
        self._corridors_stale = True  # (made again when asked: a scene adds thousands)
        return slot

    def extend_paths(self, paths: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """Append paths of no corridor already checked (``(s, points)``:
        :func:`checked_table` of width 2), in order (see :meth:`TableBank.extend`)."""
        if paths:
            self.extend(paths)
            self._corridor.extend([-1] * len(paths))
            self._corridors_stale = True

    @property
    def all_in_corridors(self) -> bool:
        """Whether every path belongs to a corridor (no leaders to search on other paths)."""
        self.corridor_ids  # noqa: B018 - brought up to date
        return self._all_in_corridors

    def corridors(self, slots: np.ndarray) -> np.ndarray:
        """Corridor id of each path in ``slots`` (``-1`` for none)."""
        return self.corridor_ids[slots]

    @property
    def corridor_ids(self) -> np.ndarray:
        """Corridor id of every path slot (``-1`` for none), int64."""
        if self._corridors_stale:
            self._corridor_arr = np.array(self._corridor, dtype=np.int64)
            self._all_in_corridors = bool(self._corridor_arr.min() >= 0)
            self._corridors_stale = False
        return self._corridor_arr

    def _on_rebuild(self) -> None:
        self._heading = libm.arctan2(self._slope[:, 1], self._slope[:, 0])
        self._normal = np.stack([-np.sin(self._heading), np.cos(self._heading)], axis=1)

    def frenet_to_world(self, slots, s, d):
        """World points ``(N, 2)`` and path headings [rad] at ``(s, d)`` on paths ``slots``
        (extrapolated straight beyond the path ends)."""
        _, slots, s, buckets = self._queries(slots, s)
        d = np.broadcast_to(np.asarray(d, dtype=np.float64), s.shape)
        xy, h = np.empty((len(s), 2)), np.empty(len(s))
        table_kernels.frenet(self.kernel_data(), slots, s, d, buckets, xy, h)
        return xy, h

    def point(self, slot: int, s: float, d: float) -> tuple[float, float, float]:
        """:meth:`frenet_to_world` of one point: ``(x, y)`` [m] and the heading [rad]."""
        return table_kernels.frenet_one(self.kernel_data(), slot, s, d, False)

    def kernel_data(self) -> tuple:
        """The flat arrays that :func:`~gridsim.traffic.table_kernels.frenet_one` reads: the
        table's, then the segments' normals and headings."""
        return super().kernel_data() + (self._normal, self._heading)
