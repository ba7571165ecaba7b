"""One recorded vehicle trajectory (:class:`Track`), as libraries and scenes hold them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter


@dataclass(frozen=True, eq=False)
class Track:
    """One recorded vehicle: arrays of equal length sampled at increasing ``t`` [s].

    Compared and hashed by identity (tracks are loaded once per library)."""

    scenario_id: str
    track_id: str
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    length: float
    width: float
    #: Where the track was read from (a file path), for messages.
    source: str = ""

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def lateral_offset(self) -> np.ndarray:
        """Human lateral wander [m]: signed offset of each position from a smooth fit.

        A polynomial in time (degree 1 to 3 by track length) stands for the lane the driver
        follows; the residual perpendicular to the fit's direction, positive to the left, is
        the offset replayed on synthetic roads.
        """
        n = len(self.t)
        if n < 5:
            return np.zeros(n)
        deg = 1 if n < 15 else (2 if n < 40 else 3)
        tt = self.t - self.t[0]
        fx = np.polynomial.Polynomial.fit(tt, self.x, deg)
        fy = np.polynomial.Polynomial.fit(tt, self.y, deg)
        dx, dy = fx.deriv()(tt), fy.deriv()(tt)
        norm = np.hypot(dx, dy)
        norm[norm < 1e-6] = 1.0
        rx, ry = self.x - fx(tt), self.y - fy(tt)
        return (dx * ry - dy * rx) / norm

    def smoothed_speed(self) -> np.ndarray:
        """Speed [m/s] smoothed with a Savitzky-Golay filter (recorded speeds are noisy)."""
        n = len(self.speed)
        win = min(11, n if n % 2 else n - 1)
        if win < 5:
            return self.speed.copy()
        return np.maximum(savgol_filter(self.speed, win, 2), 0.0)
