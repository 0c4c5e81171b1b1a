"""The compiled path: the explicit Runge-Kutta stepper of :mod:`mbs_envs.dynamics.integrators`
as one numba loop over a batch, for models with compiled kernels.

Nothing here knows a mechanism. A model opts in with ``kernels =
(acceleration_kernel, energy_kernel)``, numba functions of a batch built on the
very formulas its numpy methods use (see :mod:`mbs_envs.models.planar2r`),
``advance_kernel``, its module-level binding of :func:`rk_run` (a kernel
passed from one compiled function to another is bound at compile time, and
such a module-level function is cached on disk: nothing is compiled again in
a new process), and :meth:`~mbs_envs.models.base.Model.kernel_params` (its
parameters as an array, ``(P,)`` or ``(B, P)`` with per-member parameters).

Layout: kernels take the batch in *columns*, the member index last (``q`` is
``(n, B)``, the parameters ``(P, B)``), and every innermost loop runs over the
members. With the branch-free :func:`mbs_envs.dynamics.trig.sincos` those loops compile to
SIMD code (a loop that calls libm's ``sin`` stays scalar). The stepper runs any
explicit :class:`~mbs_envs.dynamics.integrators.Tableau`: the same stages, in the same
order, as :class:`~mbs_envs.dynamics.integrators.ExplicitRK`, so the two paths differ
only by rounding: of the models' linear solves (Cramer's rule against Cholesky)
and of sines and cosines (:func:`mbs_envs.dynamics.trig.sincos` against libm, 1 ulp);
tested to 1e-12.

Compile time: numba links a callee's code into its caller and optimizes the whole again, so
every level of calls pays for everything below it. The levels that only forward (:func:`rk_run`,
:func:`rk_columns`, :func:`mbs_envs.envs.engine.engine_step`) are therefore inlined
(``inline="always"``, at numba's IR), and kernels take no ``reshape`` (it compiles numba's
error-message formatting); the cold start this saves is in docs/performance.md.

Constrained models (:mod:`mbs_envs.dynamics.constraints`) bind the same stepper with their
Schur-complement accelerations and the projection after every step (the ``after``
kernel of :func:`rk_run`). The numpy path stays the general one (implicit and
adaptive integrators, Baumgarte stabilization, callable inputs);
:func:`compiled_stepping` says when the compiled one applies.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import TYPE_CHECKING, Any

import numpy as np

from .integrators import ExplicitRK, Tableau
from .jit import njit

if TYPE_CHECKING:  # models import this module for their kernels
    from ..models.base import Model


@dataclasses.dataclass(frozen=True)
class TableauArrays:
    """An explicit :class:`Tableau` as the arrays the compiled stepper reads.

    Attributes
    ----------
    A_v, A_q : ndarray, shape (s, s)
    b_v, b_q : ndarray, shape (s,)
    needed : ndarray of bool, shape (s,)
        Whether stage ``i``'s acceleration is used (others are not evaluated).
    """

    A_v: np.ndarray
    A_q: np.ndarray
    b_v: np.ndarray
    b_q: np.ndarray
    needed: np.ndarray

    def packed(self, h: float, substeps: int, tol: float = 0.0) -> tuple:
        """``(A_v, A_q, b_v, b_q, needed, h, substeps, tol)``: the stepper argument of :func:`rk_run`
        (``tol``: the projection tolerance of constrained models [m], unused by the others)."""
        return (self.A_v, self.A_q, self.b_v, self.b_q, self.needed, float(h), int(substeps), float(tol))

    @classmethod
    def of(cls, tableau: Tableau) -> "TableauArrays":
        return cls(
            np.array(tableau.A_v, float),
            np.array(tableau.A_q, float),
            np.array(tableau.b_v, float),
            np.array(tableau.b_q, float),
            np.array(tableau.needs_acceleration, bool),
        )


def compiled_stepping(model: Model, stepper: Any, stabilization: Any = None) -> TableauArrays | None:
    """The tableau to run compiled, or None where the numpy path must be used.

    The compiled path needs model kernels, an explicit Runge-Kutta stepper,
    ``nq == nv``, and for a constrained model the projection after every step
    (the environments' default; Baumgarte and unstabilized runs take the numpy path).
    """
    if (
        model.kernels is None
        or model.advance_kernel is None
        or not isinstance(stepper, ExplicitRK)
        or model.nq != model.nv
        or (stabilization is not None and stabilization.kind != "projection")
        or (model.nc > 0 and stabilization is None)
    ):
        return None
    return _arrays_of(stepper.tableau)


def projection_tol(stabilization: Any) -> float:
    """The projection tolerance the compiled stepper applies after every step [m] (0: none)."""
    return 0.0 if stabilization is None else float(stabilization.tol)


#: One :class:`TableauArrays` per tableau (``advance`` asks for it on every call; the kernels only read it).
_arrays_of = functools.cache(TableauArrays.of)


@njit(cache=False, inline="always")  # takes kernels as arguments: cached inside the module-level bindings that call it
def rk_columns(acc, after, theta, A_v, A_q, b_v, b_q, needed, q, v, tau, h, substeps, tol, Q, V, K):  # pragma: no cover
    """Advance every column of ``q, v`` (n, B) ``substeps`` steps of size ``h``, in place.

    The stages are those of :meth:`mbs_envs.dynamics.integrators.ExplicitRK.step`, term by
    term in the same order (zero coefficients skipped), with the input ``tau``
    (n, B) held. ``Q, V, K`` are work arrays of shape ``(s, n, B)``; the model's
    kernel is called as ``acc(Q[i], V[i], tau, theta, K[i])``, and
    ``after(q, v, theta, tol)`` after every step (a constrained model's
    projection, its ``project_kernel``; :func:`no_projection` otherwise). Every innermost loop runs over the batch, so it vectorizes.
    """
    s = A_v.shape[0]
    n, B = q.shape
    for _ in range(substeps):
        for i in range(s):
            for k in range(n):
                for b in range(B):
                    V[i, k, b] = v[k, b]
                for j in range(i):
                    if A_v[i, j] != 0.0:
                        c = h * A_v[i, j]
                        for b in range(B):
                            V[i, k, b] = V[i, k, b] + c * K[j, k, b]
                for b in range(B):
                    Q[i, k, b] = q[k, b]
                for j in range(i + 1):
                    if A_q[i, j] != 0.0:
                        c = h * A_q[i, j]
                        for b in range(B):
                            Q[i, k, b] = Q[i, k, b] + c * V[j, k, b]
            if needed[i]:
                acc(Q[i], V[i], tau, theta, K[i])
        for k in range(n):
            for i in range(s):
                if b_q[i] != 0.0:
                    c = h * b_q[i]
                    for b in range(B):
                        q[k, b] = q[k, b] + c * V[i, k, b]
                if b_v[i] != 0.0:
                    c = h * b_v[i]
                    for b in range(B):
                        v[k, b] = v[k, b] + c * K[i, k, b]
        after(q, v, theta, tol)


#: bytes of a cache line and of an AVX-512 register: the alignment of the kernels' work arrays
ALIGN = 64


@njit(inline="always")
def aligned_empty(size):  # pragma: no cover - compiled
    """An uninitialized float64 array of ``size`` elements whose data starts on an :data:`ALIGN`-byte
    boundary (numba's ``np.empty`` aligns to 32 bytes, numpy's to 16; the SIMD loops of
    ``SerialChain``'s tile kernels are slower on either, docs/performance.md). One-dimensional:
    a ``reshape`` in a kernel compiles numba's error-message machinery (docs/performance.md)."""
    raw = np.empty(size + ALIGN // 8)
    skip = (-raw.ctypes.data % ALIGN) // 8
    return raw[skip : skip + size]


@njit(cache=False, inline="always")  # takes kernels as arguments: cached inside the module-level bindings that call it
def rk_run(acc, after, theta, stepper, q, v, tau):  # pragma: no cover - compiled
    """:func:`rk_columns` allocating its work arrays; ``acc, after`` are bound by the caller's compilation.

    Parameters
    ----------
    acc : compiled acceleration kernel
    after : compiled kernel ``(q, v, theta, tol)`` applied after every step
    theta : ndarray, shape (P, B)
    stepper : tuple
        ``(A_v, A_q, b_v, b_q, needed, h, substeps, tol)`` (:meth:`TableauArrays.packed`).
    q, v, tau : ndarray, shape (n, B)
        Columns; ``q, v`` advanced in place.
    """
    A_v, A_q, b_v, b_q, needed, h, substeps, tol = stepper
    shape = (A_v.shape[0], q.shape[0], q.shape[1])
    Q, V, K = np.empty(shape), np.empty(shape), np.empty(shape)
    rk_columns(acc, after, theta, A_v, A_q, b_v, b_q, needed, q, v, tau, h, substeps, tol, Q, V, K)


@njit
def no_projection(q, v, theta, tol):  # pragma: no cover - compiled
    """The ``after`` kernel of :func:`rk_run` for models without constraints: nothing."""
    return


@njit
def never_singular(q, flags):  # pragma: no cover - compiled
    """The singularity kernel of models whose coordinates have none: ``flags`` stay False."""
    return


@njit
def no_constraint_info(q, v, tau, theta, residual, lam):  # pragma: no cover - compiled
    """The constraint-info kernel of models without constraints: ``residual = 0`` (``lam`` has no rows)."""
    for b in range(q.shape[1]):
        residual[b] = 0.0


# Dense Cholesky over a batch in columns, member index innermost (SIMD): the generated kernels of derived
# models (mbs_envs.models.symbolic) and the column solves of mbs_envs.dynamics.constraints.


@njit
def cholesky_columns(A, ok):  # pragma: no cover - compiled
    """``A = L L^T`` in place for every member: the strict lower triangle of ``A`` (n, n, B) becomes ``L``'s, the
    diagonal ``1 / L_jj`` (the solves multiply: a division costs several multiplications' time in the SIMD
    loops); ``ok[b]`` cleared where ``A`` is not positive definite (or not finite)."""
    n, B = A.shape[0], A.shape[2]
    for j in range(n):
        for p in range(j):
            for b in range(B):
                A[j, j, b] -= A[j, p, b] * A[j, p, b]
        for b in range(B):
            ok[b] &= A[j, j, b] > 0.0
            A[j, j, b] = 1.0 / np.sqrt(abs(A[j, j, b]))
        for i in range(j + 1, n):
            for p in range(j):
                for b in range(B):
                    A[i, j, b] -= A[i, p, b] * A[j, p, b]
            for b in range(B):
                A[i, j, b] = A[i, j, b] * A[j, j, b]


@njit
def cholesky_solve_columns(L, x):  # pragma: no cover - compiled
    """``x <- (L L^T)^-1 x`` in place for every member: ``L`` (n, n, B) from :func:`cholesky_columns` (its
    diagonal ``1 / L_jj``), ``x`` (n, B)."""
    n, B = L.shape[0], L.shape[2]
    for i in range(n):
        for p in range(i):
            for b in range(B):
                x[i, b] -= L[i, p, b] * x[p, b]
        for b in range(B):
            x[i, b] = x[i, b] * L[i, i, b]
    for i in range(n - 1, -1, -1):
        for p in range(i + 1, n):
            for b in range(B):
                x[i, b] -= L[p, i, b] * x[p, b]
        for b in range(B):
            x[i, b] = x[i, b] * L[i, i, b]


def aligned(x: Any) -> np.ndarray:
    """A new C-contiguous float64 copy of ``x`` whose data starts on an :data:`ALIGN`-byte boundary
    (numpy's allocator aligns to 16 bytes): the arrays the kernels' SIMD loops read once per step
    (parameters, references), like :func:`aligned_empty`'s work arrays."""
    x = np.asarray(x, dtype=np.float64)
    raw = np.empty(x.size + ALIGN // 8)
    skip = (-raw.ctypes.data % ALIGN) // 8
    out = raw[skip : skip + x.size].reshape(x.shape)
    out[...] = x
    return out


def columns_of(x: np.ndarray) -> np.ndarray:
    """A new float64 array of the rows ``(..., n)`` as contiguous columns ``(n, B)``, the kernels'
    layout (``B`` the leading dimensions flattened)."""
    x = np.asarray(x)
    return np.array(x.reshape(-1, x.shape[-1]).T, dtype=np.float64, order="C")


def batch_theta(model: Model, batch: int) -> np.ndarray:
    """``model.kernel_params()`` as contiguous columns ``(P, batch)``, cached on the model
    for its current parameters (read only). A model whose kernels take one column for every
    member (``shared_theta = True``) gets ``(P, 1)`` when its parameters are the same for all."""
    cached = model.__dict__.get("_theta_cache")
    if cached is None or cached[0] is not model.params or cached[1] != batch:
        theta = np.asarray(model.kernel_params(), float)
        width = 1 if theta.ndim == 1 and getattr(model, "shared_theta", False) else batch
        theta = aligned(np.broadcast_to(theta, (width, theta.shape[-1])).T)
        theta.flags.writeable = False
        cached = model.__dict__["_theta_cache"] = (model.params, batch, theta)
    return cached[2]


def advance_compiled(
    model: Model,
    tab: TableauArrays,
    q: np.ndarray,
    v: np.ndarray,
    u: np.ndarray,
    duration: float,
    substeps: int = 1,
    stabilization: Any = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The compiled :func:`mbs_envs.dynamics.simulate.advance` for a held input (numpy in, numpy out).

    Parameters
    ----------
    model : Model
        With ``kernels`` (see :func:`compiled_stepping`).
    tab : TableauArrays
    q, v : ndarray, shape (..., n)
    u : ndarray, shape (..., nu)
        Held over the interval; ``B u`` is applied.
    duration : float
        [s], in ``substeps`` equal steps.
    stabilization : Stabilization, optional
        A constrained model's (projection after every step).

    Returns
    -------
    q, v : ndarray, shape (..., n)
        New arrays; non-finite where a member blew up.
    """
    shape = np.broadcast_shapes(np.shape(q)[:-1], np.shape(v)[:-1], np.shape(u)[:-1])
    n = model.nv

    def columns(x):  # a new (n, B) array
        return np.array(np.broadcast_to(x, shape + (n,)).reshape(-1, n).T, float, order="C")

    q2, v2, tau = columns(q), columns(v), columns(model.generalized_input(u))
    theta = batch_theta(model, q2.shape[1])
    model.advance_kernel(theta, tab.packed(duration / substeps, substeps, projection_tol(stabilization)), q2, v2, tau)
    return q2.T.reshape(shape + (n,)), v2.T.reshape(shape + (n,))
