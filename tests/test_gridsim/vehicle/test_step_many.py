"""The batched bicycle step (``step_bicycle`` on many vehicles: one compiled loop over
``step_one``) against the NumPy code it replaced, kept here as the reference: the same bits,
for per-vehicle parameters, the power limit, speed and steering limits, broadcasting and NaN
inputs."""

import numpy as np
import pytest

from gridsim import libm
from gridsim.vehicle.kinematics import DELTA, PSI, STATE_SIZE, BicycleParams, V, X, Y, step_bicycle


def numpy_step(state, accel, steer_rate, p, dt):
    """The replaced NumPy implementation of the batched step (new state, applied inputs)."""
    state = np.asarray(state, dtype=np.float64)
    x0, y0, psi0, v0, d0 = (state[..., X], state[..., Y], state[..., PSI], state[..., V],
                            state[..., DELTA])  # fmt: skip
    vd_lo = np.maximum(-p.v_delta_max, (-p.delta_max - d0) / dt)
    vd_hi = np.minimum(p.v_delta_max, (p.delta_max - d0) / dt)
    vd = np.minimum(np.maximum(steer_rate, vd_lo), vd_hi)
    a = np.minimum(np.maximum(accel, -p.b_max), p.a_max)
    v1 = v0 + a * dt
    vh = v0 + (0.5 * dt) * a
    if np.any(np.isfinite(p.v_switch)):
        c = p.a_max * p.v_switch
        with np.errstate(divide="ignore", invalid="ignore"):
            power = (v0 > p.v_switch) & (a * v0 >= c)
        v1 = np.where(power, np.sqrt(v0 * v0 + 2.0 * c * dt), v1)
        vh = np.where(power, np.sqrt(v0 * v0 + c * dt), vh)
    v1_clipped = np.minimum(np.maximum(v1, p.v_min), p.v_max)
    if np.any(v1_clipped != v1):
        vh = np.where(v1_clipped != v1, 0.5 * (v0 + v1_clipped), vh)
        v1 = v1_clipped
    ddt = vd * dt
    inv_l = 1.0 / p.wheelbase
    w0 = v0 * libm.tan(d0) * inv_l
    wh = vh * libm.tan(d0 + 0.5 * ddt) * inv_l
    w1 = v1 * libm.tan(d0 + ddt) * inv_l
    psih = psi0 + dt / 24.0 * (5.0 * w0 + 8.0 * wh - w1)
    psi1 = psi0 + dt / 6.0 * (w0 + 4.0 * wh + w1)
    x1 = x0 + dt / 6.0 * (v0 * np.cos(psi0) + 4.0 * vh * np.cos(psih) + v1 * np.cos(psi1))
    y1 = y0 + dt / 6.0 * (v0 * np.sin(psi0) + 4.0 * vh * np.sin(psih) + v1 * np.sin(psi1))
    shape = np.broadcast_shapes(state.shape[:-1], np.shape(v1), np.shape(vd))
    out = np.empty(shape + (STATE_SIZE,))
    out[..., X], out[..., Y], out[..., PSI], out[..., V], out[..., DELTA] = (
        x1, y1, psi1, v1, d0 + ddt)  # fmt: skip
    return (out, np.broadcast_to((v1 - v0) / dt, shape).copy(),
            np.broadcast_to(vd, shape).copy())  # fmt: skip


def _states(rng, n):
    s = np.empty((n, 5))
    s[:, :2] = rng.uniform(-500, 500, (n, 2))
    s[:, 2] = rng.uniform(-np.pi, np.pi, n)
    s[:, 3] = rng.uniform(-1, 45, n)  # some beyond the limits
    s[:, 4] = rng.uniform(-0.7, 0.7, n)
    return s


def _same(got, want):
    for g, w in zip(got, want, strict=True):
        assert g.shape == w.shape
        np.testing.assert_array_equal(g, w)  # NaN where NaN, every other bit the same


@pytest.mark.parametrize("dt", [0.1, 0.05, 0.5])
def test_many_vehicles_step_as_the_numpy_code_did(dt):
    rng = np.random.default_rng(int(dt * 100))
    n = 2000
    states = _states(rng, n)
    accel = rng.uniform(-15, 15, n)
    rate = rng.uniform(-3, 3, n)
    accel[::97], rate[::89] = np.nan, np.nan  # NaN in, NaN out, as NumPy's min and max
    accel[::101], rate[::103] = np.inf, -np.inf
    per_vehicle = BicycleParams(
        wheelbase=rng.uniform(2.0, 4.0, n), v_max=rng.uniform(10, 40, n),
        a_max=rng.uniform(1, 6, n), v_switch=np.where(rng.random(n) < 0.5, 7.0, np.inf),
        delta_max=rng.uniform(0.3, 1.0, n),
    )  # fmt: skip
    for params in (BicycleParams(), BicycleParams(v_switch=7.3), per_vehicle):
        _same(step_bicycle(states, accel, rate, params, dt),
              numpy_step(states, accel, rate, params, dt))  # fmt: skip


def test_broadcasting_is_kept():
    rng = np.random.default_rng(1)
    p = BicycleParams()
    one = _states(rng, 1)[0]
    many = _states(rng, 6)
    cases = [
        (many, 1.5, -0.2),  # inputs held alike
        (one, rng.uniform(-3, 3, 6), rng.uniform(-1, 1, 6)),  # one state, many inputs
        (many.reshape(2, 3, 5), rng.uniform(-3, 3, (2, 3)), 0.3),  # more than one axis
        (one, np.float64(0.7), np.float64(0.1)),  # NumPy scalars: the batched path
        (many, 2, 0),  # integers
    ]
    for state, accel, rate in cases:
        got = step_bicycle(state, accel, rate, p, 0.1)
        _same(got, numpy_step(state, accel, rate, p, 0.1))
    state = one.copy()
    step_bicycle(state, 1.0, 0.1, p, 0.1)
    np.testing.assert_array_equal(state, one)  # the input is not modified
