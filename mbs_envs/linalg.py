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


def cholesky_solve_columns(M: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Solve ``M X = B`` for symmetric positive definite ``M`` and several right-hand sides.

    ``M = L L^T`` is factorized once by LAPACK (``numpy.linalg.cholesky``,
    batched); the triangular solves ``L Y = B``, ``L^T X = Y`` are vectorized
    over the batch and the columns, looping over the (small) dimension ``n``.

    Parameters
    ----------
    M : ndarray, shape (..., n, n)
        Symmetric positive definite matrices (only the lower triangle is read).
    B : ndarray, shape (..., n, r)
        Right-hand sides as columns; batch dimensions broadcast against ``M``'s.

    Returns
    -------
    X : ndarray, shape (broadcast(...), n, r)

    Raises
    ------
    numpy.linalg.LinAlgError
        If a matrix is not positive definite (a non-physical mass matrix).
    """
    L = np.linalg.cholesky(M)
    n = L.shape[-1]
    shape = np.broadcast_shapes(L.shape[:-2], B.shape[:-2])
    if L.shape[:-2] != shape:
        L = np.broadcast_to(L, shape + (n, n))
    Y = np.array(np.broadcast_to(B, shape + B.shape[-2:]), dtype=float)
    for i in range(n):  # forward substitution, L Y = B
        if i:
            Y[..., i, :] -= np.einsum("...j,...jr->...r", L[..., i, :i], Y[..., :i, :])
        Y[..., i, :] /= L[..., i, i, None]
    for i in range(n - 1, -1, -1):  # back substitution, L^T X = Y
        if i < n - 1:
            Y[..., i, :] -= np.einsum("...j,...jr->...r", L[..., i + 1 :, i], Y[..., i + 1 :, :])
        Y[..., i, :] /= L[..., i, i, None]
    return Y


def cholesky_solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``M x = b`` for symmetric positive definite ``M`` by Cholesky.

    Parameters
    ----------
    M : ndarray, shape (..., n, n)
    b : ndarray, shape (..., n)
        Batch dimensions broadcast against ``M``'s.

    Returns
    -------
    x : ndarray, shape (broadcast(...), n)

    See Also
    --------
    cholesky_solve_columns : the same with several right-hand sides.
    """
    return cholesky_solve_columns(M, b[..., None])[..., 0]
