"""The destination curve: arrives when it can, and is always kinematically feasible."""

import math

import numpy as np
import pytest

from neurotrajectory.curves import CurveLimits, curve_to, destination_curves

TIMES = 0.5 * np.arange(1, 6)
LIMITS = CurveLimits(a_max=2.0, b_max=6.0, v_max=30.0, max_curvature=math.tan(0.6) / 2.7)


def _ego(speed, heading):
    return np.array([speed, 0, 0, 0, math.cos(heading), math.sin(heading)], np.float32)


def test_straight_ahead_at_its_speed_is_constant_velocity():
    out = curve_to(20.0, 1.0, 0.0, (50.0, 0.0), TIMES, LIMITS)
    np.testing.assert_allclose(out, np.stack([20 * TIMES, 0 * TIMES], 1), atol=1e-5)


def test_arrives_at_a_reachable_destination_on_time():
    heading = 0.7
    ego = _ego(12.0, heading)
    # 32 m ahead and 4 m to the left in the body frame, in the grid frame
    c, s = math.cos(heading), math.sin(heading)
    dest = np.array([c * 32 - s * 4, s * 32 + c * 4])
    out = destination_curves(ego[None], dest[None], TIMES, LIMITS)[0]
    np.testing.assert_allclose(out[-1], dest, atol=1e-4)


@pytest.mark.parametrize("seed", range(3))
def test_always_kinematically_feasible(seed):
    """Sampled densely (the same curve: it depends on the last time only), the path's
    curvature, speed and acceleration stay within the limits and it never reverses."""
    rng = np.random.default_rng(seed)
    dt = 0.01
    fine = dt * np.arange(1, 251)  # ends at 2.5 s like TIMES
    for _ in range(150):
        heading, speed = rng.uniform(-np.pi, np.pi), rng.uniform(0, 35)
        dest = rng.uniform(-80, 80, 2)
        c, s = math.cos(heading), math.sin(heading)
        pts = np.vstack([[0.0, 0.0], curve_to(speed, c, s, dest, fine, LIMITS)]).astype(float)
        steps = np.diff(pts, axis=0)
        dist = np.hypot(*steps.T)
        v = dist / dt
        assert np.all(v <= LIMITS.v_max + 1e-3)
        v0 = min(speed, LIMITS.v_max)
        accel = np.diff(np.concatenate([[v0], v])) / dt
        tol = 0.15  # m/s^2: float32 positions, differenced twice over 10 ms
        assert np.all(accel <= LIMITS.a_max + tol) and np.all(accel >= -LIMITS.b_max - tol)
        moving = dist > 1e-4
        direction = steps[moving] / dist[moving, None]
        heads = np.vstack([[c, s], direction])  # the heading, then each step's direction
        a, b = heads[:-1], heads[1:]
        assert np.all(np.sum(a * b, 1) > 0.9), "no reversing, no kinks"
        turn = np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.sum(a * b, 1))
        step = dist[moving]
        curvature = (turn / np.maximum(step, 1e-9))[step > 1e-2]
        assert np.all(np.abs(curvature) <= LIMITS.max_curvature * 1.01)
        np.testing.assert_allclose(
            pts[-1], curve_to(speed, c, s, dest, TIMES, LIMITS)[-1], atol=1e-4
        )


def test_a_destination_behind_means_stop():
    out = curve_to(10.0, 1.0, 0.0, (-5.0, 2.0), TIMES, LIMITS)
    stop = 10.0**2 / (2 * LIMITS.b_max)
    np.testing.assert_allclose(out[-1], (stop, 0.0), atol=1e-5)
    assert np.all(np.diff(out[:, 0]) >= 0)


def test_rows_do_not_depend_on_their_batch():
    rng = np.random.default_rng(3)
    ego = np.stack([_ego(v, h) for v, h in rng.uniform(0, 3, (9, 2)) * [10, 1]])
    dest = rng.uniform(-30, 30, (9, 2))
    batch = destination_curves(ego, dest, TIMES, LIMITS)
    for k in range(9):
        np.testing.assert_array_equal(
            batch[k], destination_curves(ego[k : k + 1], dest[k : k + 1], TIMES, LIMITS)[0]
        )


@pytest.mark.parametrize("arrive", [None, 5.0])
def test_the_compiled_batch_is_the_python_curve_bit_for_bit(arrive):
    """``destination_curves`` (one compiled call) gives the bits of ``curve_to`` run in Python
    for every row: destinations ahead, behind, inside the turning circle, on the heading,
    near the origin; speeds negative, zero, above v_max, infinite."""
    rng = np.random.default_rng(5)
    n = 400
    heading = rng.uniform(-np.pi, np.pi, n)
    speeds = rng.choice([0.0, 1e-3, 5.0, 20.0, 35.0, 45.0], n) * rng.uniform(0.5, 1.5, n)
    ego = np.stack([_ego(v, h) for v, h in zip(speeds, heading, strict=True)])
    ego[:3, 0] = [-1.0, 0.0, np.inf]
    dest = rng.uniform(-80, 80, (n, 2)).astype(np.float32)
    dest[:40] *= 1e-3
    dest[40:80, 1] = 0.0
    for times in (TIMES.astype(np.float32), 0.1 * np.arange(1, 26)):
        batch = destination_curves(ego, dest, times, LIMITS, arrive)
        one = [curve_to(ego[k, 0], ego[k, 4], ego[k, 5], dest[k], times, LIMITS, arrive)
               for k in range(n)]  # fmt: skip
        np.testing.assert_array_equal(batch, np.stack(one))


#: SHA-256 of the curves below as the pure-Python implementation computed them (before the
#: compiled one, 5194d29), arriving at the horizon and 5 s ahead: the compiled curves keep
#: its bits (libm's sin, cos, atan and atan2 on every x86-64 CPU).
PYTHON_DIGESTS = {
    None: "2644c448487837d503af9048c8cc0a3588d956d1863ed14c5800124a521a9730",
    5.0: "b13a3922e69b79b9bae2e919f9af286870b9797c9ebd6f46cf2139a919d502b0",
}


@pytest.mark.parametrize("arrive", [None, 5.0])
def test_the_curves_keep_the_bits_of_the_python_implementation(arrive):
    import hashlib

    rng = np.random.default_rng(11)
    n = 300
    heading = rng.uniform(-np.pi, np.pi, n)
    ego = np.zeros((n, 6), np.float32)
    ego[:, 0] = rng.uniform(-2, 45, n)
    ego[:, 4], ego[:, 5] = np.cos(heading), np.sin(heading)
    dest = rng.uniform(-60, 60, (n, 2)).astype(np.float32)
    out = destination_curves(ego, dest, TIMES.astype(np.float32), LIMITS, arrive)
    assert hashlib.sha256(out.tobytes()).hexdigest() == PYTHON_DIGESTS[arrive]


def test_curves_of_mismatched_or_empty_inputs_are_refused():
    ego = np.stack([_ego(10.0, 0.0)] * 3)
    with pytest.raises(ValueError, match=r"one destination \(x, y\) per ego state"):
        destination_curves(ego, np.zeros((2, 2)), TIMES, LIMITS)
    with pytest.raises(ValueError, match="times must be a 1-D array"):
        destination_curves(ego, np.zeros((3, 2)), np.array([]), LIMITS)
    with pytest.raises(ValueError, match="arrival time must be > 0 s, got 0.0"):
        curve_to(10.0, 1.0, 0.0, (5.0, 0.0), TIMES, LIMITS, arrive=0.0)
