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

from ..dynamics.compiled import aligned
from ..dynamics.jit import njit
from ..dynamics.trig import in_range, sincos, sincos_libm
import numpy as np


@njit(inline="always")
def _components(A, w, s, c):  # pragma: no cover - compiled
    """One component's terms ``(A sin, A w cos, A sin w^2)`` of ``q_ref, v_ref, -a_ref``, given
    ``s, c = sin, cos(w t + p)``."""
    As = A * s
    return As, A * w * c, As * w**2


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
    if not _sums(t, center, rate, amplitude, omega, phase, q_ref, v_ref, a_ref, False):
        _sums(t, center, rate, amplitude, omega, phase, q_ref, v_ref, a_ref, True)


@njit(inline="always")
def _sums(t, center, rate, amplitude, omega, phase, q_ref, v_ref, a_ref, exact):  # pragma: no cover - compiled
    """:func:`sum_of_sines_columns`'s pass: with the SIMD sincos (``exact`` False; returns whether
    every argument was in its range), or with libm's beyond the range (``exact`` True). A constant
    ``exact`` at each (inlined) call: each pass is a loop without that branch. Rows are taken as
    1-d views, whose loops LLVM vectorizes (it did not vectorize the 3-d indexing)."""
    n, K, B = amplitude.shape
    ok = True
    for i in range(n):
        qi, vi, ai = q_ref[i], v_ref[i], a_ref[i]
        for b in range(B):
            qi[b] = 0.0
            vi[b] = 0.0
            ai[b] = 0.0
        for k in range(K):
            Ak, wk, pk = amplitude[i, k], omega[i, k], phase[i, k]
            for b in range(B):
                x = wk[b] * t[b] + pk[b]
                if exact:
                    s, c = sincos(x) if in_range(x) else sincos_libm(x)
                else:
                    s, c = sincos(x)
                    ok &= in_range(x)
                dq, dv, da = _components(Ak[b], wk[b], s, c)
                qi[b] += dq
                vi[b] += dv
                ai[b] += da
        ci, ri = center[i], rate[i]
        for b in range(B):
            qi[b] = ci[b] + qi[b] + ri[b] * t[b]
            vi[b] = vi[b] + ri[b]
            ai[b] = -ai[b]
    return ok


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
            return aligned(np.moveaxis(rows, 0, -1))  # on a 64-byte boundary: read by SIMD loops every step

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
