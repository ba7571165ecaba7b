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


def _libm_float_function(name: str):
    """The C library's float32 function ``name`` (``atan2f``, ...), through ctypes."""
    import ctypes
    import ctypes.util

    fn = getattr(ctypes.CDLL(ctypes.util.find_library("m")), name)
    fn.restype = ctypes.c_float
    return fn


@pytest.mark.parametrize(
    ("ours", "c_name", "args"),
    [
        (libm.arctan2, "atan2f", (X[:3], Y)),
        (libm.power, "powf", (P[:3], np.float32(4.0))),
        (libm.arctan, "atanf", (X[:3],)),
        (libm.tan, "tanf", (X[:3],)),
        (libm.exp, "expf", (X[:3],)),
    ],
)
def test_float32_inputs_use_the_c_librarys_float_functions(ours, c_name, args):
    import ctypes

    args32 = tuple(np.asarray(a, dtype=np.float32) for a in args)
    fn = _libm_float_function(c_name)
    arrays = np.broadcast_arrays(*args32)
    expected = np.array(
        [
            fn(*(ctypes.c_float(v) for v in vs))
            for vs in zip(*(a.ravel() for a in arrays), strict=True)
        ],
        dtype=np.float32,
    )
    out = ours(*args32)
    assert out.dtype == np.float32
    assert np.array_equal(out.ravel(), expected)
    assert ours(*(a.ravel()[0] for a in arrays)) == expected[0]  # a float32 scalar
    # mixed with float64: computed in float64
    assert ours(*(a.astype(np.float64) for a in args32)).dtype == np.float64


def test_non_finite_inputs_give_nan_or_inf_as_numpy_does():
    assert math.isnan(libm.tan(math.inf))
    assert libm.exp(1000.0) == math.inf
    assert math.isnan(libm.power(-8.0, 1.0 / 3.0))
    assert libm.power(0.0, -1.0) == math.inf
    assert np.isnan(libm.arctan(np.array([math.nan])))[0]


def test_complex_input_is_refused():
    with pytest.raises(TypeError, match="libm.exp takes real numbers"):
        libm.exp(np.array([1j]))
