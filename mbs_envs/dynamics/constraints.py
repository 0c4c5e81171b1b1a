"""Constraint machinery for constrained scenes only (serial scenes never import it).

Equations (docs/physics.md §1-§2) with ``f = B u - h(q, v)``:

    M a = f + Psi^T lam,        Psi a = gamma,
    gamma = -dPsi v                                   (exact constraint acceleration)
          - 2 alpha Psi v - beta^2 phi                (Baumgarte terms, optional)

Eliminating ``a`` gives the Schur complement ``S = Psi M^-1 Psi^T`` and
``S lam = gamma - Psi M^-1 f``. Near a rank loss of ``Psi`` (a change point),
``S`` is singular: it is inverted by its symmetric eigendecomposition with
eigenvalues below ``rcond * max`` dropped (the least-squares, minimum-norm
multipliers), and its condition number is reported. The solve runs compiled,
member by member (:func:`constrained_accelerations`).

All functions are batched over leading dimensions.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .compiled import cholesky_columns, cholesky_solve_columns
from .jit import njit
from .linalg import batched_matvec

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
    k = S.shape[-1]
    lead = np.broadcast_shapes(S.shape[:-2], r.shape[:-1])
    Sr = np.ascontiguousarray(np.broadcast_to(S, lead + (k, k)).reshape(-1, k, k), dtype=float)
    rr = np.ascontiguousarray(np.broadcast_to(r, lead + (k,)).reshape(-1, k), dtype=float)
    x, cond = np.empty(rr.shape), np.empty(rr.shape[0])
    _pinv_rows(Sr, rr, float(rcond), x, cond)
    return x.reshape(lead + (k,)), cond.reshape(lead)


@njit
def _pinv_rows(S, r, rcond, x, cond):  # pragma: no cover - compiled
    """:func:`_pinv_solve` for every row (B, k, k) / (B, k); NaN for a member with non-finite input."""
    for b in range(r.shape[0]):
        ok = True
        for i in range(r.shape[1]):
            ok &= np.isfinite(r[b, i])
            for j in range(r.shape[1]):
                ok &= np.isfinite(S[b, i, j])
        if ok:
            cond[b] = _pinv_solve(S[b], r[b], rcond, x[b])
        else:
            x[b, :] = np.nan
            cond[b] = np.nan


def constrained_accelerations(
    M: np.ndarray, f: np.ndarray, Psi: np.ndarray, gamma: np.ndarray, rcond: float = RCOND, conditioning: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve ``M a = f + Psi^T lam``, ``Psi a = gamma`` by the Schur complement.

    Per member, compiled (:func:`_schur_kernel`): ``M = L L^T`` (Cholesky), ``M^-1 f``
    and ``M^-1 Psi^T`` from it, ``S = Psi M^-1 Psi^T`` and its pseudo-inverse by the
    symmetric eigendecomposition (LAPACK's ``syevd``, as :func:`symmetric_pinv_solve`).
    A member whose ``M`` is not positive definite or whose inputs are not finite
    (a blow-up) gets NaN; the others are unaffected.

    With ``conditioning=False`` (when ``cond`` is not wanted) a member whose ``S``
    is provably well conditioned, ``trace(S) trace(S^-1) < 1 / rcond`` (which bounds
    ``max / min`` eigenvalue, so the pseudo-inverse drops nothing), is solved by the
    Cholesky factors of ``S`` instead: the same multipliers to rounding, while the
    eigendecomposition is most of the solve's cost; its ``cond`` is NaN. The choice is made per
    member, so results do not depend on the batch.

    Parameters
    ----------
    M : ndarray, shape (..., n, n)
        Mass matrix (symmetric positive definite; the lower triangle is read).
    f : ndarray, shape (..., n)
        Applied minus bias forces, ``B u - h``.
    Psi : ndarray, shape (..., k, n)
        Constraint Jacobian.
    gamma : ndarray, shape (..., k)
        Required constraint acceleration ``Psi a``.
    rcond : float
        Relative eigenvalue cut-off of the pseudo-inverse.
    conditioning : bool
        Whether ``cond`` is wanted for every member (see above).

    Returns
    -------
    a : ndarray, shape (..., n)
    lam : ndarray, shape (..., k)
    cond : ndarray, shape (...)
        Condition number of ``S = Psi M^-1 Psi^T`` (NaN where not computed).
    """
    n, k = M.shape[-1], Psi.shape[-2]
    lead = np.broadcast_shapes(M.shape[:-2], f.shape[:-1], Psi.shape[:-2], gamma.shape[:-1])

    def rows(x: np.ndarray, tail: tuple[int, ...]) -> np.ndarray:
        return np.ascontiguousarray(np.broadcast_to(x, lead + tail).reshape((-1,) + tail), dtype=float)

    Mr, fr, Pr, gr = rows(M, (n, n)), rows(f, (n,)), rows(Psi, (k, n)), rows(gamma, (k,))
    B = Mr.shape[0]
    a, lam, cond = np.empty((B, n)), np.empty((B, k)), np.empty(B)
    _schur_kernel(Mr, fr, Pr, gr, float(rcond), bool(conditioning), a, lam, cond)
    return a.reshape(lead + (n,)), lam.reshape(lead + (k,)), cond.reshape(lead)


