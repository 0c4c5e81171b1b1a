"""The compiled path: the explicit Runge-Kutta stepper of :mod:`mbs_envs.integrators`
as one numba loop over a batch, for models with compiled kernels.

Nothing here knows a mechanism. A model opts in with ``kernels =
(acceleration_kernel, energy_kernel)``, numba functions of one member built on
the very formulas its numpy methods use (see :mod:`mbs_envs.models.planar2r`),
and :meth:`~mbs_envs.models.base.Model.kernel_params` (its parameters as an
array, ``(P,)`` or ``(B, P)`` with per-member parameters). The stepper runs any
explicit :class:`~mbs_envs.integrators.Tableau`: the same stages, in the same
order, as :class:`~mbs_envs.integrators.ExplicitRK`, so the two paths differ
only by the rounding of the models' linear solves (tested to 1e-12).

The numpy path stays the general one (constrained models, implicit and
adaptive integrators, stabilization); :func:`compiled_stepping` says when the
compiled one applies.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

from .jit import njit
import numpy as np

from .integrators import ExplicitRK, Tableau
from .models.base import Model


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

    The compiled path needs model kernels, an explicit Runge-Kutta stepper, no
    constraint stabilization, ``nq == nv`` and no coordinate singularities.
    """
    if (
        model.kernels is None
        or not isinstance(stepper, ExplicitRK)
        or stabilization is not None
        or model.nq != model.nv
        or type(model).singular is not Model.singular
    ):
        return None
    return TableauArrays.of(stepper.tableau)


@njit(cache=False)
def rk_member(acc, theta, A_v, A_q, b_v, b_q, needed, q, v, tau, b, h, substeps, Q, V, K):  # pragma: no cover
    """Advance row ``b`` of ``q, v`` (B, n) ``substeps`` steps of size ``h``, in place.

    The stages are those of :meth:`mbs_envs.integrators.ExplicitRK.step`, term by
    term in the same order (zero coefficients skipped), with the input
    ``tau[b]`` held. ``Q, V, K`` are work arrays of shape ``(s, n)``; the
    model's kernel is called as ``acc(Q, V, i, tau, theta, b, K)`` and writes
    stage ``i``'s accelerations into ``K[i]`` (kernels index rows rather than
    take views, which measured slower).
    """
    s, n = Q.shape
    for _ in range(substeps):
        for i in range(s):
            for k in range(n):
                x = v[b, k]
                for j in range(i):
                    if A_v[i, j] != 0.0:
                        x = x + (h * A_v[i, j]) * K[j, k]
                V[i, k] = x
            for k in range(n):
                x = q[b, k]
                for j in range(i + 1):
                    if A_q[i, j] != 0.0:
                        x = x + (h * A_q[i, j]) * V[j, k]
                Q[i, k] = x
            if needed[i]:
                acc(Q, V, i, tau, theta, b, K)
        for k in range(n):
            xq = q[b, k]
            xv = v[b, k]
            for i in range(s):
                if b_q[i] != 0.0:
                    xq = xq + (h * b_q[i]) * V[i, k]
                if b_v[i] != 0.0:
                    xv = xv + (h * b_v[i]) * K[i, k]
            q[b, k] = xq
            v[b, k] = xv


@functools.cache
def rk_batch(acc):
    """:func:`rk_member` over the rows of a batch, with the acceleration kernel bound at compile time.

    The returned function ``(theta, A_v, A_q, b_v, b_q, needed, q, v, tau, h, substeps)``
    advances every row of ``q, v, tau`` (shape ``(B, n)``) in place; ``theta``
    is ``(B, P)``. (A kernel passed as an argument would be type-checked on every call.)
    """

    @njit(cache=False)
    def run(theta, A_v, A_q, b_v, b_q, needed, q, v, tau, h, substeps):  # pragma: no cover - compiled
        s = A_v.shape[0]
        B, n = q.shape
        Q = np.empty((s, n))
        V = np.empty((s, n))
        K = np.empty((s, n))
        for b in range(B):
            rk_member(acc, theta, A_v, A_q, b_v, b_q, needed, q, v, tau, b, h, substeps, Q, V, K)

    return run


def batch_theta(model: Model, batch: int) -> np.ndarray:
    """``model.kernel_params()`` as a contiguous ``(batch, P)`` array, cached on the model
    for its current parameters (read only)."""
    cached = model.__dict__.get("_theta_cache")
    if cached is None or cached[0] is not model.params or cached[1] != batch:
        theta = np.asarray(model.kernel_params(), float)
        theta = np.ascontiguousarray(np.broadcast_to(theta, (batch, theta.shape[-1])))
        theta.flags.writeable = False
        cached = model.__dict__["_theta_cache"] = (model.params, batch, theta)
    return cached[2]


def advance_compiled(
    model: Model, tab: TableauArrays, q: np.ndarray, v: np.ndarray, u: np.ndarray, duration: float, substeps: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """The compiled :func:`mbs_envs.simulate.advance` for a held input (numpy in, numpy out).

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

    Returns
    -------
    q, v : ndarray, shape (..., n)
        New arrays; non-finite where a member blew up.
    """
    shape = np.broadcast_shapes(np.shape(q)[:-1], np.shape(v)[:-1], np.shape(u)[:-1])
    n = model.nv
    q2 = np.array(np.broadcast_to(q, shape + (n,)), float).reshape(-1, n)
    v2 = np.array(np.broadcast_to(v, shape + (n,)), float).reshape(-1, n)
    tau = np.ascontiguousarray(np.broadcast_to(model.generalized_input(u), shape + (n,)), float).reshape(-1, n)
    theta = batch_theta(model, q2.shape[0])
    rk_batch(model.kernels[0])(theta, tab.A_v, tab.A_q, tab.b_v, tab.b_q, tab.needed, q2, v2, tau, duration / substeps, substeps)
    return q2.reshape(shape + (n,)), v2.reshape(shape + (n,))
