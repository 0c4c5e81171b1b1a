"""numpy's distributions from raw draws, so that a batch draws member by member only the raw numbers.

A batch of members, each with its own generator, must make one generator call per member and
distribution; numpy's ``Generator.uniform`` with array bounds and ``Generator.dirichlet`` cost several
microseconds a call in argument checks alone. The task code instead draws each member's raw numbers
in one call per kind (``random``: uniform doubles in [0, 1); ``standard_exponential``) and maps them
for all members at once with the formulas numpy's C code applies to the same draws:

- ``Generator.uniform(low, high)`` is ``low + (high - low) * d`` of the next double ``d``
  (``random_uniform``); consecutive uniforms, of any bounds, are consecutive doubles;
- ``Generator.dirichlet(alpha)`` with every ``alpha_j = 1`` draws ``K`` standard gammas of shape 1,
  which are standard exponentials, and scales them by ``1 / (0 + g_1 + ... + g_K)`` (``random_standard_gamma``
  and ``dirichlet``'s gamma method).

So the numbers are numpy's, bit for bit (tested against ``uniform`` and ``dirichlet`` in
``tests/envs/test_draws.py``).
"""

from __future__ import annotations

import numpy as np


def uniform_of(d: np.ndarray, low: float | np.ndarray, high: float | np.ndarray) -> np.ndarray:
    """``Generator.uniform(low, high)`` of the doubles ``d`` in [0, 1) (``Generator.random``'s).

    Parameters
    ----------
    d : ndarray, shape (...)
    low, high : float or ndarray broadcasting with ``d``

    Returns
    -------
    ndarray, shape (...)
        ``low + (high - low) * d``.
    """
    return low + (high - low) * d


def dirichlet_ones_of(e: np.ndarray) -> np.ndarray:
    """``Generator.dirichlet(np.ones(K))`` of the standard exponentials ``e`` (``Generator.standard_exponential``'s).

    Parameters
    ----------
    e : ndarray, shape (..., K)
        ``K`` consecutive draws per weight vector.

    Returns
    -------
    ndarray, shape (..., K)
        ``e / sum(e)`` as numpy forms it: the sum from the left, then one reciprocal.
    """
    acc = e[..., 0].copy()
    for j in range(1, e.shape[-1]):
        acc = acc + e[..., j]
    return e * (1.0 / acc)[..., None]