@njit
def schur_work(n, k):  # pragma: no cover - compiled
    """Work array of :func:`schur_member` for ``n`` coordinates and ``k`` constraint rows."""
    return np.empty(n * n + n * (k + 1) + 3 * k * k + 2 * k)


@njit
def schur_member(M, f, Psi, gamma, rcond, conditioning, work, a, lam):  # pragma: no cover - compiled
    """:func:`constrained_accelerations` of one member, the formulas every compiled path shares.

    ``M = L L^T`` (Cholesky), ``X = M^-1 [f, Psi^T]``, ``S = Psi M^-1 Psi^T``,
    ``r = gamma - Psi M^-1 f``; ``lam = S^-1 r`` by Cholesky where ``S`` is provably well
    conditioned and ``conditioning`` is False (:func:`_cholesky_solve_if_well_conditioned`),
    else ``S^+ r`` (:func:`_pinv_solve`); ``a = M^-1 (f + Psi^T lam)``.

    Parameters
    ----------
    M : ndarray, shape (n, n)
    f : ndarray, shape (n,)
    Psi : ndarray, shape (k, n)
    gamma : ndarray, shape (k,)
    rcond : float
    conditioning : bool
    work : ndarray
        :func:`schur_work` ``(n, k)``.
    a, lam : ndarray, shape (n,), (k,)
        Written; NaN (and the return value NaN) if ``M`` is not positive definite
        or an input is not finite.

    Returns
    -------
    float
        The condition number of ``S`` (NaN where not computed).
    """
    n = f.shape[0]
    k = gamma.shape[0]
    o = 0
    L = work[o : o + n * n].reshape((n, n))
    o += n * n
    X = work[o : o + n * (k + 1)].reshape((n, k + 1))  # columns: M^-1 f, then M^-1 Psi^T
    o += n * (k + 1)
    S = work[o : o + k * k].reshape((k, k))
    o += k * k
    R = work[o : o + k * k].reshape((k, k))
    o += k * k
    Rinv = work[o : o + k * k].reshape((k, k))
    o += k * k
    r = work[o : o + k]
    y = work[o + k : o + 2 * k]
    ok = _cholesky(M, L)  # M = L L^T
    for i in range(k):
        for p in range(n):
            ok &= np.isfinite(Psi[i, p])
        ok &= np.isfinite(gamma[i])
    for i in range(n):
        ok &= np.isfinite(f[i])
    if not ok:
        a[:] = np.nan
        lam[:] = np.nan
        return np.nan
    for i in range(n):
        X[i, 0] = f[i]
        for c in range(k):
            X[i, 1 + c] = Psi[c, i]
    for c in range(k + 1):  # L Y = X, then L^T X = Y
        for i in range(n):
            e = X[i, c]
            for p in range(i):
                e -= L[i, p] * X[p, c]
            X[i, c] = e / L[i, i]
        for i in range(n - 1, -1, -1):
            e = X[i, c]
            for p in range(i + 1, n):
                e -= L[p, i] * X[p, c]
            X[i, c] = e / L[i, i]
    for i in range(k):  # S = Psi M^-1 Psi^T, r = gamma - Psi M^-1 f
        e = gamma[i]
        for p in range(n):
            e -= Psi[i, p] * X[p, 0]
        r[i] = e
        for j in range(k):
            e = 0.0
            for p in range(n):
                e += Psi[i, p] * X[p, 1 + j]
            S[i, j] = e
    if not conditioning and _cholesky_solve_if_well_conditioned(S, r, rcond, R, Rinv, y):
        for i in range(k):
            lam[i] = y[i]
        cond = np.nan
    else:
        cond = _pinv_solve(S, r, rcond, lam)
    for i in range(n):
        e = X[i, 0]
        for j in range(k):
            e += X[i, 1 + j] * lam[j]
        a[i] = e
    return cond


