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
from typing import Any

from ..dynamics.compiled import aligned
from ..dynamics.jit import njit
from ..dynamics.trig import in_range, sincos, sincos_libm
from .draws import dirichlet_ones_of, uniform_of
from .stacking import tree_pick
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
        times = np.empty(lead)  # the times of every member, a new contiguous array
        times[...] = t
        out = np.empty((3,) + columns[0].shape)
        sum_of_sines_columns(times.reshape(-1), *columns, *out)
        n = self.center.shape[-1]
        return tuple(x.T.reshape(lead + (n,)) for x in out)

    #: batches of at least this many members get their columns on a 64-byte boundary
    #: (:func:`~mbs_envs.dynamics.compiled.aligned`: read by SIMD loops every step); smaller ones
    #: (resets of a few members, single envs) a plain copy
    ALIGN_FROM = 64

    def columns(self, shape: tuple = ()) -> tuple[np.ndarray, ...]:
        """``(center, rate, amplitude, omega, phase)`` broadcast to times of ``shape``,
        flattened to ``L`` members and laid out in contiguous columns ``(n, L)``,
        ``(n, K, L)`` as :func:`sum_of_sines_columns` reads them (a zero rate when there is none);
        new, writable arrays."""
        n, K = self.amplitude.shape[-2:]
        own = self.center.shape[:-1]  # the references' own leading shape (members)
        rate = np.zeros(own + (n,)) if self.rate is None else self.rate
        fields = (self.center, rate, self.amplitude, self.omega, self.phase)
        lead = np.broadcast_shapes(shape, own)
        if lead != own:  # times beyond the references' shape (a reference at many times): broadcast
            fields = tuple(np.broadcast_to(x, lead + x.shape[len(own) :]) for x in fields)
        L = int(np.prod(lead, dtype=np.int64))
        copy = aligned if L >= self.ALIGN_FROM else (lambda x: np.array(x, float, order="C"))

        def columns(x):
            rows = x.reshape((L,) + x.shape[len(lead) :])
            return copy(rows.transpose(tuple(range(1, rows.ndim)) + (0,)))  # members last

        return tuple(columns(x) for x in fields)


def sample_sum_of_sines(rng: np.random.Generator, *args: Any, **kwargs: Any) -> SumOfSines:
    """Draw one :class:`SumOfSines` reference from ``rng``: :func:`sample_sums_of_sines` with one generator (the
    other arguments as there)."""
    return tree_pick(sample_sums_of_sines([rng], *args, **kwargs), 0)


def sample_sums_of_sines(
    rngs: list[np.random.Generator],
    center_low: np.ndarray,
    center_high: np.ndarray,
    max_amplitude: np.ndarray,
    omega_range: tuple[float, float],
    n_components: int = 3,
    rate_range: tuple[float, float] | None = None,
) -> SumOfSines:
    """Draw ``L = len(rngs)`` :class:`SumOfSines` references, stacked, member ``i`` from ``rngs[i]``.

    The centre is uniform in ``[center_low, center_high]``; each coordinate's
    total amplitude ``sum_k |A_k|`` is uniform in ``[max_amplitude / 2,
    max_amplitude]``, split among the components by Dirichlet(1) weights;
    frequencies are uniform in ``omega_range`` [rad/s]; phases uniform; the
    mean rate, if ``rate_range`` is given, uniform in it [rad/s]. Each member's
    numbers are drawn in that order from its own generator (the same draws
    whatever ``L``, and numpy's ``uniform`` and ``dirichlet`` draws bit for bit:
    :mod:`mbs_envs.envs.draws`); the rest is computed for all members at once.

    Parameters
    ----------
    rngs : list of numpy.random.Generator
    center_low, center_high, max_amplitude : array_like, shape (n,)
    omega_range : (float, float)
    n_components : int
    rate_range : (float, float), optional

    Returns
    -------
    SumOfSines
        Fields of shape ``(L, n)`` and ``(L, n, n_components)``.
    """
    center_low = np.asarray(center_low, float)
    center_high = np.asarray(center_high, float)
    max_amplitude = np.asarray(max_amplitude, float)
    L, n, K = len(rngs), center_low.shape[0], n_components
    nr = 0 if rate_range is None else n
    first, exps, last = np.empty((L, 2 * n)), np.empty((L, n, K)), np.empty((L, 2 * n * K + nr))
    for i, rng in enumerate(rngs):  # numpy's draws (:mod:`mbs_envs.envs.draws`), three calls a member
        first[i] = rng.random(2 * n)  # centre, total amplitude
        exps[i] = rng.standard_exponential((n, K))  # the Dirichlet(1) weights
        last[i] = rng.random(2 * n * K + nr)  # frequencies, phases, rates
    center = uniform_of(first[:, :n], center_low, center_high)
    total = uniform_of(first[:, n:], 0.5, 1.0) * max_amplitude
    amplitude = total[..., None] * dirichlet_ones_of(exps)
    omega = uniform_of(last[:, : n * K].reshape(L, n, K), omega_range[0], omega_range[1])
    phase = uniform_of(last[:, n * K : 2 * n * K].reshape(L, n, K), 0.0, 2 * np.pi)
    rate = None if rate_range is None else uniform_of(last[:, 2 * n * K :], rate_range[0], rate_range[1])
    return SumOfSines(center, amplitude, omega, phase, rate)
