"""Kinematic single-track model against CommonRoad's vehicle_dynamics_ks and golden values."""

import numpy as np
import pytest
from scipy.integrate import odeint
from vehiclemodels.parameters_vehicle1 import parameters_vehicle1
from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
from vehiclemodels.parameters_vehicle3 import parameters_vehicle3
from vehiclemodels.vehicle_dynamics_ks import vehicle_dynamics_ks

from gridsim.errors import GridSimError
from gridsim.vehicle import DELTA, PSI, BicycleParams, V, X, Y, box_corners, step_bicycle


def ours(p) -> BicycleParams:
    lon, st = p.longitudinal, p.steering
    return BicycleParams(
        wheelbase=p.a + p.b,
        v_min=lon.v_min,
        v_max=lon.v_max,
        a_max=lon.a_max,
        b_max=lon.a_max,
        delta_max=st.max,
        v_delta_max=st.v_max,
        v_switch=lon.v_switch,
    )


def to_ours(cr):  # CommonRoad [sx, sy, delta, v, psi] -> ours [x, y, psi, v, delta]
    return np.array([cr[0], cr[1], cr[4], cr[3], cr[2]])


def simulate(params, x0, accel, steer_rate, dt, steps):
    s = np.asarray(x0, float)[None]
    for _ in range(steps):
        s = step_bicycle(s, accel, steer_rate, params, dt).state
    return s[0]


def reference(p, x0_cr, u, t_end):
    def f(x, t):
        return vehicle_dynamics_ks(x, u, p)

    return to_ours(odeint(f, x0_cr, [0.0, t_end], rtol=1e-12, atol=1e-12)[-1])


# Golden values from the CommonRoad reference (shared/notes/reference.md section 3).
GOLDEN = [
    (
        parameters_vehicle2,
        [0, 0, 0, 15, 0],
        [0.15, 0.0],
        0.5,
        [7.491073, 0.272565, 0.075, 15, 0.109160],
    ),
    (
        parameters_vehicle2,
        [0, 0, 0, 15, 0],
        [0.15, 0.0],
        1.0,
        [14.715551, 2.156353, 0.15, 15, 0.437876],
    ),
    (
        parameters_vehicle2,
        [0, 0, 0.1, 10, 0],
        [0.0, 1.0],
        1.0,
        [10.210385, 2.115022, 0.1, 11.0, 0.408511],
    ),
    (
        parameters_vehicle3,
        [0, 0, 0, 5, 0.5],
        [1.0, -2.0],
        0.5,
        [1.942016, 1.134731, 0.2, 4.0, 0.588223],
    ),
]


@pytest.mark.parametrize("pfun,x0,u,t_end,expected", GOLDEN)
@pytest.mark.parametrize("dt", [0.1, 0.05])
def test_golden_values(pfun, x0, u, t_end, expected, dt):
    got = simulate(ours(pfun()), to_ours(x0), u[1], u[0], dt, int(round(t_end / dt)))
    np.testing.assert_allclose(got, to_ours(expected), atol=1e-5)


def test_power_limited_acceleration_matches_golden():
    got = simulate(ours(parameters_vehicle1()), [0, 0, 0, 20, 0], 11.5, 0.0, 0.1, 5)
    assert got[V] == pytest.approx(21.323285, abs=1e-5)
    assert got[X] == pytest.approx(10.334353, abs=1e-5)


def test_random_inputs_match_commonroad_within_1mm():
    rng = np.random.default_rng(42)
    p = parameters_vehicle2()
    params = ours(p)
    for _ in range(25):
        v0 = rng.uniform(2, 30)
        d0 = rng.uniform(-0.3, 0.3)
        x0_cr = [rng.uniform(-5, 5), rng.uniform(-5, 5), d0, v0, rng.uniform(-np.pi, np.pi)]
        # Inputs that keep every state strictly inside its limits for the whole second.
        u = [rng.uniform(-0.3, 0.3), rng.uniform(-1.5, min(1.5, 11.5 * 7.319 / (v0 + 2) - 0.1))]
        got = simulate(params, to_ours(x0_cr), u[1], u[0], 0.1, 10)
        ref = reference(p, x0_cr, u, 1.0)
        assert np.hypot(got[X] - ref[X], got[Y] - ref[Y]) <= 1e-3
        np.testing.assert_allclose(got[[PSI, V, DELTA]], ref[[PSI, V, DELTA]], atol=1e-4)


def test_batched_step_equals_per_vehicle_steps():
    rng = np.random.default_rng(1)
    params = BicycleParams()
    states = np.column_stack(
        [rng.normal(size=(50, 3)), rng.uniform(0, 30, 50), rng.uniform(-0.5, 0.5, 50)]
    )
    a, sr = rng.uniform(-8, 4, 50), rng.uniform(-1, 1, 50)
    batched = step_bicycle(states, a, sr, params, 0.1)
    for i in range(50):
        single = step_bicycle(states[i], a[i], sr[i], params, 0.1)
        np.testing.assert_array_equal(batched.state[i], single.state)
        assert batched.accel[i] == single.accel