@njit
def _cholesky(A, L):  # pragma: no cover - compiled
    """``A = L L^T`` from the lower triangle of symmetric ``A`` (n, n) into ``L``; False (``L``
    partly written) if ``A`` is not positive definite or not finite."""
    n = A.shape[0]
    for j in range(n):
        d = A[j, j]
        for p in range(j):
            d -= L[j, p] * L[j, p]
        if not d > 0.0:  # not positive definite, or NaN
            return False
        L[j, j] = np.sqrt(d)
        for i in range(j + 1, n):
            e = A[i, j]
            for p in range(j):
                e -= L[i, p] * L[j, p]
            L[i, j] = e / L[j, j]
    return True


@njit
def _schur_kernel(M, f, Psi, gamma, rcond, conditioning, a, lam, cond):  # pragma: no cover - compiled
    """:func:`schur_member` for rows: ``M`` (B, n, n), ``f`` (B, n), ``Psi`` (B, k, n),
    ``gamma`` (B, k); writes ``a`` (B, n), ``lam`` (B, k) and ``cond`` (B,)."""
    B, n = f.shape
    work = schur_work(n, gamma.shape[1])
    for b in range(B):
        cond[b] = schur_member(M[b], f[b], Psi[b], gamma[b], rcond, conditioning, work, a[b], lam[b])


@njit
def _pinv_solve(S, r, rcond, x):  # pragma: no cover - compiled
    """``x = S^+ r`` by the eigendecomposition of symmetric ``S`` (k, k), eigenvalues below
    ``rcond * max |w|`` dropped; returns ``max |w| / min w`` (inf if not positive)."""
    k = r.shape[0]
    w, V = np.linalg.eigh(S)
    w_max = 0.0
    for i in range(k):
        w_max = max(w_max, abs(w[i]))
    for i in range(k):
        x[i] = 0.0
    for j in range(k):  # x = V diag(w^+) V^T r
        if w[j] > rcond * w_max:
            e = 0.0
            for i in range(k):
                e += V[i, j] * r[i]
            e /= w[j]
            for i in range(k):
                x[i] += V[i, j] * e
    return w_max / w[0] if w[0] > 0.0 else np.inf


@njit
def _cholesky_solve_if_well_conditioned(S, r, rcond, R, Rinv, y):  # pragma: no cover - compiled
    """``y = S^-1 r`` by ``S = R R^T`` if ``trace(S) trace(S^-1) < 1 / rcond``; returns whether it did.

    The bound holds ``max / min`` eigenvalue of symmetric ``S`` (k, k) from above
    (``max <= trace S``, ``1 / min <= trace S^-1 = |R^-1|_F^2``), so where it is
    below ``1 / rcond`` the pseudo-inverse of :func:`_pinv_solve` is the inverse.
    ``R, Rinv`` (k, k) and ``y`` (k,) are work arrays.
    """
    k = r.shape[0]
    if not _cholesky(S, R):
        return False
    tr = 0.0
    for j in range(k):
        tr += S[j, j]
    tr_inv = 0.0
    for c in range(k):  # R^-1 column by column (lower triangular)
        for i in range(k):
            e = 1.0 if i == c else 0.0
            for p in range(c, i):
                e -= R[i, p] * Rinv[p, c]
            Rinv[i, c] = e / R[i, i] if i >= c else 0.0
            tr_inv += Rinv[i, c] * Rinv[i, c]
    if not tr * tr_inv * rcond < 1.0:
        return False
    for i in range(k):  # R z = r, R^T y = z
        e = r[i]
        for p in range(i):
            e -= R[i, p] * y[p]
        y[i] = e / R[i, i]
    for i in range(k - 1, -1, -1):
        e = y[i]
        for p in range(i + 1, k):
            e -= R[p, i] * y[p]
        y[i] = e / R[i, i]
    return True


