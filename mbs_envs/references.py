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

from .jit import njit
import numpy as np


@njit
def sum_of_sines_member(t, center, rate, amplitude, omega, phase, b, q_ref, v_ref, a_ref):  # pragma: no cover
    """The reference formulas (module docstring) of row ``b`` at time ``t``, written into row ``b`` of the outputs.

    Parameters
    ----------
    t : float
        [s]
    center, rate : ndarray, shape (L, n)
    amplitude, omega, phase : ndarray, shape (L, n, K)
    b : int
        The row (compiled callers index rows rather than take views).
    q_ref, v_ref, a_ref : ndarray, shape (L, n)
        Outputs [rad], [rad/s], [rad/s^2].
    """
    n, K = amplitude.shape[1], amplitude.shape[2]
    for i in range(n):
        sq = 0.0
        sv = 0.0
        sa = 0.0
        for k in range(K):
            w = omega[b, i, k]
            arg = w * t + phase[b, i, k]
            As = amplitude[b, i, k] * np.sin(arg)
            sq += As
            sv += amplitude[b, i, k] * w * np.cos(arg)
            sa += As * w**2
        q_ref[b, i] = center[b, i] + sq + rate[b, i] * t
        v_ref[b, i] = sv + rate[b, i]
        a_ref[b, i] = -sa


@njit
def _sum_of_sines_rows(t, center, rate, amplitude, omega, phase, q_ref, v_ref, a_ref):  # pragma: no cover
    for r in range(t.shape[0]):
        sum_of_sines_member(t[r], center, rate, amplitude, omega, phase, r, q_ref, v_ref, a_ref)


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
        t = np.asarray(t, float)
        rows = self.rows(t.shape)
        lead = np.broadcast_shapes(t.shape, self.center.shape[:-1])
        out = np.empty((3,) + rows[0].shape)
        _sum_of_sines_rows(np.broadcast_to(t, lead).reshape(-1), *rows, out[0], out[1], out[2])
        n = self.center.shape[-1]
        return tuple(x.reshape(lead + (n,)) for x in out)

    def rows(self, shape: tuple = ()) -> tuple[np.ndarray, ...]:
        """``(center, rate, amplitude, omega, phase)`` broadcast to times of ``shape`` and
        flattened to rows ``(L, n)``, ``(L, n, K)`` (a zero rate when there is none)."""
        lead = np.broadcast_shapes(shape, self.center.shape[:-1])
        n, K = self.amplitude.shape[-2:]
        rate = np.zeros(n) if self.rate is None else self.rate
        vec = [np.broadcast_to(x, lead + (n,)).reshape(-1, n) for x in (self.center, rate)]
        mat = [np.broadcast_to(x, lead + (n, K)).reshape(-1, n, K) for x in (self.amplitude, self.omega, self.phase)]
        return (*vec, *mat)


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
