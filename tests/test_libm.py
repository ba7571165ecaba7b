"""gridsim.libm: the C library's result for every element, whatever NumPy's SIMD code does."""

import math

import numpy as np
import pytest

from gridsim import libm

RNG = np.random.default_rng(0)
X = RNG.uniform(-12.0, 12.0, (40, 25))
Y = RNG.uniform(-12.0, 12.0, 25)
P = RNG.uniform(0.0, 3.0, (40, 25))


@pytest.mark.parametrize(
    ("ours", "scalar", "args"),
    [
        (libm.arctan2, math.atan2, (X, Y)),  # broadcast (40, 25) with (25,)
        (libm.power, math.pow, (P, 4.0)),
        (libm.arctan, math.atan, (X,)),
        (libm.tan, math.tan, (X,)),
        (libm.exp, math.exp, (X,)),
    ],
)
def test_every_element_is_the_c_librarys(ours, scalar, args):
    arrays = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in args))
    expected = np.array([scalar(*v) for v in zip(*(a.ravel() for a in arrays), strict=True)])
    out = ours(*args)
    assert out.dtype == np.float64 and out.shape == arrays[0].shape
    assert np.array_equal(out.ravel(), expected)
    # scalars (Python or NumPy) give Python floats, the same bits
    first = tuple(float(a.ravel()[0]) for a in arrays)
    assert ours(*first) == expected[0] and isinstance(ours(*first), float)
    assert ours(*(np.float64(v) for v in first)) == expected[0]


def test_views_and_other_dtypes_are_read_as_float64():
    strided = X[::2, ::3]
    assert np.array_equal(libm.tan(strided), np.vectorize(math.tan)(strided))
    ints = np.arange(-5, 6)
    assert np.array_equal(libm.exp(ints), np.array([math.exp(v) for v in ints]))
    assert libm.exp(np.empty((0, 3))).shape == (0, 3)


def test_angle_is_the_argument_of_complex_numbers():
    z = np.exp(1j * X)
    assert np.array_equal(libm.angle(z), np.vectorize(math.atan2)(z.imag, z.real))