# ---------------------------------------------------------------------------
# The compiled path of a constrained model (see mbs_envs.dynamics.compiled). A model
# supplies kernels of one member -- ``terms(q, v, tau, p, M, f, Psi, gamma)``
# (``M``, ``f = tau - h``, ``Psi`` and ``gamma = -dPsi v``), ``residual(q, p, phi)``,
# ``jacobian(q, p, Psi)``, ``mass(q, p, M)`` -- on the member as a batch of one
# column, ``q, v, tau`` (n, 1) and ``p`` (P, 1) (:func:`column`), so that they are the
# model's batch formulas; the generic loops below run them member by member and are
# bound in the model's module (cache=False here, as rk_run).
# ---------------------------------------------------------------------------


@njit
def column(x, b):  # pragma: no cover - compiled
    """Column ``b`` of ``x`` (rows, B) as a contiguous (rows, 1) array: one member for the
    general path, where a model's closed-form batch kernel leaves a member to it."""
    out = np.empty((x.shape[0], 1))
    for i in range(x.shape[0]):
        out[i, 0] = x[i, b]
    return out


@njit(cache=False)
def constrained_acceleration_columns(terms, k, q, v, tau, theta, a):  # pragma: no cover - compiled
    """Accelerations of a batch in columns (the ``acc`` kernel of :func:`mbs_envs.dynamics.compiled.rk_run`):
    per member, ``terms`` then :func:`schur_member` (as :meth:`ConstrainedModel.forward_dynamics`).

    Parameters
    ----------
    terms : compiled kernel of one member (see above)
    k : int
        Rows of ``Psi``.
    q, v, tau : ndarray, shape (n, B)
    theta : ndarray, shape (P, B)
    a : ndarray, shape (n, B)
        Written.
    """
    n, B = q.shape
    M, f, Psi, gamma = np.empty((n, n)), np.empty(n), np.empty((k, n)), np.empty(k)
    ab, lam = np.empty(n), np.empty(k)
    work = schur_work(n, k)
    for b in range(B):
        terms(column(q, b), column(v, b), column(tau, b), column(theta, b), M, f, Psi, gamma)
        schur_member(M, f, Psi, gamma, RCOND, False, work, ab, lam)
        for i in range(n):
            a[i, b] = ab[i]


@njit(cache=False)
def project_columns(residual, jacobian, mass, rows, k, q, v, theta, tol):  # pragma: no cover - compiled
    """:meth:`ConstrainedModel.project` of a batch in columns, in place (the ``after`` kernel of
    :func:`mbs_envs.dynamics.compiled.rk_run`).

    Per member: Gauss-Newton on the holonomic rows ``rows`` of ``Psi`` until
    ``max |phi| <= tol`` (at most 20 iterations, as :func:`gauss_newton_projection`),
    the steps solved by Cholesky where ``Psi Psi^T`` is provably well conditioned and
    by its pseudo-inverse otherwise; then ``v`` projected onto ``Psi v = 0`` in the
    kinetic-energy metric (:func:`project_velocities`).

    Parameters
    ----------
    residual, jacobian, mass : compiled kernels of one member (see above)
    rows : ndarray of int, shape (p,)
        The rows of ``Psi`` that are the Jacobian of ``phi``.
    k : int
        Rows of ``Psi``.
    q, v : ndarray, shape (n, B)
    theta : ndarray, shape (P, B)
    tol : float
        [m]
    """
    n, B = q.shape
    m = rows.shape[0]
    M, Psi, zero, gamma = np.empty((n, n)), np.empty((k, n)), np.zeros(n), np.empty(k)
    dv, lam = np.empty(n), np.empty(k)
    phi, G, y = np.empty(m), np.empty((m, m)), np.empty(m)
    R, Rinv = np.zeros((m, m)), np.zeros((m, m))
    work = schur_work(n, k)
    for b in range(B):
        p, qb = column(theta, b), column(q, b)
        residual(qb, p, phi)
        for _ in range(20):
            active = False
            for i in range(m):
                active |= abs(phi[i]) > tol
            if not active:
                break
            jacobian(qb, p, Psi)
            for i in range(m):  # G = P P^T with P the holonomic rows
                for j in range(m):
                    e = 0.0
                    for c in range(n):
                        e += Psi[rows[i], c] * Psi[rows[j], c]
                    G[i, j] = e
            if not _cholesky_solve_if_well_conditioned(G, phi, RCOND, R, Rinv, y):
                _pinv_solve(G, phi, RCOND, y)
            for c in range(n):
                e = 0.0
                for i in range(m):
                    e += Psi[rows[i], c] * y[i]
                qb[c, 0] -= e
            residual(qb, p, phi)
        mass(qb, p, M)
        jacobian(qb, p, Psi)
        for i in range(k):
            e = 0.0
            for c in range(n):
                e += Psi[i, c] * v[c, b]
            gamma[i] = -e
        schur_member(M, zero, Psi, gamma, RCOND, False, work, dv, lam)
        for i in range(n):
            q[i, b] = qb[i, 0]
            v[i, b] = v[i, b] + dv[i]


