"""Batched dense linear algebra used by the models.

Every function takes arrays with arbitrary leading batch dimensions ``(...)``
and works on the trailing matrix/vector dimensions, so one call serves a single
state, a vector of environments and a parameter sweep alike.
"""

from __future__ import annotations

import numpy as np


def batched_matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Matrix-vector product ``A x`` over leading batch dimensions.

    Parameters
    ----------
    A : ndarray, shape (..., m, n)
    x : ndarray, shape (..., n)

    Returns
    -------
    ndarray, shape (..., m)
    """
    return np.einsum("...ij,...j->...i", A, x)


def cholesky_solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``M x = b`` for symmetric positive definite ``M`` by Cholesky.

    ``M = L L^T`` is factorized by LAPACK (``numpy.linalg.cholesky``, batched);
    the two triangular solves ``L y = b`` and ``L^T x = y`` are vectorized over
    the batch with a loop over the (small) matrix dimension ``n``.

    Parameters
    ----------
    M : ndarray, shape (..., n, n)
        Symmetric positive definite matrices (only the lower triangle is read).
    b : ndarray, shape (..., n)
        Right-hand sides; batch dimensions broadcast against ``M``'s.

    Returns
    -------
    x : ndarray, shape (broadcast(...), n)

    Raises
    ------
    numpy.linalg.LinAlgError
        If a matrix is not positive definite (a non-physical mass matrix).
    """
    L = np.linalg.cholesky(M)
    n = L.shape[-1]
    shape = np.broadcast_shapes(L.shape[:-1], b.shape)
    L = np.broadcast_to(L, shape + (n,))
    y = np.array(np.broadcast_to(b, shape), dtype=float)
    for i in range(n):  # forward substitution, L y = b
        if i:
            y[..., i] -= np.einsum("...j,...j->...", L[..., i, :i], y[..., :i])
        y[..., i] /= L[..., i, i]
    for i in range(n - 1, -1, -1):  # back substitution, L^T x = y
        if i < n - 1:
            y[..., i] -= np.einsum("...j,...j->...", L[..., i + 1 :, i], y[..., i + 1 :])
        y[..., i] /= L[..., i, i]
    return y
