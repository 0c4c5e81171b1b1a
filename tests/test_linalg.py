"""Batched linear algebra helpers against numpy's own routines."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mbs_envs.dynamics.linalg import cross


@settings(max_examples=50, deadline=None)
@given(
    st.integers(0, 2**32 - 1), st.sampled_from([((3,), (3,)), ((5, 3), (5, 3)), ((4, 1, 3), (2, 3)), ((3,), (7, 3))])
)
def test_cross_is_numpys_cross_bit_for_bit(seed, shapes):
    """The same products and differences as ``np.cross``: equal exactly, with broadcasting."""
    rng = np.random.default_rng(seed)
    a, b = (rng.normal(size=s) * 10.0 ** rng.integers(-8, 9, size=s) for s in shapes)
    np.testing.assert_array_equal(cross(a, b), np.cross(a, b))


def test_cross_of_the_unit_vectors():
    ex, ey, ez = np.eye(3)
    np.testing.assert_array_equal(cross(ex, ey), ez)
    np.testing.assert_array_equal(cross(ey, ex), -ez)
    np.testing.assert_array_equal(cross(ez, ex), ey)
