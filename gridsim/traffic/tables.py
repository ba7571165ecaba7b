"""Many piecewise-linear tables in flat arrays, evaluated for many (table, x) pairs at once.

Used for recorded profiles (functions of time) and for vehicle paths (points as functions of
arc length): one ``searchsorted`` locates every query, whatever the number of tables.
"""

from __future__ import annotations

import numpy as np

_GAP = 1.0  # separation of tables on the shared key axis


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
        self._dirty = True

    def __len__(self) -> int:
        return len(self._x)

    def add(self, x: np.ndarray, y: np.ndarray) -> int:
        """Store a table; returns its slot id."""
        slot = self._free.pop() if self._free else len(self._x)
        if slot == len(self._x):
            self._x.append(None)
            self._y.append(None)
        self.set(slot, x, y)
        return slot

    def set(self, slot: int, x: np.ndarray, y: np.ndarray) -> None:
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64).reshape(len(x), self.width)
        if len(x) < 2 or np.any(np.diff(x) <= 0):
            raise ValueError("a table needs >= 2 strictly increasing knots")
        self._x[slot], self._y[slot] = x, y
        self._dirty = True

    def remove(self, slot: int) -> None:
        self._x[slot] = self._y[slot] = None
        self._free.append(slot)
        self._dirty = True

    def x_range(self, slot: int) -> tuple[float, float]:
        x = self._x[slot]
        return float(x[0]), float(x[-1])

    def _rebuild(self) -> None:
        keys, ys, first, last, base = [], [], [], [], []
        offset, n = 0.0, 0
        for x, y in zip(self._x, self._y, strict=True):
            if x is None:
                x, y = np.array([0.0, 1.0]), np.zeros((2, self.width))
            b = offset - x[0]
            keys.append(x + b)
            ys.append(y)
            base.append(b)
            first.append(n)
            last.append(n + len(x) - 2)
            n += len(x)
            offset = x[-1] + b + _GAP
        self._keys = np.concatenate(keys) if keys else np.zeros(0)
        self._ys = np.vstack(ys) if ys else np.zeros((0, self.width))
        self._base = np.array(base)
        self._first = np.array(first, dtype=np.int64)
        self._last = np.array(last, dtype=np.int64)
        self._lo = np.array([x[0] if x is not None else 0.0 for x in self._x])
        self._hi = np.array([x[-1] if x is not None else 1.0 for x in self._x])
        self._dirty = False

    def ranges(self, slots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last knot ``x`` of each table in ``slots``."""
        if self._dirty:
            self._rebuild()
        return self._lo[slots], self._hi[slots]

    def lookup(self, slots: np.ndarray, x: np.ndarray, clamp: bool = True):
        """Values ``(N, width)`` and slopes ``dy/dx`` at ``x`` in tables ``slots``.

        With ``clamp`` the argument is clamped to each table's range; otherwise the end
        segments are extended linearly.
        """
        if self._dirty:
            self._rebuild()
        slots = np.asarray(slots, dtype=np.int64)
        x = np.asarray(x, dtype=np.float64)
        if clamp:
            x = np.clip(x, self._lo[slots], self._hi[slots])
        k = x + self._base[slots]
        i = np.searchsorted(self._keys, k, side="right") - 1
        i = np.clip(i, self._first[slots], self._last[slots])
        x0, x1 = self._keys[i], self._keys[i + 1]
        slope = (self._ys[i + 1] - self._ys[i]) / (x1 - x0)[:, None]
        return self._ys[i] + (k - x0)[:, None] * slope, slope


class PathBank(TableBank):
    """Vehicle paths: polylines parameterised by arc length ``s`` [m]."""

    def __init__(self) -> None:
        super().__init__(width=2)

    def add_path(self, points: np.ndarray, s: np.ndarray) -> int:
        return self.add(s, points)

    def frenet_to_world(self, slots, s, d):
        """World points ``(N, 2)`` and path headings [rad] at ``(s, d)`` on paths ``slots``
        (extrapolated straight beyond the path ends)."""
        p, slope = self.lookup(slots, s, clamp=False)
        h = np.arctan2(slope[:, 1], slope[:, 0])
        d = np.asarray(d, dtype=np.float64)
        return p + d[:, None] * np.stack([-np.sin(h), np.cos(h)], axis=1), h
