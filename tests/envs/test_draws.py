"""The raw-draw maps of :mod:`mbs_envs.envs.draws` give numpy's own ``uniform`` and ``dirichlet`` draws bit for bit
(the batched starts rely on it: a member's start is the one its generator would give through numpy's methods)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mbs_envs.envs.draws import dirichlet_ones_of, uniform_of
from mbs_envs.envs.references import sample_sum_of_sines, sample_sums_of_sines

from ..budget import examples

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@settings(deadline=None, max_examples=examples(300))
@given(seed=st.integers(0, 2**63), low=finite, width=st.floats(0.0, 1e6), size=st.integers(0, 9))
def test_uniform_of_random_is_numpys_uniform(seed, low, width, size):
    high = low + width
    assert np.array_equal(uniform_of(np.random.default_rng(seed).random(size), low, high),
                          np.random.default_rng(seed).uniform(low, high, size))  # fmt: skip
    assert uniform_of(np.random.default_rng(seed).random(), low, high) == np.random.default_rng(seed).uniform(low, high)


@settings(deadline=None, max_examples=examples(150))
@given(seed=st.integers(0, 2**63), bounds=st.lists(st.tuples(finite, st.floats(0.0, 1e3)), min_size=1, max_size=5))
def test_consecutive_uniforms_of_any_bounds_are_one_call_of_doubles(seed, bounds):
    lows = np.array([b[0] for b in bounds])
    highs = lows + np.array([b[1] for b in bounds])
    g = np.random.default_rng(seed)
    numpy_way = np.concatenate([g.uniform(lows, highs), [g.uniform(lo, hi) for lo, hi in zip(lows, highs)]])
    d = np.random.default_rng(seed).random(2 * len(bounds))
    ours = np.concatenate([uniform_of(d[: len(bounds)], lows, highs), uniform_of(d[len(bounds) :], lows, highs)])
    assert np.array_equal(ours, numpy_way)


@settings(deadline=None, max_examples=examples(150))
@given(seed=st.integers(0, 2**63), k=st.integers(1, 6), n=st.integers(1, 5))
def test_dirichlet_ones_of_exponentials_is_numpys_dirichlet(seed, k, n):
    ours = dirichlet_ones_of(np.random.default_rng(seed).standard_exponential((n, k)))
    assert np.array_equal(ours, np.random.default_rng(seed).dirichlet(np.ones(k), size=n))


def test_a_batch_of_references_is_its_members_drawn_one_by_one_with_numpys_methods():
    """``sample_sums_of_sines`` of L generators = the numpy-method draw of each (as the code was before batching)."""
    lo, hi, amp = np.array([-2.0, -1.2]), np.array([0.5, 1.2]), np.array([0.6, 0.8])
    refs = sample_sums_of_sines([np.random.default_rng(s) for s in range(6)], lo, hi, amp, (0.5, 3.0), 3, (-1.0, 2.0))
    for s in range(6):
        g = np.random.default_rng(s)
        center, total = g.uniform(lo, hi), g.uniform(0.5, 1.0, size=2) * amp
        weights = g.dirichlet(np.ones(3), size=2)
        omega, phase, rate = (
            g.uniform(0.5, 3.0, size=(2, 3)),
            g.uniform(0.0, 2 * np.pi, size=(2, 3)),
            g.uniform(-1.0, 2.0, size=2),
        )
        for got, want in zip((refs.center[s], refs.amplitude[s], refs.omega[s], refs.phase[s], refs.rate[s]),
                             (center, total[:, None] * weights, omega, phase, rate)):  # fmt: skip
            assert np.array_equal(got, want)
        one = sample_sum_of_sines(np.random.default_rng(s), lo, hi, amp, (0.5, 3.0), 3, (-1.0, 2.0))
        assert np.array_equal(one.center, refs.center[s]) and one.center.shape == (2,)
