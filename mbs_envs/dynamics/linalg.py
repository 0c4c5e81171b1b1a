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


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product ``a x b`` over leading batch dimensions.

    The same products and differences as :func:`numpy.cross`, spelt out, without
    that function's axis bookkeeping (the larger part of its time on 3-vectors).

    Parameters
    ----------
    a, b : ndarray, shape (..., 3), broadcastable

    Returns
    -------
    ndarray, shape (..., 3)
    """
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _sqrt_pivot(d: np.ndarray) -> np.ndarray:
    """``sqrt(d)``, NaN where ``d <= 0`` (not positive definite)."""
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.where(d > 0, d, np.nan))


def _cholesky_2x2_3x3(M: np.ndarray) -> np.ndarray:
    """Closed-form Cholesky of a batch of 2 x 2 or 3 x 3 matrices, vectorized over the batch.

    LAPACK pays a per-matrix call; for the scenes' small mass matrices in a
    large batch a handful of whole-array operations is several times faster.
    A non-positive pivot gives NaN for that member.
    """
    n = M.shape[-1]
    L = np.zeros(M.shape)
    l00 = _sqrt_pivot(M[..., 0, 0])
    l10 = M[..., 1, 0] / l00
    L[..., 0, 0], L[..., 1, 0] = l00, l10
    L[..., 1, 1] = l11 = _sqrt_pivot(M[..., 1, 1] - l10 * l10)
    if n == 3:
        l20 = M[..., 2, 0] / l00
        l21 = (M[..., 2, 1] - l20 * l10) / l11
        L[..., 2, 0], L[..., 2, 1] = l20, l21
        L[..., 2, 2] = _sqrt_pivot(M[..., 2, 2] - l20 * l20 - l21 * l21)
    return L


def _substitute_small(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``L L^T X = B`` for 2 x 2 or 3 x 3 lower factors, by written-out substitution."""
    l = lambda i, j: L[..., i, j, None]  # noqa: E731  (broadcast over the columns of B)
    b = [B[..., i, :] for i in range(L.shape[-1])]
    if L.shape[-1] == 2:
        y0 = b[0] / l(0, 0)
        y1 = (b[1] - l(1, 0) * y0) / l(1, 1)
        x1 = y1 / l(1, 1)
        x0 = (y0 - l(1, 0) * x1) / l(0, 0)
        return np.stack([x0, x1], axis=-2)
    y0 = b[0] / l(0, 0)
    y1 = (b[1] - l(1, 0) * y0) / l(1, 1)
    y2 = (b[2] - l(2, 0) * y0 - l(2, 1) * y1) / l(2, 2)
    x2 = y2 / l(2, 2)
    x1 = (y1 - l(2, 1) * x2) / l(1, 1)
    x0 = (y0 - l(1, 0) * x1 - l(2, 0) * x2) / l(0, 0)
    return np.stack([x0, x1, x2], axis=-2)


def per_member(f, A: np.ndarray, fill: float) -> np.ndarray:
    """``f`` (a LAPACK matrix function) on each matrix of a batch ``A`` of shape ``(..., n, n)``.

    The fallback after a batched call raised ``LinAlgError``: members where
    ``f`` fails get ``fill`` in every entry, the others their own result.
    """
    flat = A.reshape((-1,) + A.shape[-2:])
    out = np.full(flat.shape, fill, dtype=float)
    for k, Ak in enumerate(flat):
        try:
            out[k] = f(Ak)
        except np.linalg.LinAlgError:
            pass
    return out.reshape(A.shape)


def cholesky_lower(M: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of a batch of symmetric positive definite matrices.

    A batch member that is not positive definite (a blown-up state) gets a
    NaN factor instead of failing the whole batch, so one diverging
    environment of a vector env does not stop the others. 2 x 2 and 3 x 3
    matrices (the scenes' mass matrices) are factorized in closed form
    (:func:`_cholesky_2x2_3x3`, NaN where not positive definite), everything
    else by LAPACK.

    Raises
    ------
    numpy.linalg.LinAlgError
        For a single (unbatched) large matrix that is not positive definite.
    """
    if M.shape[-1] in (2, 3):
        return _cholesky_2x2_3x3(M)
    try:
        return np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        if M.ndim == 2:
            raise
    return per_member(np.linalg.cholesky, M, np.nan)


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
        If a single matrix is not positive definite (a non-physical mass
        matrix); in a batch, such members get NaN (:func:`cholesky_lower`).
    """
    L = cholesky_lower(M)
    n = L.shape[-1]
    if n in (2, 3):
        return _substitute_small(L, B)
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
