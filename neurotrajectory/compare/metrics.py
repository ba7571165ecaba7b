"""The paper's accuracy metrics for predicted set-points against human-driven ones.

Errors are taken in the **ego frame at prediction time**: ``e_x`` along the ego's heading
(longitudinal), ``e_y`` to its left (lateral), in metres. For ``N`` windows of ``tau_o``
set-points:

- ``mean_ex`` / ``max_ex``, ``mean_ey`` / ``max_ey``: mean and max of ``|e_x|``, ``|e_y|``
  over all windows and set-points;
- ``rmse``: the paper's ``sqrt(1/tau_o sum_t [(x^_t - x_t)^2 + (y^_t - y_t)^2])``, pooled
  over windows as a quadratic mean, ``sqrt(mean over windows and set-points of |e|^2)``;
- ``rmse_per_setpoint[k]``: ``sqrt(mean over windows of |e_k|^2)``; ``std_per_setpoint[k]``:
  the standard deviation over windows of ``|e_k|`` (the band of the paper's Fig. 8);
- ``ade``: mean of ``|e|`` over windows and set-points; ``fde``: mean of ``|e|`` at the last
  set-point;
- ``window_rmse``: each window's own RMSE ``(N,)`` (the box plots of the paper's Fig. 9).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SUMMARY_KEYS = ("mean_ex", "max_ex", "mean_ey", "max_ey", "rmse", "ade", "fde")


def ego_frame_errors(
    predicted: np.ndarray, target: np.ndarray, heading: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(e_x, e_y)``, each ``(N, T)`` [m]: ``predicted - target`` (``(N, T, 2)`` in the grid
    frame) rotated into the ego frame by the ego's ``heading`` ``(N,)`` [rad] in that frame."""
    predicted = np.asarray(predicted, float)
    target = np.asarray(target, float)
    if predicted.shape != target.shape or predicted.ndim != 3 or predicted.shape[2] != 2:
        raise ValueError(
            f"predicted and target must both be (N, T, 2), got {predicted.shape} and {target.shape}"
        )
    if not np.all(np.isfinite(predicted)):
        raise ValueError("predicted set-points contain NaN or infinite values")
    d = predicted - target
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    return c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]


@dataclass(frozen=True)
class Accuracy:
    """Accuracy of one method on one set of windows (see the module docstring)."""

    count: int
    mean_ex: float
    max_ex: float
    mean_ey: float
    max_ey: float
    rmse: float
    ade: float
    fde: float
    rmse_per_setpoint: tuple[float, ...]
    std_per_setpoint: tuple[float, ...]
    window_rmse: np.ndarray

    def summary(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in SUMMARY_KEYS}


def accuracy(predicted: np.ndarray, target: np.ndarray, heading: np.ndarray) -> Accuracy:
    """The metrics of ``predicted`` against ``target`` set-points (both ``(N, T, 2)``, grid
    frame [m]) for egos with ``heading`` ``(N,)`` [rad] in that frame."""
    ex, ey = ego_frame_errors(predicted, target, heading)
    if ex.size == 0:
        raise ValueError("no windows to evaluate")
    sq = ex**2 + ey**2
    dist = np.sqrt(sq)
    return Accuracy(
        count=int(ex.shape[0]),
        mean_ex=float(np.mean(np.abs(ex))),
        max_ex=float(np.max(np.abs(ex))),
        mean_ey=float(np.mean(np.abs(ey))),
        max_ey=float(np.max(np.abs(ey))),
        rmse=float(np.sqrt(np.mean(sq))),
        ade=float(np.mean(dist)),
        fde=float(np.mean(dist[:, -1])),
        rmse_per_setpoint=tuple(float(v) for v in np.sqrt(np.mean(sq, axis=0))),
        std_per_setpoint=tuple(float(v) for v in np.std(dist, axis=0)),
        window_rmse=np.sqrt(np.mean(sq, axis=1)),
    )
