"""The branch-free sincos of the compiled path against numpy's (libm's) sin and cos."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from numba import njit

from mbs_envs.dynamics.trig import SINCOS_RANGE, sincos, sincos_checked, sincos_columns


def ulps(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """``|x - ref|`` in units of the last place of ``ref``."""
    return np.abs(x - ref) / np.spacing(np.abs(ref))


def fast(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s, c = np.empty_like(x), np.empty_like(x)
    sincos_columns(x, s, c)
    return s, c


def test_one_ulp_over_the_range_and_at_the_hard_points():
    rng = np.random.default_rng(0)
    k = np.arange(-2000, 2001)
    x = np.concatenate(
        [
            rng.uniform(-10, 10, 200_000),
            rng.uniform(-SINCOS_RANGE, SINCOS_RANGE, 200_000),
            k * (np.pi / 2),  # near the zeros of sin and cos: the reduction must not cancel
            np.nextafter(k * (np.pi / 4), np.inf),  # on the quadrant boundaries
            np.geomspace(1e-300, 1.0, 2000),
            -np.geomspace(1e-300, 1.0, 2000),
            [0.0, SINCOS_RANGE, -SINCOS_RANGE],
        ]
    )
    s, c = fast(x)
    assert ulps(s, np.sin(x)).max() <= 1.0
    assert ulps(c, np.cos(x)).max() <= 1.0


@settings(max_examples=500, deadline=None)
@given(st.floats(-SINCOS_RANGE, SINCOS_RANGE))
def test_one_ulp_anywhere_in_range(x):
    s, c = sincos(x)
    assert ulps(np.array(s), np.sin(x)) <= 1.0
    assert ulps(np.array(c), np.cos(x)) <= 1.0


def test_out_of_range_and_non_finite_arguments_take_libm_without_touching_the_others():
    x = np.array([0.3, 1e7, -1e20, 2.0, np.nan, np.inf, -np.inf, 1e300, -5.0])
    with np.errstate(invalid="ignore"):
        ref_s, ref_c = np.sin(x), np.cos(x)
    s, c = fast(x)
    np.testing.assert_array_equal(np.isnan(s), np.isnan(ref_s))
    finite = np.isfinite(ref_s)
    assert ulps(s[finite], ref_s[finite]).max() <= 1.0
    assert ulps(c[finite], ref_c[finite]).max() <= 1.0
    # outside the range the libm values are taken as they are
    out = finite & (np.abs(x) > SINCOS_RANGE)
    np.testing.assert_array_equal(s[out], ref_s[out])
    np.testing.assert_array_equal(c[out], ref_c[out])


def _bits(x: np.ndarray) -> np.ndarray:
    """Bit patterns, every NaN as one (comparing values bit for bit, signed zeros included)."""
    x = np.where(np.isnan(x), np.nan, x)
    return np.ascontiguousarray(x).view(np.int64)


def test_wrap_gives_python_remainders_bits_and_hands_the_rest_to_fmod():
    """``wrap`` = ``(x + pi) % (2 pi) - pi`` by one FMA instead of libm's fmod: the same bits as numpy's
    (and Python's) remainder everywhere it claims ``ok``, including at and beside multiples of 2 pi,
    signed zeros, subnormals and up to WRAP_RANGE; NaN, inf and larger arguments go to fmod."""
    from mbs_envs.dynamics.trig import TWO_PI, WRAP_RANGE, wrap
    from mbs_envs.envs.tracking import error_columns, wrap_angle

    rng = np.random.default_rng(5)
    k = np.arange(-100_000, 100_001)
    on = k * TWO_PI - np.pi  # x + pi is a multiple of 2 pi (to rounding)
    x = np.concatenate(
        [
            rng.uniform(-10, 10, 300_000),
            rng.normal(0, 1, 100_000),
            rng.uniform(-WRAP_RANGE, WRAP_RANGE, 100_000) * 0.99,
            np.exp(rng.uniform(-745, 27, 100_000)) * rng.choice([-1, 1], 100_000),
            on, np.nextafter(on, np.inf), np.nextafter(on, -np.inf), on + 1e-15, on - 1e-15,
            np.nextafter(k * np.pi, np.inf), np.nextafter(k * np.pi, -np.inf),
            [0.0, -0.0, np.pi, -np.pi, 5e-324, -5e-324, 0.99 * WRAP_RANGE, -0.99 * WRAP_RANGE],
            [np.nan, np.inf, -np.inf, WRAP_RANGE, -2 * WRAP_RANGE, 1e300, -1e300],  # fmod's
        ]
    )  # fmt: skip
    with np.errstate(invalid="ignore"):
        ref = wrap_angle(x)
    assert np.array_equal(_bits(ref[:2000]), _bits(np.array([(v + np.pi) % (2 * np.pi) - np.pi for v in x[:2000]])))
    e = np.empty((1, x.size))
    error_columns(np.zeros((1, x.size)), x[None, :].copy(), np.zeros(1, np.int64), e)  # q = 0: e = wrap(q_ref)
    assert np.array_equal(_bits(e[0]), _bits(ref))
    assert all(np.array_equal(_bits(np.array([wrap(v)])), _bits(np.array([r]))) for v, r in zip(x[-20:], ref[-20:]))


@settings(max_examples=2000, deadline=None)
@given(st.floats(allow_nan=True, allow_infinity=True))
def test_wrap_bits_anywhere(x):
    from mbs_envs.dynamics.trig import wrap
    from mbs_envs.envs.tracking import wrap_angle

    with np.errstate(invalid="ignore"):
        assert np.array_equal(_bits(np.array([wrap(x)])), _bits(np.array([wrap_angle(np.float64(x))])))


def test_sum_of_sines_columns_in_one_pass_has_the_elementwise_definitions_bits():
    """The references' kernel (one SIMD pass, a second with libm when an argument is beyond the
    SIMD sincos's range) against the module docstring's formulas written elementwise with
    :func:`sincos_checked`, bit for bit: in range, with some members' ``w t + p`` beyond the range
    (huge times) and with a NaN time; and against numpy's ``sin``/``cos`` to 1e-12 where in range."""
    from mbs_envs.envs.references import sum_of_sines_columns

    @njit
    def elementwise(t, center, rate, A, w, p):
        n, K, B = A.shape
        out = np.empty((3, n, B))
        for i in range(n):
            for b in range(B):
                q, dq, ddq = 0.0, 0.0, 0.0
                for k in range(K):
                    s, c = sincos_checked(w[i, k, b] * t[b] + p[i, k, b])
                    As = A[i, k, b] * s
                    q += As
                    dq += A[i, k, b] * w[i, k, b] * c
                    ddq += As * w[i, k, b] ** 2
                out[0, i, b] = center[i, b] + q + rate[i, b] * t[b]
                out[1, i, b] = dq + rate[i, b]
                out[2, i, b] = -ddq
        return out

    rng = np.random.default_rng(3)
    n, K, B = 4, 3, 37
    center, rate = rng.normal(size=(n, B)), rng.normal(size=(n, B))
    A, w, p = rng.normal(size=(n, K, B)), rng.uniform(0.2, 3, (n, K, B)), rng.uniform(0, 6, (n, K, B))
    for case in ("in range", "beyond", "nan"):
        t = rng.uniform(0, 20, B)
        if case == "beyond":
            t[[2, 30]] = [1e9, -3e12]
        if case == "nan":
            t[5] = np.nan
        out = np.empty((3, n, B))
        sum_of_sines_columns(t, center, rate, A, w, p, out[0], out[1], out[2])
        ref = elementwise(t, center, rate, A, w, p)
        same = (out.view(np.int64) == ref.view(np.int64)) | (np.isnan(out) & np.isnan(ref))
        assert same.all(), case
        if case == "in range":
            x = w * t + p
            q = center + rate * t + np.sum(A * np.sin(x), axis=1)
            np.testing.assert_allclose(out[0], q, rtol=0, atol=1e-12 * np.abs(q).max())
            v = rate + np.sum(A * w * np.cos(x), axis=1)
            np.testing.assert_allclose(out[1], v, rtol=0, atol=1e-12 * np.abs(v).max())
