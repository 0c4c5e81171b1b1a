"""Reference motions with analytic derivatives, for tracking tasks.

The family is a sum of sinusoids per coordinate,

    q_ref(t) = c + s t + sum_k A_k sin(w_k t + p_k),
    v_ref(t) = s + sum_k A_k w_k cos(w_k t + p_k),
    a_ref(t) = -sum_k A_k w_k^2 sin(w_k t + p_k),

smooth (C-infinity); ``|q_ref - c - s t| <= sum_k |A_k|``. The mean rate ``s``
(zero by default) lets a reference spin, e.g. a crank at a rippled speed.
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class SumOfSines:
    """A reference ``q_ref(t)`` for ``n`` coordinates with ``K`` components each.

    Attributes
    ----------
    center : ndarray, shape (n,)
        Mean position ``c`` [rad].
    amplitude : ndarray, shape (n, K)
        ``A`` [rad].
    omega : ndarray, shape (n, K)
        Angular frequencies ``w`` [rad/s].
    phase : ndarray, shape (n, K)
        Phases ``p`` [rad].
    rate : ndarray, shape (n,), optional
        Mean rate ``s`` [rad/s] (default zero).
    """

    center: np.ndarray
    amplitude: np.ndarray
    omega: np.ndarray
    phase: np.ndarray
    rate: np.ndarray | None = None

    def __call__(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Evaluate ``(q_ref, v_ref, a_ref)`` at times ``t``.

        Parameters
        ----------
        t : float or ndarray, shape (T,)

        Returns
        -------
        q_ref, v_ref, a_ref : ndarray, shape (n,) or (T, n)
        """
        tt = np.asarray(t, float)[..., None, None]
        arg = self.omega * tt + self.phase
        As = self.amplitude * np.sin(arg)
        q_ref = self.center + As.sum(axis=-1)
        v_ref = (self.amplitude * self.omega * np.cos(arg)).sum(axis=-1)
        if self.rate is not None:
            q_ref = q_ref + self.rate * np.asarray(t, float)[..., None]
            v_ref = v_ref + self.rate
        a_ref = -(As * self.omega**2).sum(axis=-1)
        return q_ref, v_ref, a_ref


def sample_sum_of_sines(
    rng: np.random.Generator,
    center_low: np.ndarray,
    center_high: np.ndarray,
    max_amplitude: np.ndarray,
    omega_range: tuple[float, float],
    n_components: int = 3,
    rate_range: tuple[float, float] | None = None,
) -> SumOfSines:
    """Draw a :class:`SumOfSines` reference.

    The centre is uniform in ``[center_low, center_high]``; each coordinate's
    total amplitude ``sum_k |A_k|`` is uniform in ``[max_amplitude / 2,
    max_amplitude]``, split among the components by Dirichlet(1) weights;
    frequencies are uniform in ``omega_range`` [rad/s]; phases uniform; the
    mean rate, if ``rate_range`` is given, uniform in it [rad/s].

    Parameters
    ----------
    rng : numpy.random.Generator
    center_low, center_high, max_amplitude : array_like, shape (n,)
    omega_range : (float, float)
    n_components : int

    Returns
    -------
    SumOfSines
    """
    center_low = np.asarray(center_low, float)
    center_high = np.asarray(center_high, float)
    max_amplitude = np.asarray(max_amplitude, float)
    n = center_low.shape[0]
    center = rng.uniform(center_low, center_high)
    total = rng.uniform(0.5, 1.0, size=n) * max_amplitude
    weights = rng.dirichlet(np.ones(n_components), size=n)
    amplitude = total[:, None] * weights
    omega = rng.uniform(omega_range[0], omega_range[1], size=(n, n_components))
    phase = rng.uniform(0.0, 2 * np.pi, size=(n, n_components))
    rate = None if rate_range is None else rng.uniform(rate_range[0], rate_range[1], size=n)
    return SumOfSines(center, amplitude, omega, phase, rate)
