"""Base of models with constraints ``Psi(q) v = 0`` (holonomic rows from ``phi(q) = 0``).

Only constrained mechanisms (four-bar, rolling disk, derived ones with constraints) derive from this.
Serial models never import :mod:`mbs_envs.dynamics.constraints`; this base, the constrained mechanisms' modules
and :mod:`mbs_envs.models.symbolic` (whose generated code calls its column solves) do.
"""

from __future__ import annotations

import abc
from typing import Any, ClassVar

import numpy as np

from ..dynamics.constraints import (
    Stabilization,
    constrained_accelerations,
    gauss_newton_projection,
    project_velocities,
)
from ..dynamics.compiled import batch_theta, columns_of
from ..dynamics.linalg import batched_matvec
from .base import Model, as_vector


class ConstrainedModel(Model):
    """A model whose motion obeys ``Psi(q) v = 0``; see docs/physics.md §2.

    Subclasses implement :meth:`constraint_residual` (the holonomic ``phi``,
    whose Jacobian is the rows ``position_rows`` of ``Psi``),
    :meth:`constraint_jacobian` and :meth:`constraint_bias` (``dPsi v``), and
    name their ``independent`` coordinates (the ones a user prescribes).
    """

    constrained: ClassVar[bool] = True
    #: number of rows of Psi
    nc: ClassVar[int]
    #: rows of Psi that are derivatives of phi (the rest are non-holonomic)
    position_rows: ClassVar[tuple[int, ...] | None] = None
    #: independent coordinates (velocities) that parametrize the motion
    independent: ClassVar[tuple[int, ...]]
    #: The compiled projection ``(q, v, theta, tol)`` of a batch in columns, in place (with
    #: ``kernels``; see :meth:`project_compiled`), or None.
    project_kernel: ClassVar[Any] = None
    #: The compiled ``(q, v, tau, theta, residual, lam)`` of a batch in columns (see
    #: :meth:`multipliers`), or None.
    constraint_info_kernel: ClassVar[Any] = None

    @abc.abstractmethod
    def constraint_residual(self, q: np.ndarray) -> np.ndarray:
        """Holonomic residual ``phi(q)``, shape ``(..., len(position_rows))``."""

    @abc.abstractmethod
    def constraint_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``Psi(q)``, shape ``(..., nc, nv)``; motions satisfy ``Psi v = 0``."""

    @abc.abstractmethod
    def constraint_bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``dPsi(q, v) v``, shape ``(..., nc)``: ``Psi a + dPsi v = 0``."""

    # -- dynamics -------------------------------------------------------------

    def _rows(self) -> tuple[int, ...]:
        return tuple(range(self.nc)) if self.position_rows is None else self.position_rows

    def solve(
        self,
        q: np.ndarray,
        v: np.ndarray,
        u: np.ndarray | None = None,
        alpha: float = 0.0,
        beta: float = 0.0,
        conditioning: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Accelerations, multipliers and the conditioning of ``Psi M^-1 Psi^T``.

        ``gamma = -dPsi v - 2 alpha Psi v - beta^2 phi`` (Baumgarte when
        ``alpha, beta > 0``; ``phi`` enters the holonomic rows only). With
        ``conditioning=False`` the condition number is only computed where the
        solve needs it (NaN elsewhere; see :func:`constrained_accelerations`).

        Returns
        -------
        a : ndarray, shape (..., nv)
        lam : ndarray, shape (..., nc)
        cond : ndarray, shape (...)
        """
        q = as_vector(q, self.nq, "q")
        v = as_vector(v, self.nv, "v")
        Psi = self.constraint_jacobian(q)
        gamma = -self.constraint_bias(q, v)
        if alpha or beta:
            gamma = gamma - 2 * alpha * batched_matvec(Psi, v)
            phi = self.constraint_residual(q)
            rows = self._rows()
            full = np.zeros(phi.shape[:-1] + (self.nc,))
            full[..., rows] = phi
            gamma = gamma - beta**2 * full
        f = self.generalized_input(u) - self.bias(q, v)
        return constrained_accelerations(self.mass_matrix(q), f, Psi, gamma, conditioning=conditioning)

    def forward_dynamics(
        self, q: np.ndarray, v: np.ndarray, u: np.ndarray | None = None, alpha: float = 0.0, beta: float = 0.0
    ) -> np.ndarray:
        """Accelerations with the constraints enforced (Schur complement), shape ``(..., nv)``."""
        return self.solve(q, v, u, alpha, beta, conditioning=False)[0]

    def multipliers(
        self, q: np.ndarray, v: np.ndarray, u: np.ndarray | None = None, compiled: bool = False
    ) -> np.ndarray:
        """Lagrange multipliers ``lam`` with ``M a + C v + G + F = B u + Psi^T lam``, shape ``(..., nc)``.

        ``compiled=True`` takes the model's ``constraint_info_kernel`` where it has one (what its
        compiled steps report; equal to rounding, tested), else the numpy solve.
        """
        if not compiled or self.constraint_info_kernel is None:
            return self.solve(q, v, u, conditioning=False)[1]
        tau = self.generalized_input(u)
        q, v, tau = np.broadcast_arrays(as_vector(q, self.nq, "q"), as_vector(v, self.nv, "v"), tau)
        lead = q.shape[:-1]
        qc, vc, tc = columns_of(q), columns_of(v), columns_of(tau)
        B = qc.shape[1]
        res, lam = np.empty(B), np.empty((B, self.nc))
        self.constraint_info_kernel(qc, vc, tc, batch_theta(self, B), res, lam)
        return lam.reshape(lead + (self.nc,))

    def constraint_conditioning(self, q: np.ndarray) -> np.ndarray:
        """Condition number of ``Psi M^-1 Psi^T`` (inf where ``Psi`` loses rank), shape ``(...)``."""
        q = as_vector(q, self.nq, "q")
        return self.solve(q, np.zeros(q.shape[:-1] + (self.nv,)))[2]

    def inverse_dynamics_with_multipliers(
        self, q: np.ndarray, v: np.ndarray, a: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Inputs and multipliers producing a consistent motion ``(q, v, a)``.

        Solves ``[B, Psi^T] [u; lam] = M a + h`` (least squares via the
        pseudo-inverse, exact when the matrix is square and regular).

        Returns
        -------
        u : ndarray, shape (..., nu)
        lam : ndarray, shape (..., nc)
        """
        q = as_vector(q, self.nq, "q")
        a = as_vector(a, self.nv, "a")
        tau = batched_matvec(self.mass_matrix(q), a) + self.bias(q, v)
        Psi = self.constraint_jacobian(q)
        A = np.concatenate(
            [np.broadcast_to(self.actuation, Psi.shape[:-2] + self.actuation.shape), np.swapaxes(Psi, -1, -2)], axis=-1
        )
        x = batched_matvec(np.linalg.pinv(A), tau)
        return x[..., : self.nu], x[..., self.nu :]

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Inputs ``u`` producing a consistent motion ``(q, v, a)``, shape ``(..., nu)``."""
        return self.inverse_dynamics_with_multipliers(q, v, a)[0]

    # -- consistent states ----------------------------------------------------

    def _dependent(self) -> list[int]:
        return [i for i in range(self.nv) if i not in self.independent]

    def complete(self, q: np.ndarray, x_ind: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Full vector ``x`` with ``x[independent] = x_ind`` and ``Psi x = rhs``."""
        q = as_vector(q, self.nq, "q")
        Psi = self.constraint_jacobian(q)
        ind, dep = list(self.independent), self._dependent()
        x_ind = as_vector(x_ind, len(ind), "independent values")
        r = rhs - batched_matvec(Psi[..., :, ind], x_ind)
        x_dep = batched_matvec(np.linalg.pinv(Psi[..., :, dep]), r)
        x = np.empty(np.broadcast_shapes(x_ind.shape[:-1], x_dep.shape[:-1]) + (self.nv,))
        x[..., ind] = x_ind
        x[..., dep] = x_dep
        return x

    def complete_velocity(self, q: np.ndarray, v_ind: np.ndarray) -> np.ndarray:
        """Velocities with ``Psi v = 0`` and the given independent rates."""
        return self.complete(q, v_ind, 0.0)

    def complete_acceleration(self, q: np.ndarray, v: np.ndarray, a_ind: np.ndarray) -> np.ndarray:
        """Accelerations with ``Psi a + dPsi v = 0`` and the given independent ones."""
        return self.complete(q, a_ind, -self.constraint_bias(q, v))

    def project(self, q: np.ndarray, v: np.ndarray, tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
        """Project a state onto the constraints: ``q`` onto ``phi = 0``, ``v`` onto ``Psi v = 0``."""
        rows = list(self._rows())
        q, _ = gauss_newton_projection(
            q, self.constraint_residual, lambda x: self.constraint_jacobian(x)[..., rows, :], tol=tol
        )
        v = project_velocities(as_vector(v, self.nv, "v"), self.mass_matrix(q), self.constraint_jacobian(q))
        return q, v

    def project_compiled(self, q: np.ndarray, v: np.ndarray, tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`project` by the model's compiled ``project_kernel`` (the projection its compiled
        steps use; equal to :meth:`project` to rounding, tested), or by :meth:`project` without one.

        Parameters
        ----------
        q : ndarray, shape (..., nq)
        v : ndarray, shape (..., nv)
        tol : float
            Gauss-Newton stops when ``max |phi| <= tol`` [m].
        """
        if self.project_kernel is None:
            return self.project(q, v, tol)
        q, v = np.broadcast_arrays(as_vector(q, self.nq, "q"), as_vector(v, self.nv, "v"))
        lead = q.shape[:-1]
        qc, vc = columns_of(q), columns_of(v)
        self.project_kernel(qc, vc, batch_theta(self, qc.shape[1]), float(tol))
        return qc.T.reshape(lead + (self.nq,)), vc.T.reshape(lead + (self.nv,))

    def make_consistent(self, q: np.ndarray, v: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
        """Project a state onto the constraints (:meth:`project_compiled`); refuse it if it cannot be.

        Raises
        ------
        ValueError
            If the projection is not finite or leaves a constraint residual above ``tol`` [m].
        """
        q_p, v_p = self.project_compiled(q, v)
        residual = np.max(np.abs(self.constraint_residual(q_p)), axis=-1)  # per state, shape (...)
        bad = ~(np.all(np.isfinite(q_p), axis=-1) & (residual <= tol))
        if np.any(bad):
            i = np.unravel_index(np.argmax(bad), bad.shape) if bad.ndim else ()  # the first refused
            raise ValueError(
                f"start state q = {np.asarray(q)[i].tolist()} cannot be made consistent with the constraints "
                f"(residual {residual[i]:.3g} after projection)"
            )
        return q_p, v_p

    def constraint_violation(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``max(|phi(q)|, |Psi(q) v|)`` per sample, shape ``(...)``."""
        phi = self.constraint_residual(q)  # the holonomic rows
        dphi = batched_matvec(self.constraint_jacobian(q), as_vector(v, self.nv, "v"))  # all rows
        return np.maximum(np.max(np.abs(phi), axis=-1), np.max(np.abs(dphi), axis=-1))

    def stabilization(self, kind: Any = None, **options: Any) -> Stabilization:
        """The :class:`~mbs_envs.dynamics.constraints.Stabilization` a simulation uses.

        ``kind`` is ``"projection"`` (default, also for ``None``), ``"baumgarte"``,
        ``"none"`` or a ready :class:`Stabilization`; ``options`` are its fields
        (``alpha``, ``beta``, ``tol``).
        """
        if isinstance(kind, Stabilization):
            return kind
        return Stabilization("projection" if kind is None else kind, **options)

    def accelerations(self, q, v, u, stabilization: Stabilization) -> np.ndarray:
        """Forward dynamics with the Baumgarte gains of ``stabilization`` (if any)."""
        return self.forward_dynamics(q, v, u, *stabilization.gains)

    def after_step(self, q, v, stabilization: Stabilization):
        """Projection after an integration step, when ``stabilization`` asks for it."""
        if stabilization.kind == "projection":
            return self.project(q, v, stabilization.tol)
        return q, v