@njit(cache=False)
def constraint_info_columns(terms, residual, q, v, tau, theta, res, lam):  # pragma: no cover - compiled
    """Per member of a batch in columns: ``res = max |phi|`` [m] and the multipliers ``lam``
    (B, k) of the motion under ``tau`` (:meth:`ConstrainedModel.multipliers`)."""
    n, B = q.shape
    k = lam.shape[1]
    M, f, Psi, gamma = np.empty((n, n)), np.empty(n), np.empty((k, n)), np.empty(k)
    ab, lb = np.empty(n), np.empty(k)
    phi = np.zeros(k)  # the holonomic rows written, the others stay 0
    work = schur_work(n, k)
    for b in range(B):
        p, qb = column(theta, b), column(q, b)
        residual(qb, p, phi)
        worst = 0.0
        for i in range(k):
            x = abs(phi[i])
            if x > worst or x != x:  # NaN stays
                worst = x
        res[b] = worst
        terms(qb, column(v, b), column(tau, b), p, M, f, Psi, gamma)
        schur_member(M, f, Psi, gamma, RCOND, False, work, ab, lb)
        for i in range(k):
            lam[b, i] = lb[i]


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
    f = np.zeros(np.broadcast_shapes(v.shape, M.shape[:-1]))
    a, _, _ = constrained_accelerations(M, f, Psi, -batched_matvec(Psi, v), conditioning=False)
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


# ---------------------------------------------------------------------------
# The same solves over a batch in columns with the member index innermost (SIMD), for models whose terms
# are generated as straight-line code over the batch (mbs_envs.models.symbolic). A member these cannot
# decide (M not positive definite, S not provably well conditioned, non-finite values) is flagged, and the
# caller recomputes it by the general member path above, so both give the general path's results.
# ---------------------------------------------------------------------------


@njit
def well_conditioned_solve_columns(S, r, rcond, y, ok):  # pragma: no cover - compiled
    """:func:`_cholesky_solve_if_well_conditioned` for every member: ``y = S^-1 r`` (``S`` (k, k, B) destroyed,
    ``r, y`` (k, B)); ``ok[b]`` cleared where ``trace(S) trace(S^-1) < 1 / rcond`` does not hold (or ``S`` is not
    positive definite), those members' ``y`` meaningless."""
    k, B = S.shape[0], S.shape[2]
    tr = np.zeros(B)
    for j in range(k):
        for b in range(B):
            tr[b] += S[j, j, b]
    cholesky_columns(S, ok)
    Rinv = np.zeros((k, k, B))
    tr_inv = np.zeros(B)
    for c in range(k):
        for i in range(c, k):
            for b in range(B):
                Rinv[i, c, b] = 1.0 if i == c else 0.0
            for p in range(c, i):
                for b in range(B):
                    Rinv[i, c, b] -= S[i, p, b] * Rinv[p, c, b]
            for b in range(B):
                Rinv[i, c, b] = Rinv[i, c, b] * S[i, i, b]  # S's diagonal holds 1 / R_ii
                tr_inv[b] += Rinv[i, c, b] * Rinv[i, c, b]
    for b in range(B):
        ok[b] &= tr[b] * tr_inv[b] * rcond < 1.0
    for i in range(k):
        for b in range(B):
            y[i, b] = r[i, b]
    cholesky_solve_columns(S, y)


