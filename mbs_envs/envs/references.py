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

from ..dynamics.jit import njit
from ..dynamics.trig import in_range, sincos, sincos_libm
import numpy as np


@njit(inline="always")
def _components(t, amplitude, omega, phase, i, k, b, s, c):  # pragma: no cover - compiled
    """Component ``k`` of coordinate ``i``, member ``b``, given ``s, c = sin, cos(w t + p)``:
    its terms ``(A sin, A w cos, A sin w^2)`` of ``q_ref, v_ref, -a_ref``."""
    w = omega[i, k, b]
    As = amplitude[i, k, b] * s
    return As, amplitude[i, k, b] * w * c, As * w**2


@njit
def sum_of_sines_columns(t, center, rate, amplitude, omega, phase, q_ref, v_ref, a_ref):  # pragma: no cover
    """The reference formulas (module docstring) of ``B`` members at their times ``t``, in columns.

    One SIMD pass (:func:`mbs_envs.dynamics.trig.sincos`); if some argument ``w t + p`` is beyond
    its range, a second pass of the whole batch with libm's there (the same bits either way).

    Parameters
    ----------
    t : ndarray, shape (B,)
        [s]
    center, rate : ndarray, shape (n, B)
    amplitude, omega, phase : ndarray, shape (n, K, B)
    q_ref, v_ref, a_ref : ndarray, shape (n, B)
        Outputs [rad], [rad/s], [rad/s^2].
    """
    n, K, B = amplitude.shape
    ok = True
    for i in range(n):
        for b in range(B):
            q_ref[i, b] = 0.0
            v_ref[i, b] = 0.0
            a_ref[i, b] = 0.0
        for k in range(K):
            for b in range(B):
                x = omega[i, k, b] * t[b] + phase[i, k, b]
                s, c = sincos(x)
                ok &= in_range(x)
                dq, dv, da = _components(t, amplitude, omega, phase, i, k, b, s, c)
                q_ref[i, b] += dq
                v_ref[i, b] += dv
                a_ref[i, b] += da
        for b in range(B):
            q_ref[i, b] = center[i, b] + q_ref[i, b] + rate[i, b] * t[b]
            v_ref[i, b] = v_ref[i, b] + rate[i, b]
            a_ref[i, b] = -a_ref[i, b]
    if ok:
        return
    for i in range(n):  # some argument beyond the SIMD range: again, libm's sincos there
        for b in range(B):
            q_ref[i, b] = 0.0
            v_ref[i, b] = 0.0
            a_ref[i, b] = 0.0
        for k in range(K):
            for b in range(B):
                x = omega[i, k, b] * t[b] + phase[i, k, b]
                s, c = sincos(x) if in_range(x) else sincos_libm(x)
                dq, dv, da = _components(t, amplitude, omega, phase, i, k, b, s, c)
                q_ref[i, b] += dq
                v_ref[i, b] += dv
                a_ref[i, b] += da
        for b in range(B):
            q_ref[i, b] = center[i, b] + q_ref[i, b] + rate[i, b] * t[b]
            v_ref[i, b] = v_ref[i, b] + rate[i, b]
            a_ref[i, b] = -a_ref[i, b]


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
        columns = self.columns(t.shape)
        lead = np.broadcast_shapes(t.shape, self.center.shape[:-1])
        out = np.empty((3,) + columns[0].shape)
        sum_of_sines_columns(np.require(np.broadcast_to(t, lead).reshape(-1), requirements=("C", "W")), *columns, *out)
        n = self.center.shape[-1]
        return tuple(x.T.reshape(lead + (n,)) for x in out)

    def columns(self, shape: tuple = ()) -> tuple[np.ndarray, ...]:
        """``(center, rate, amplitude, omega, phase)`` broadcast to times of ``shape``,
        flattened to ``L`` members and laid out in contiguous columns ``(n, L)``,
        ``(n, K, L)`` as :func:`sum_of_sines_columns` reads them (a zero rate when there is none);
        new, writable arrays."""
        n, K = self.amplitude.shape[-2:]
        rate = np.zeros(n) if self.rate is None else self.rate
        if not shape and self.center.ndim == 1:  # one reference at one time (resets, single envs): no broadcasting
            return tuple(np.array(x, float)[..., None] for x in (self.center, rate, self.amplitude, self.omega, self.phase))
        lead = np.broadcast_shapes(shape, self.center.shape[:-1])

        def columns(x, tail):
            rows = np.broadcast_to(x, lead + tail).reshape((-1,) + tail)
            return np.array(np.moveaxis(rows, 0, -1), float, order="C")

        return (*(columns(x, (n,)) for x in (self.center, rate)),
                *(columns(x, (n, K)) for x in (self.amplitude, self.omega, self.phase)))  # fmt: skip


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