def test_limits_are_respected_and_reported():
    p = BicycleParams(v_min=0.0, v_max=10.0, a_max=2.0, b_max=6.0, delta_max=0.5, v_delta_max=0.4)
    s = np.array([0.0, 0.0, 0.0, 9.9, 0.49])
    r = step_bicycle(s, 5.0, 3.0, p, 0.1)
    assert r.state[V] == pytest.approx(10.0)
    assert r.state[DELTA] == pytest.approx(0.5)
    assert r.accel == pytest.approx(1.0)  # only 0.1 m/s of headroom in 0.1 s
    assert r.steer_rate == pytest.approx(0.1)
    stop = step_bicycle(np.array([0.0, 0.0, 0.0, 0.3, 0.0]), -50.0, 0.0, p, 0.1)
    assert stop.state[V] == 0.0 and stop.accel == pytest.approx(-3.0)
    for _ in range(3):  # no reversing below v_min
        stop = step_bicycle(stop.state, -6.0, 0.0, p, 0.1)
    assert stop.state[V] == 0.0 and stop.state[X] == pytest.approx(0.015)


def test_circle_closes_on_itself():
    p = BicycleParams(wheelbase=2.5, delta_max=0.6)
    delta = 0.3
    radius = 2.5 / np.tan(delta)
    period = 2 * np.pi * radius / 10.0
    steps = 1000
    s = simulate(p, [0, 0, 0, 10.0, delta], 0.0, 0.0, period / steps, steps)
    assert np.hypot(s[X], s[Y]) < 1e-6


def test_invalid_params_raise_clear_error():
    with pytest.raises(GridSimError, match="wheelbase"):
        BicycleParams(wheelbase=-1.0)
    with pytest.raises(GridSimError, match="v_max"):
        BicycleParams(v_min=5.0, v_max=1.0)


def test_box_corners_orientation():
    c = box_corners(np.array([1.0]), np.array([2.0]), np.array([np.pi / 2]), 4.0, 2.0)[0]
    # Heading north: the front-right corner is to the east of the front axle line.
    np.testing.assert_allclose(c, [[2, 0], [2, 4], [0, 4], [0, 0]], atol=1e-12)


@pytest.mark.parametrize("v_switch", [np.inf, 7.0])
def test_one_vehicle_step_is_bit_identical_to_the_batched_step(v_switch):
    """The pure-Python path for one vehicle gives the batched NumPy path's bits."""
    params = BicycleParams(v_switch=v_switch, v_max=30.0, v_min=-2.0)
    rng = np.random.default_rng(11)
    for _ in range(3000):
        state = np.array([*rng.uniform(-500, 500, 2), rng.uniform(-7, 7), rng.uniform(-3, 32),
                          rng.uniform(-0.6, 0.6)])  # fmt: skip
        accel, rate = float(rng.uniform(-9, 9)), float(rng.uniform(-2, 2))
        one = step_bicycle(state, accel, rate, params, 0.1)
        batched = step_bicycle(state[None], np.array([accel]), np.array([rate]), params, 0.1)
        assert one.state.tobytes() == batched.state[0].tobytes()
        assert float(one.accel) == float(batched.accel[0])
        assert float(one.steer_rate) == float(batched.steer_rate[0])


@pytest.mark.parametrize("v_switch", [np.inf, 7.0])
def test_compiled_one_vehicle_step_is_bit_identical_to_python(v_switch):
    """``step_one`` inside a kernel (the reference's shadow ticks) gives the Python floats'
    bits."""
    from numba import njit

    from gridsim.vehicle.kinematics import step_limits, step_one

    compiled = njit(lambda *a: step_one(*a))
    limits = step_limits(BicycleParams(v_switch=v_switch, v_max=30.0, v_min=-2.0))
    rng = np.random.default_rng(12)
    for _ in range(3000):
        state = [*rng.uniform(-500, 500, 2), rng.uniform(-7, 7), rng.uniform(-3, 32),
                 rng.uniform(-0.6, 0.6)]  # fmt: skip
        args = (*(float(s) for s in state), float(rng.uniform(-9, 9)), float(rng.uniform(-2, 2)))
        assert compiled(*args, limits, 0.1) == step_one(*args, limits, 0.1)


def test_compiled_pursuit_and_idm_are_bit_identical_to_python():
    """``pursuit_one`` and ``idm_accel_pow`` compiled give what Python computes on floats
    (the IDM's powers are libm's ``pow`` there, not ``x * x``)."""
    from numba import njit

    from gridsim.vehicle.control import PursuitGains, pursuit_inputs, pursuit_one
    from gridsim.vehicle.idm import IDMParams, idm_accel, idm_accel_pow

    pursuit, idm = njit(lambda *a: pursuit_one(*a)), njit(lambda *a: idm_accel_pow(*a))
    p, g = BicycleParams(), PursuitGains()
    limits = (p.wheelbase, p.delta_max, p.b_max, p.a_max, p.v_delta_max, g.steer_time,
              g.speed_gain)  # fmt: skip
    rng = np.random.default_rng(13)
    for _ in range(20000):
        state = np.array([*rng.uniform(-500, 500, 2), rng.uniform(-7, 7), rng.uniform(0, 32),
                          rng.uniform(-0.6, 0.6)])  # fmt: skip
        target = state[:2] + rng.uniform(-30, 30, 2)
        speed = float(rng.uniform(0, 35))
        assert pursuit(*state.tolist(), *target.tolist(), speed, limits) == pursuit_inputs(
            state, target, speed, p, g
        )
        args = (state[3], speed, float(rng.uniform(-2, 80)), float(rng.uniform(-10, 10)))
        assert idm(*args, *IDMParams().values) == float(idm_accel(*args, *IDMParams().values))
