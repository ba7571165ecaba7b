"""Intelligent Driver Model (Treiber et al. 2000), vectorised over vehicles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class IDMParams:
    """IDM parameters (SI units).

    ``a`` max acceleration [m/s^2], ``b`` comfortable deceleration [m/s^2], ``t_headway`` [s],
    ``s0`` jam distance [m], ``delta`` free-road exponent, ``b_emergency`` hardest braking
    [m/s^2] the model may command.
    """

    a: float = 1.5
    b: float = 2.0
    t_headway: float = 1.2
    s0: float = 2.0
    delta: float = 4.0
    b_emergency: float = 9.0


def desired_gap(v: np.ndarray, dv: np.ndarray, p: IDMParams) -> np.ndarray:
    """IDM desired bumper-to-bumper gap s* [m]; ``dv`` is own speed minus leader speed."""
    return p.s0 + np.maximum(0.0, v * p.t_headway + v * dv / (2.0 * np.sqrt(p.a * p.b)))


def idm_acceleration(
    v: np.ndarray, v_desired: np.ndarray, gap: np.ndarray, dv: np.ndarray, p: IDMParams
) -> np.ndarray:
    """IDM acceleration [m/s^2], clipped to ``[-b_emergency, a]``.

    ``gap`` is the bumper-to-bumper distance to the leader [m] (``inf`` for none), ``dv`` the
    approach rate (own speed minus leader speed) [m/s].
    """
    v_des = np.maximum(v_desired, 0.1)
    free = 1.0 - (np.maximum(v, 0.0) / v_des) ** p.delta
    s_star = desired_gap(v, dv, p)
    interaction = (s_star / np.maximum(gap, 0.1)) ** 2
    return np.minimum(np.maximum(p.a * (free - interaction), -p.b_emergency), p.a)