@njit
def schur_columns(M, X, P, g, rcond, a, lam, ok):  # pragma: no cover - compiled
    """:func:`schur_member` for every member of a batch in columns, member index innermost.

    Parameters
    ----------
    M : ndarray, shape (n, n, B)
        Destroyed (its Cholesky factor).
    X : ndarray, shape (k + 1, n, B)
        ``X[0]`` holds ``f``; written: ``M^-1 f`` and ``M^-1 Psi^T``.
    P, g : ndarray, shape (k, n, B), (k, B)
        ``Psi`` and ``gamma``.
    a, lam : ndarray, shape (n, B), (k, B)
        Written.
    ok : ndarray of bool, shape (B,)
        Cleared where the member must be recomputed by the general path (see above).
    """
    k, n, B = P.shape
    for c in range(k):
        for i in range(n):
            for b in range(B):
                X[1 + c, i, b] = P[c, i, b]
    cholesky_columns(M, ok)
    for c in range(k + 1):
        cholesky_solve_columns(M, X[c])
    S, r = np.empty((k, k, B)), np.empty((k, B))
    for i in range(k):
        for b in range(B):
            r[i, b] = g[i, b]
        for p in range(n):
            for b in range(B):
                r[i, b] -= P[i, p, b] * X[0, p, b]
        for j in range(k):
            for b in range(B):
                S[i, j, b] = 0.0
            for p in range(n):
                for b in range(B):
                    S[i, j, b] += P[i, p, b] * X[1 + j, p, b]
    well_conditioned_solve_columns(S, r, rcond, lam, ok)
    for i in range(n):
        for b in range(B):
            a[i, b] = X[0, i, b]
        for j in range(k):
            for b in range(B):
                a[i, b] += X[1 + j, i, b] * lam[j, b]
    for b in range(B):
        fine = True
        for i in range(n):
            fine &= np.isfinite(a[i, b])
        ok[b] &= fine


@njit(cache=False, inline="always")  # takes a kernel as argument: cached inside the generated modules that call it
def project_simd(terms_cols, nh, k, q, v, theta, tol, general):  # pragma: no cover - compiled
    """:func:`project_columns` for every member with the member index innermost: Gauss-Newton on the ``nh``
    holonomic rows of the ``k`` rows of ``Psi`` (at most 20 steps, a member stops when ``max |phi| <= tol``), then
    ``v`` onto ``Psi v = 0`` in the kinetic-energy metric, in place. ``terms_cols(q, theta, phi, P, M)`` is the
    model's batch kernel of ``phi``, ``Psi`` and ``M`` at once (one pass of sines and cosines per iteration, the
    last one's ``Psi`` and ``M`` serving the velocity projection); ``general[b]`` is set for members the caller must
    project by the general member path (from their input state)."""
    n, B = q.shape
    P, M = np.empty((k, n, B)), np.empty((n, n, B))
    phi, G, y = np.empty((nh, B)), np.empty((nh, nh, B)), np.empty((nh, B))
    active, ok = np.empty(B, np.bool_), np.empty(B, np.bool_)
    for it in range(21):
        terms_cols(q, theta, phi, P, M)
        n_active = 0
        for b in range(B):
            act = False
            for i in range(nh):
                act |= abs(phi[i, b]) > tol
            active[b] = act & (not general[b])
            n_active += active[b]
        if n_active == 0 or it == 20:
            break
        for i in range(nh):  # G = P_h P_h^T
            for j in range(nh):
                for b in range(B):
                    G[i, j, b] = 0.0
                for c in range(n):
                    for b in range(B):
                        G[i, j, b] += P[i, c, b] * P[j, c, b]
        for b in range(B):
            ok[b] = True
        well_conditioned_solve_columns(G, phi, RCOND, y, ok)
        for b in range(B):
            general[b] |= active[b] & (not ok[b])
            active[b] &= ok[b]
        for c in range(n):
            for i in range(nh):
                for b in range(B):
                    if active[b]:
                        q[c, b] -= P[i, c, b] * y[i, b]
    X, g = np.empty((k + 1, n, B)), np.empty((k, B))
    for i in range(n):
        for b in range(B):
            X[0, i, b] = 0.0
    for i in range(k):
        for b in range(B):
            g[i, b] = 0.0
        for c in range(n):
            for b in range(B):
                g[i, b] -= P[i, c, b] * v[c, b]
    dv, lam = np.empty((n, B)), np.empty((k, B))
    for b in range(B):
        ok[b] = True
    schur_columns(M, X, P, g, RCOND, dv, lam, ok)
    for b in range(B):
        general[b] |= not ok[b]
    for c in range(n):
        for b in range(B):
            if not general[b]:
                v[c, b] += dv[c, b]
