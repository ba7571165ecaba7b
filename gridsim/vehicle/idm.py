"""Intelligent Driver Model (Treiber et al. 2000), vectorised over vehicles.

The formulas (:func:`idm_gap`, :func:`idm_accel`) take the parameters as scalars so that
compiled kernels can call the very same code (:func:`~gridsim.jit.jitable`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gridsim.jit import jitable


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

    @property
    def values(self) -> tuple[float, ...]:
        """The parameters as a tuple, in field order (the trailing arguments of
        :func:`idm_gap` and :func:`idm_accel`)."""
        return (self.a, self.b, self.t_headway, self.s0, self.delta, self.b_emergency)


@jitable
def idm_gap(v, dv, a, b, t_headway, s0, delta, b_emergency):
    """Desired gap s* [m] (see :func:`desired_gap`); parameters in :class:`IDMParams` order."""
    return s0 + np.maximum(0.0, v * t_headway + v * dv / (2.0 * np.sqrt(a * b)))


@jitable
def idm_ratios(v, v_desired, gap, dv, a, b, t_headway, s0, delta, b_emergency):
    """The IDM's speed ratio ``v / v_desired`` and gap ratio ``s* / gap`` (both floored as
    :func:`idm_accel` needs them)."""
    v_des = np.maximum(v_desired, 0.1)
    s_star = idm_gap(v, dv, a, b, t_headway, s0, delta, b_emergency)
    return np.maximum(v, 0.0) / v_des, s_star / np.maximum(gap, 0.1)


@jitable
def idm_accel(v, v_desired, gap, dv, a, b, t_headway, s0, delta, b_emergency):
    """IDM acceleration [m/s^2] (see :func:`idm_acceleration`); parameters in
    :class:`IDMParams` order."""
    speed, closing = idm_ratios(v, v_desired, gap, dv, a, b, t_headway, s0, delta, b_emergency)
    free = 1.0 - speed**delta
    interaction = closing**2
    return np.minimum(np.maximum(a * (free - interaction), -b_emergency), a)


@jitable
def idm_accel_pow(v, v_desired, gap, dv, a, b, t_headway, s0, delta, b_emergency):
    """:func:`idm_accel` as Python computes it on floats, compiled: both powers through libm's
    ``pow`` (compiled ``x ** 2`` is ``x * x``, which differs from ``pow`` in the last bit
    for about 0.1 % of inputs)."""
    speed, closing = idm_ratios(v, v_desired, gap, dv, a, b, t_headway, s0, delta, b_emergency)
    free = 1.0 - np.float_power(speed, delta)
    # the exponent 2 computed, not a constant: LLVM turns pow(x, 2.0) into x * x
    interaction = np.float_power(closing, 2.0 + 0.0 * delta)
    return np.minimum(np.maximum(a * (free - interaction), -b_emergency), a)


def desired_gap(v: np.ndarray, dv: np.ndarray, p: IDMParams) -> np.ndarray:
    """IDM desired bumper-to-bumper gap s* [m]; ``dv`` is own speed minus leader speed."""
    return idm_gap(v, dv, *p.values)


def idm_acceleration(
    v: np.ndarray, v_desired: np.ndarray, gap: np.ndarray, dv: np.ndarray, p: IDMParams
) -> np.ndarray:
    """IDM acceleration [m/s^2], clipped to ``[-b_emergency, a]``.

    ``gap`` is the bumper-to-bumper distance to the leader [m] (``inf`` for none), ``dv`` the
    approach rate (own speed minus leader speed) [m/s].
    """
    return idm_accel(v, v_desired, gap, dv, *p.values)
