"""The branch-free sincos of the compiled path against numpy's (libm's) sin and cos."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mbs_envs.dynamics.trig import SINCOS_RANGE, sincos, sincos_columns


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
