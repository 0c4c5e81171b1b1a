"""Constraint machinery for constrained scenes only (serial scenes never import it).

Equations (PHYSICS.md (1), (2)) with ``f = B u - h(q, v)``:

    M a = f + Psi^T lam,        Psi a = gamma,
    gamma = -dPsi v                                   (exact constraint acceleration)
          - 2 alpha Psi v - beta^2 phi                (Baumgarte terms, optional)

Eliminating ``a`` gives the Schur complement ``S = Psi M^-1 Psi^T`` and
``S lam = gamma - Psi M^-1 f``. Near a rank loss of ``Psi`` (a change point),
``S`` is singular: it is inverted by its symmetric eigendecomposition with
eigenvalues below ``rcond * max`` dropped (the least-squares, minimum-norm
multipliers), and its condition number is reported.

All functions are batched over leading dimensions.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .linalg import batched_matvec, cholesky_solve_columns

#: Relative eigenvalue cut-off of the Schur complement pseudo-inverse.
RCOND = 1e-12


def symmetric_pinv_solve(S: np.ndarray, r: np.ndarray, rcond: float = RCOND) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-norm least-squares solution of ``S x = r`` for symmetric PSD ``S``.

    Parameters
    ----------
    S : ndarray, shape (..., k, k)
    r : ndarray, shape (..., k)
    rcond : float
        Eigenvalues below ``rcond * max(eigenvalues)`` are treated as zero.

    Returns
    -------
    x : ndarray, shape (..., k)
    cond : ndarray, shape (...)
        ``max / min`` eigenvalue of ``S`` (inf when singular).
    """
    bad = ~(np.all(np.isfinite(S), axis=(-2, -1)) & np.all(np.isfinite(r), axis=-1))
    if np.any(bad):  # a blown-up batch member: NaN for it, the others solved
        S = np.where(bad[..., None, None], np.eye(S.shape[-1]), S)
        r = np.where(bad[..., None], 0.0, r)
        x, cond = symmetric_pinv_solve(S, r, rcond)
        return np.where(bad[..., None], np.nan, x), np.where(bad, np.nan, cond)
    w, V = np.linalg.eigh(S)
    w_max = np.max(np.abs(w), axis=-1, keepdims=True)
    keep = w > rcond * w_max
    w_inv = np.where(keep, 1.0 / np.where(keep, w, 1.0), 0.0)
    x = batched_matvec(V, w_inv * np.einsum("...ji,...j->...i", V, r))
    with np.errstate(divide="ignore"):
        cond = np.where(w[..., 0] > 0, w_max[..., 0] / np.where(w[..., 0] > 0, w[..., 0], 1.0), np.inf)
    return x, cond


