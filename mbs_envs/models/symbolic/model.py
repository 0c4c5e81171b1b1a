"""The runtime models of a derivation: :class:`DerivedModel` (and its constrained variant), built per
generated source by :func:`model_class`; :func:`derive`, the one call from a Lagrangian to a model."""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ...dynamics import constraints as _constraints
from ..base import Model, Params, as_vector, param
from ..constrained import ConstrainedModel
from .cache import cached_derivation, load_generated, source_of
from .derivation import Derivation


class DerivedModel(Model):
    """The base of models made by :func:`derive` (the class it returns sets the derivation)."""

    derivation: Derivation
    generated: Any
    shared_theta = True

    @property
    def actuation(self) -> np.ndarray:
        return self.derivation.B

    def kernel_params(self) -> np.ndarray:
        return np.array([getattr(self.params, k) for k, _ in self.derivation.params], float)

    def _flat_rows(self, q: np.ndarray, v: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, tuple]:
        """``q, v`` (``v`` None: zero) checked, broadcast and flattened to contiguous rows ``(B, n)``, with the
        broadcast shape ``(..., n)``: what the generated row functions take."""
        n = self.nq
        q = as_vector(q, n, "q")
        v = np.zeros(q.shape) if v is None else as_vector(v, n, "v")
        shape = np.broadcast_shapes(q.shape, v.shape)
        flat = [np.ascontiguousarray(np.broadcast_to(x, shape).reshape(-1, n), dtype=float) for x in (q, v)]
        return flat[0], flat[1], shape

    def _terms(self, q: np.ndarray, v: np.ndarray | None = None):
        n = self.nq
        qr, vr, shape = self._flat_rows(q, v)
        M, Cv, G, E = self.generated.rows(qr, vr, self.kernel_params())
        lead = shape[:-1]
        return (
            M.reshape(lead + (n, n)),
            Cv.reshape(shape),
            G.reshape(shape),
            E[:, 0].reshape(lead),
            E[:, 1].reshape(lead),
        )

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        return self._terms(q)[0]

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self._terms(q, v)[1]

    def gravity(self, q: np.ndarray) -> np.ndarray:
        return self._terms(q)[2]

    def kinetic_energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self._terms(q, v)[3]

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        return self._terms(q)[4]

    def friction(self, v: np.ndarray) -> np.ndarray:
        """Viscous friction ``b_i v_i`` on the coordinates with a damping parameter, plus the friction law's ``F(v)``
        where the derivation has one (by its generated code)."""
        v = as_vector(v, self.nv, "v")
        b = np.array([0.0 if k is None else getattr(self.params, k) for k in self.derivation.damping])
        if self.derivation.F is None:
            return b * v
        rows = np.ascontiguousarray(np.reshape(v, (-1, self.nv)), float)
        return b * v + self.generated.friction_rows(rows, self.kernel_params()).reshape(np.shape(v))

    def bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        _, Cv, G, _, _ = self._terms(q, v)
        return Cv + G + self.friction(v)

    def __reduce__(self):  # the class is made at run time: rebuilt from the derivation (cached)
        return (_rebuild, (self.derivation, self.params.as_dict()))


class ConstrainedDerivedModel(DerivedModel, ConstrainedModel):
    """The base of derived models with constraints ``Psi(q) v = 0``: the holonomic rows first (``phi``, projected
    onto after every step), then the non-holonomic ones; :class:`~mbs_envs.models.constrained.ConstrainedModel`'s
    Schur-complement dynamics, multipliers, projection and consistent states, on the generated code."""

    def _constraint_terms(self, q: np.ndarray, v: np.ndarray | None = None):
        n = self.nq
        qr, vr, shape = self._flat_rows(q, v)
        phi, Psi, Pdv = self.generated.constraint_rows(qr, vr, self.kernel_params())
        lead = shape[:-1]
        return (
            phi.reshape(lead + (self.derivation.nh,)),
            Psi.reshape(lead + (self.nc, n)),
            Pdv.reshape(lead + (self.nc,)),
        )

    def constraint_residual(self, q: np.ndarray) -> np.ndarray:
        return self._constraint_terms(q)[0]

    def constraint_jacobian(self, q: np.ndarray) -> np.ndarray:
        return self._constraint_terms(q)[1]

    def constraint_bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self._constraint_terms(q, v)[2]

    def assemble(self, q_ind: np.ndarray, guess: np.ndarray, tol: float = 1e-12, max_iter: int = 50) -> np.ndarray:
        """Coordinates on the holonomic constraints with the independent ones given, on the assembly branch of
        ``guess``: the guess is first closed at its own independent values, then the independent coordinates are
        moved to ``q_ind`` in steps of at most 0.2 (continuation), Gauss-Newton (minimum-norm steps on the dependent
        coordinates) closing the loop after each; a loop that passes no singular configuration on the way stays on
        its branch (as :meth:`FourBar.assemble`'s ``branch``).

        Parameters
        ----------
        q_ind : ndarray, shape (..., n - nc)
            The independent coordinates.
        guess : ndarray, shape (..., n)
            A configuration near the wanted branch (it need not close the loop exactly).

        Raises
        ------
        ValueError
            If the residual stays above ``1e3 tol``, also from 20 restarts of the dependent coordinates drawn in
            ``[-pi, pi]`` (a fixed generator: the same answer every call).
        """
        ind, dep = list(self.independent), self._dependent()
        q_ind = as_vector(q_ind, len(ind), "q_ind")
        guess = as_vector(guess, self.nq, "guess")
        q = np.array(
            np.broadcast_to(guess, np.broadcast_shapes(q_ind.shape[:-1], guess.shape[:-1]) + (self.nq,)), float
        )
        rows = list(self._rows())
        if not rows:
            q[..., ind] = q_ind
            return q

        def residual(x):
            y = q.copy()
            y[..., dep] = x
            return self.constraint_residual(y)

        def jacobian(x):
            y = q.copy()
            y[..., dep] = x
            return self.constraint_jacobian(y)[..., rows, :][..., dep]

        def close(x):
            return _constraints.gauss_newton_projection(x, residual, jacobian, tol=tol, max_iter=max_iter)

        start = q[..., ind].copy()
        x, phi = close(q[..., dep])  # the guess closed where it is
        # each member's own number of steps (a batch's members take the steps each would take alone; a member
        # done early stays at its target, where Gauss-Newton changes nothing more once converged)
        steps = np.maximum(1, np.ceil(np.max(np.abs(q_ind - start), axis=-1, initial=0.0) / 0.2))[..., None]
        for k in range(1, int(np.max(steps, initial=1)) + 1):
            q[..., ind] = start + (q_ind - start) * (np.minimum(k, steps) / steps)
            x, phi = close(x)
        failed = ~np.all(np.abs(phi) <= 1e3 * tol, axis=-1)
        for trial in np.random.default_rng(0).uniform(-np.pi, np.pi, (20, len(dep))):
            if not np.any(failed):  # Gauss-Newton stalled in a minimum of |phi| that is not an assembly: restart those
                break
            y, psi = close(np.broadcast_to(trial, x.shape))
            fixed = failed & np.all(np.abs(psi) <= 1e3 * tol, axis=-1)
            x, phi = np.where(fixed[..., None], y, x), np.where(fixed[..., None], psi, phi)
            failed &= ~fixed
        if np.any(failed):
            raise ValueError(f"q_ind: no assembly of {self.derivation.name} at {np.asarray(q_ind)[failed].tolist()} "
                             f"(residual {np.max(np.abs(phi)):.3g} after restarts)")  # fmt: skip
        q[..., dep] = x
        return q

    def moving_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The independent coordinates at 0.3 moving at 0.5, assembled from 0.3 in every coordinate."""
        m = len(self.independent)
        q = self.assemble(np.full(m, 0.3), np.full(self.nq, 0.3))
        return q, self.complete_velocity(q, np.full(m, 0.5))

    def motion_from_tracked(self, q_t, v_t, a_t, branch: int = 1):
        """The whole motion from the independent coordinates' ``(q, v, a)``, each shape ``(T, m)``: each ``q``
        assembled from the previous one (continuation along the motion, from :meth:`moving_state`'s configuration)."""
        q = np.empty(np.shape(q_t)[:-1] + (self.nq,))
        guess = self.moving_state()[0]
        for k in range(len(q)):
            guess = q[k] = self.assemble(q_t[k], guess)
        v = self.complete_velocity(q, v_t)
        return q, v, self.complete_acceleration(q, v, a_t)


def _rebuild(derivation: Derivation, params: dict) -> DerivedModel:
    return model_class(derivation)(params)


class DerivedParams(Params):
    """The base of a derived model's parameter dataclass (made at run time, so pickled through its derivation)."""

    derivation = None  # set on the subclass

    def __reduce__(self):
        return (_rebuild_params, (type(self).derivation, self.as_dict()))


def _rebuild_params(derivation: Derivation, values: dict) -> Params:
    return model_class(derivation).Params(**values)


_CLASSES: dict[str, type] = {}


def model_class(d: Derivation) -> type:
    """The :class:`DerivedModel` subclass of a derivation (one per generated source, kept)."""
    source = source_of(d)
    key = hashlib.sha256(source.encode()).hexdigest()
    if key in _CLASSES:
        return _CLASSES[key]
    generated = load_generated(source)
    checks = d.checks or ("finite",) * len(d.params)
    fields = [
        (k, float, param(default, c, "", f"parameter {k} of {d.name}")) for (k, default), c in zip(d.params, checks)
    ]
    P = dataclasses.make_dataclass(f"{d.name}Params", fields, bases=(DerivedParams,), frozen=True)
    P.derivation = d
    n, nu = len(d.q), d.B.shape[1]
    body = {
        "Params": P, "nq": n, "nv": n, "nu": nu, "derivation": d, "generated": generated,
        "kernels": (generated.acceleration_kernel, generated.energy_kernel),
        "advance_kernel": staticmethod(generated.advance_kernel),
        "__doc__": f"{d.name}: derived by mbs_envs.models.symbolic from T = {d.T}, V = {d.V}.",
    }  # fmt: skip
    if d.nc:
        body.update(nc=d.nc, position_rows=tuple(range(d.nh)), independent=d.independent,
                    project_kernel=staticmethod(generated.project_kernel),
                    constraint_info_kernel=staticmethod(generated.constraint_info_kernel))  # fmt: skip
    cls = type(d.name, (ConstrainedDerivedModel if d.nc else DerivedModel,), body)
    _CLASSES[key] = cls
    return cls


def derive(name: str, q: Sequence[Any], T: Any, V: Any, params: Mapping[str, float], actuation: Any = None,
           damping: Mapping[Any, str] | None = None, **constraints: Any) -> DerivedModel:  # fmt: skip
    """A model from its Lagrangian: :func:`derive_equations` (``constraints``: its ``constraints``,
    ``velocity_constraints``, ``independent`` and ``friction``), then :func:`model_class`, at the default parameters.

    Example (a pendulum of mass ``m`` on a massless rod ``l``, ``q`` from hanging)::

        import sympy as sp
        from sympy.physics.mechanics import dynamicsymbols
        th = dynamicsymbols("th")
        m, l, g = sp.symbols("m l g")
        t = dynamicsymbols._t
        model = derive("Pendulum", [th], m * (l * th.diff(t)) ** 2 / 2, -m * g * l * sp.cos(th), {"m": 1.0, "l": 1.0, "g": 9.81})
    """
    return model_class(cached_derivation(name, q, T, V, params, actuation, damping, **constraints))()