def constrained_accelerations(
    M: np.ndarray, f: np.ndarray, Psi: np.ndarray, gamma: np.ndarray, rcond: float = RCOND
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve ``M a = f + Psi^T lam``, ``Psi a = gamma`` by the Schur complement.

    ``M`` is factorized once by Cholesky (``M^-1 f`` and ``M^-1 Psi^T`` from it).

    Parameters
    ----------
    M : ndarray, shape (..., n, n)
        Mass matrix (symmetric positive definite).
    f : ndarray, shape (..., n)
        Applied minus bias forces, ``B u - h``.
    Psi : ndarray, shape (..., k, n)
        Constraint Jacobian.
    gamma : ndarray, shape (..., k)
        Required constraint acceleration ``Psi a``.

    Returns
    -------
    a : ndarray, shape (..., n)
    lam : ndarray, shape (..., k)
    cond : ndarray, shape (...)
        Condition number of ``S = Psi M^-1 Psi^T``.
    """
    PsiT = np.swapaxes(Psi, -1, -2)
    shape = np.broadcast_shapes(f.shape[:-1], PsiT.shape[:-2])
    # one Cholesky factorization, k + 1 right-hand sides [f, Psi^T]
    rhs = np.concatenate(
        [np.broadcast_to(f[..., :, None], shape + f.shape[-1:] + (1,)), np.broadcast_to(PsiT, shape + PsiT.shape[-2:])],
        axis=-1,
    )
    sol = cholesky_solve_columns(M, rhs)
    Minv_f, Minv_PsiT = sol[..., 0], sol[..., 1:]
    S = Psi @ Minv_PsiT
    lam, cond = symmetric_pinv_solve(S, gamma - batched_matvec(Psi, Minv_f), rcond)
    a = Minv_f + batched_matvec(Minv_PsiT, lam)
    return a, lam, cond


def gauss_newton_projection(
    q: np.ndarray,
    residual: Any,
    jacobian: Any,
    tol: float = 1e-12,
    max_iter: int = 20,
) -> tuple[np.ndarray, np.ndarray]:
    """Project ``q`` onto ``phi(q) = 0`` by Gauss-Newton (minimum-norm steps).

    ``q <- q - Psi^T (Psi Psi^T)^+ phi`` until ``|phi| <= tol``.

    Parameters
    ----------
    q : ndarray, shape (..., n)
    residual : callable ``phi(q) -> (..., k)``
    jacobian : callable ``Psi(q) -> (..., k, n)`` (rows of ``phi``'s Jacobian)
    tol : float
    max_iter : int

    Returns
    -------
    q : ndarray, shape (..., n)
    phi : ndarray, shape (..., k)
        The residual at the returned ``q``.
    """
    q = np.array(q, dtype=float)
    phi = residual(q)
    for _ in range(max_iter):
        active = np.any(np.abs(phi) > tol, axis=-1)  # members of a batch stop on their own
        if not np.any(active):
            break
        Psi = jacobian(q)
        y, _ = symmetric_pinv_solve(Psi @ np.swapaxes(Psi, -1, -2), phi)
        q = q - np.where(active[..., None], np.einsum("...ki,...k->...i", Psi, y), 0.0)
        phi = residual(q)
    return q, phi


def project_velocities(v: np.ndarray, M: np.ndarray, Psi: np.ndarray) -> np.ndarray:
    """Project ``v`` onto ``Psi v = 0`` in the kinetic-energy metric.

    ``v+ = v - M^-1 Psi^T (Psi M^-1 Psi^T)^+ Psi v``: the constraint impulse
    that removes the violating velocity with the least change of kinetic energy.

    Parameters
    ----------
    v : ndarray, shape (..., n)
    M : ndarray, shape (..., n, n)
    Psi : ndarray, shape (..., k, n)
    """
    a, _, _ = constrained_accelerations(M, np.zeros(np.broadcast_shapes(v.shape, M.shape[:-1])), Psi, -batched_matvec(Psi, v))
    return v + a


@dataclasses.dataclass(frozen=True)
class Stabilization:
    """How a simulation keeps a constrained model on its constraints.

    Attributes
    ----------
    kind : {"projection", "baumgarte", "none"}
        ``projection``: after every step, ``q`` is projected onto ``phi = 0``
        (Gauss-Newton) and ``v`` onto ``Psi v = 0``. ``baumgarte``: the terms
        ``2 alpha Psi v + beta^2 phi`` are added to the constraint acceleration.
        ``none``: the index-1 equations alone (the residual drifts).
    alpha, beta : float
        Baumgarte gains [1/s] (used by ``baumgarte`` only).
    tol : float
        Projection tolerance on ``|phi|`` [m].
    """

    kind: str = "projection"
    alpha: float = 10.0
    beta: float = 10.0
    tol: float = 1e-12

    KINDS = ("projection", "baumgarte", "none")

    def __post_init__(self) -> None:
        if self.kind not in self.KINDS:
            raise ValueError(f"stabilization must be one of {list(self.KINDS)}, got {self.kind!r}")
        for name in ("alpha", "beta", "tol"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"stabilization {name} must be finite and >= 0, got {value!r}")

    @property
    def gains(self) -> tuple[float, float]:
        """``(alpha, beta)`` in effect in the dynamics (zero unless Baumgarte)."""
        return (self.alpha, self.beta) if self.kind == "baumgarte" else (0.0, 0.0)
