"""The shared model interface: validated parameters and the equations of motion

    M(q) a + C(q, v) v + G(q) + F(v) = B u                         (docs/physics.md §1)

for unconstrained mechanisms, with forward dynamics through a Cholesky
factorization of ``M``. Constrained mechanisms extend this with their own
``forward_dynamics`` (see :mod:`mbs_envs.dynamics.constraints`); serial ones pay nothing
for constraints.

Conventions: every function is pure and batched. ``q`` has shape ``(..., nq)``,
``v`` and ``a`` ``(..., nv)``, ``u`` ``(..., nu)``; leading dimensions broadcast.
Units are SI (rad, m, kg, s, N m).
"""

from __future__ import annotations

import abc
import copy
import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from .. import validation as check
from ..validation import as_vector  # noqa: F401  (the models' argument check, served here as before)
from ..dynamics.linalg import batched_matvec, cholesky_solve

# ---------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------

_CHECKS = {
    "positive": (lambda x: x > 0, "must be > 0"),
    "nonnegative": (lambda x: x >= 0, "must be >= 0"),
    "finite": (lambda x: np.ones_like(x, dtype=bool), "must be finite"),
}


def param(default: Any, check: str = "finite", unit: str = "", doc: str = "") -> Any:
    """Declare a model parameter field with its validity check, unit and meaning.

    Parameters
    ----------
    default : float or array_like
        Documented default value.
    check : {"positive", "nonnegative", "finite"}
        Condition every entry must satisfy (all must also be finite).
    unit, doc : str
        SI unit and one-line meaning, used in error messages and docs.
    """
    if check not in _CHECKS:
        raise ValueError(f"unknown parameter check {check!r}")
    return dataclasses.field(default=default, metadata={"check": check, "unit": unit, "doc": doc})


@dataclasses.dataclass(frozen=True)
class Params:
    """Base of the frozen parameter dataclasses of every model.

    Each field is converted to ``float`` (or a read-only float array) and
    checked at construction; a violation raises ``ValueError`` naming the
    parameter. Subclasses add cross-parameter checks in :meth:`_check`.
    """

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            scalar = f.type in (float, int, "float", "int")  # fields typed Any may hold arrays
            arr = check.reals(value, f"parameter {f.name!r}")
            if scalar and arr.ndim != 0:
                raise ValueError(f"parameter {f.name!r} must be a real number, got {value!r}")
            test, message = _CHECKS[f.metadata.get("check", "finite")]
            if not np.all(np.isfinite(arr) & test(arr) & (np.abs(arr) <= check.PARAM_MAX)):
                raise ValueError(
                    f"parameter {f.name!r} {message}, finite and at most {check.PARAM_MAX:g} in magnitude, got {value!r}"
                )
            if scalar:
                object.__setattr__(self, f.name, float(arr))
            else:
                arr.flags.writeable = False
                object.__setattr__(self, f.name, arr)
        with np.errstate(all="raise"):
            try:
                self._check()
            except (OverflowError, FloatingPointError) as err:
                raise ValueError(
                    f"parameters of {type(self).__name__} overflow in their consistency checks ({err}): {self!r}"
                ) from None

    def _check(self) -> None:
        """Cross-parameter validity checks (override); raise ``ValueError``."""

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Names of all parameters, in declaration order."""
        return tuple(f.name for f in dataclasses.fields(cls))

    def replace(self, **overrides: Any) -> "Params":
        """Return a validated copy with some parameters changed.

        Raises
        ------
        ValueError
            For an unknown parameter name or an invalid value.
        """
        unknown = sorted(set(overrides) - set(self.names()))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown} for {type(self).__name__}; known: {list(self.names())}")
        return dataclasses.replace(self, **overrides)

    def batched(self, **values: np.ndarray) -> "Params":
        """A copy whose named scalar parameters hold one value per batch member, shape ``(B,)``.

        For domain randomization in a batched environment: each member's
        values must have been validated already (e.g. through :meth:`replace`);
        they are not checked again here. Only models with
        ``batched_params = True`` accept such parameters.
        """
        unknown = sorted(set(values) - set(self.names()))
        if unknown:
            raise ValueError(f"unknown parameter(s) {unknown} for {type(self).__name__}")
        new = copy.copy(self)
        for name, value in values.items():
            if np.ndim(getattr(self, name)) != 0:
                raise ValueError(f"parameter {name!r} is an array; only scalar parameters can be batched")
            object.__setattr__(new, name, np.asarray(value, float))
        return new

    def as_dict(self) -> dict[str, Any]:
        """Parameters as a plain dict (arrays as lists), e.g. for JSON."""
        out = {}
        for name in self.names():
            value = getattr(self, name)
            out[name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out


# ---------------------------------------------------------------------------
# Array helpers
# ---------------------------------------------------------------------------


def friction_law(v, b, f, v_s):
    """``b v + f tanh(v / v_s)`` [N m] for floats or broadcasting arrays (the formula of :func:`smoothed_friction`)."""
    return b * v + f * np.tanh(v / v_s)


def stribeck_law(v, df, v_st, v_s):
    """``df exp(-(v / v_st)^2) tanh(v / v_s)`` [N m]: the Stribeck peak, static friction ``df`` above
    the Coulomb level, fading over the speed ``v_st``; smooth (floats or broadcasting arrays)."""
    return df * np.exp(-((v / v_st) ** 2)) * np.tanh(v / v_s)


def smoothed_friction(
    v: np.ndarray, b: np.ndarray, f: np.ndarray, v_s: float, df: np.ndarray | None = None, v_st: float = 0.1
) -> np.ndarray:
    """Joint friction ``F_i(v) = b_i v_i + f_i tanh(v_i / v_s)`` (docs/physics.md §1), plus the
    Stribeck peak ``df_i exp(-(v_i / v_st)^2) tanh(v_i / v_s)`` where ``df`` is given and nonzero
    (:func:`stribeck_law`; at rest the friction then reaches ``f_i + df_i``).

    Parameters
    ----------
    v : ndarray, shape (..., n)
        Joint rates [rad/s].
    b : ndarray, shape (n,)
        Viscous coefficients [N m s/rad].
    f : ndarray, shape (n,)
        Coulomb levels [N m], smoothed by ``tanh``.
    v_s : float
        Smoothing speed [rad/s]; small values make the equations stiff.
    df : ndarray, shape (n,), optional
        Stribeck excess [N m]: static friction above the Coulomb level (default none).
    v_st : float
        Stribeck speed [rad/s] over which that excess fades.

    Returns
    -------
    ndarray, shape (..., n)
        Friction torques opposing the motion [N m].
    """
    b, f = np.asarray(b), np.asarray(f)
    if np.any(f):
        F = friction_law(v, b, f, v_s)
    else:  # the tanh is the costly part: frictionless models skip it (and zero b the product)
        F = b * v if np.any(b) else np.zeros(np.broadcast_shapes(np.shape(v), b.shape))
    if df is not None and np.any(df):
        F = F + stribeck_law(v, np.asarray(df), v_st, v_s)
    return F


# ---------------------------------------------------------------------------
# Model
# ---------------------------------------------------------------------------


class Model(abc.ABC):
    """Equations of motion of one mechanism; stateless and batched.

    Subclasses declare ``Params`` (a :class:`Params` dataclass), ``nq``,
    ``nv``, ``nu`` and implement :meth:`mass_matrix`, :meth:`coriolis`,
    :meth:`gravity`, :meth:`potential_energy`, :meth:`friction` and
    :attr:`actuation`. Everything else (bias, forward and inverse dynamics,
    energy and power) follows here once for all unconstrained models.

    Construct with keyword overrides of the documented defaults,
    ``Model(m1=2.0)``, a mapping, ``Model({"m1": 2.0})``, or a ready
    ``Params`` instance.
    """

    Params: ClassVar[type[Params]]
    nq: ClassVar[int]
    nv: ClassVar[int]
    nu: ClassVar[int]
    #: Whether the model carries constraints (serial models: never).
    constrained: ClassVar[bool] = False
    #: Number of constraint rows ``Psi`` (serial models: none).
    nc: ClassVar[int] = 0
    #: Whether the equations accept per-batch-member parameters (:meth:`Params.batched`).
    batched_params: ClassVar[bool] = False
    #: Compiled ``(acceleration_kernel, energy_kernel)`` of one member, built on the
    #: same formulas as the numpy methods, or None (numpy only); see :mod:`mbs_envs.dynamics.compiled`.
    kernels: ClassVar[tuple | None] = None
    #: The model's binding of :func:`mbs_envs.dynamics.compiled.rk_run` (a module-level, disk-cached
    #: kernel ``(theta, stepper, q, v, tau)``), with ``kernels``; None otherwise.
    advance_kernel: ClassVar[Any] = None

    def kernel_params(self) -> np.ndarray:
        """The parameters as the kernels take them: in field order, shape ``(P,)``, or ``(B, P)``
        with per-member parameters (the kernels read them as columns, :func:`mbs_envs.dynamics.compiled.batch_theta`)."""
        return np.stack(np.broadcast_arrays(*(getattr(self.params, k) for k in self.Params.names())), axis=-1)

    def __init__(self, params: Params | Mapping[str, Any] | None = None, **overrides: Any):
        if params is None:
            params = self.Params()
        elif isinstance(params, Mapping):
            overrides = {**params, **overrides}
            params = self.Params()
        elif not isinstance(params, self.Params):
            raise ValueError(f"params must be a {self.Params.__name__}, a mapping or None, got {params!r}")
        self.params = params.replace(**overrides) if overrides else params

    def with_params(self, params: Params) -> "Model":
        """The same model with other (already validated, possibly batched) parameters."""
        new = copy.copy(self)
        new.params = params
        return new

    def __repr__(self) -> str:
        changed = {k: v for k, v in self.params.as_dict().items() if np.any(v != self.Params().as_dict()[k])}
        args = ", ".join(f"{k}={v!r}" for k, v in changed.items())
        return f"{type(self).__name__}({args})"

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self.params.as_dict() == other.params.as_dict()

    def __hash__(self) -> int:
        return hash((type(self).__name__, repr(sorted(self.params.as_dict().items()))))

    # -- to implement per mechanism ------------------------------------------

    @property
    @abc.abstractmethod
    def actuation(self) -> np.ndarray:
        """Actuation matrix ``B``, shape ``(nv, nu)``: inputs to generalized forces."""

    @abc.abstractmethod
    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Mass matrix ``M(q)``, shape ``(..., nv, nv)``, symmetric positive definite."""

    @abc.abstractmethod
    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Centripetal and Coriolis forces ``C(q, v) v``, shape ``(..., nv)``."""

    @abc.abstractmethod
    def gravity(self, q: np.ndarray) -> np.ndarray:
        """Generalized gravity forces ``G(q) = dV/dq``, shape ``(..., nv)``."""

    @abc.abstractmethod
    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        """Potential energy ``V(q)`` [J], shape ``(...)``."""

    @abc.abstractmethod
    def friction(self, v: np.ndarray) -> np.ndarray:
        """Friction forces ``F(v)``, shape ``(..., nv)`` (zero by default)."""

    def singular(self, q: np.ndarray) -> np.ndarray:
        """Whether ``q`` is at or past a singularity of the coordinates (none by default).

        Simulations stop there and report divergence rather than return NaN.
        """
        return np.zeros(np.shape(q)[:-1], dtype=bool)

    # -- derived, shared by every unconstrained model -------------------------

    def moving_state(self) -> tuple[np.ndarray, np.ndarray]:
        """A moving state the equations can start from (examples, edge runs): ``q = 0.3``,
        ``v = 0.5`` in every coordinate; constrained models give one on their constraints."""
        return np.full(self.nq, 0.3), np.full(self.nv, 0.5)

    def make_consistent(self, q: np.ndarray, v: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
        """A state the equations can start from: ``(q, v)`` unchanged (no constraints).

        Constrained models project onto their constraints (or refuse the state).
        """
        return q, v

    def constraint_violation(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``max(|phi(q)|, |Psi(q) v|)`` per sample, shape ``(...)``: zero without constraints."""
        return np.zeros(np.broadcast_shapes(np.shape(q)[:-1], np.shape(v)[:-1]))

    def motion_from_tracked(
        self, q_t: np.ndarray, v_t: np.ndarray, a_t: np.ndarray, branch: int = 1
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The whole motion ``(q, v, a)`` from that of the coordinates a task tracks.

        A serial model tracks all of them (returned as given); constrained models
        complete the dependent ones (assembly ``branch`` where there are several).
        """
        return q_t, v_t, a_t

    def stabilization(self, kind: Any = None, **options: Any) -> None:
        """Constraint stabilization for a simulation: none for unconstrained models.

        Raises
        ------
        ValueError
            If a stabilization other than ``None``/``"none"`` is asked for.
        """
        if kind not in (None, "none") or options:
            raise ValueError(
                f"{type(self).__name__} has no constraints; stabilization must be None or 'none', got {kind!r}"
            )
        return None

    def bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Bias forces ``h = C(q, v) v + G(q) + F(v)``, shape ``(..., nv)``."""
        q = as_vector(q, self.nq, "q")
        v = as_vector(v, self.nv, "v")
        return self.coriolis(q, v) + self.gravity(q) + self.friction(v)

    def generalized_input(self, u: np.ndarray | None) -> np.ndarray:
        """Generalized forces of the inputs ``B u``, shape ``(..., nv)``; ``u=None`` is zero."""
        if u is None:
            return np.zeros(self.nv)
        return batched_matvec(self.actuation, as_vector(u, self.nu, "u"))

    def forward_dynamics(self, q: np.ndarray, v: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Accelerations ``a = M(q)^-1 (B u - h(q, v))`` by Cholesky factorization.

        Parameters
        ----------
        q : ndarray, shape (..., nq)
        v : ndarray, shape (..., nv)
        u : ndarray, shape (..., nu), or None for no input

        Returns
        -------
        a : ndarray, shape (..., nv)
        """
        q = as_vector(q, self.nq, "q")
        v = as_vector(v, self.nv, "v")
        rhs = self.generalized_input(u) - self.bias(q, v)
        return cholesky_solve(self.mass_matrix(q), rhs)

    def shifted_forward_dynamics(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Accelerations ``a = (M(q) + diag(d))^-1 (tau - C(q, v) v - G(q))``, friction not included.

        The solve of :class:`mbs_envs.dynamics.integrators.JointImplicitEuler`, where
        ``d = h D + h^2 K`` folds joint damping and stiffness into the mass matrix.
        Here by Cholesky, O(n^3); :class:`~mbs_envs.models.serial_chain.SerialChain`
        does it in O(N) by its articulated-body recursion (``d`` added to the armature).

        Parameters
        ----------
        q : ndarray, shape (..., nq)
        v, tau : ndarray, shape (..., nv)
            Rates [rad/s] and generalized forces [N m].
        d : ndarray, shape (..., nv)
            Added to the diagonal of ``M`` [kg m^2], >= 0.

        Returns
        -------
        a : ndarray, shape (..., nv)
        """
        q = as_vector(q, self.nq, "q")
        v = as_vector(v, self.nv, "v")
        M = self.mass_matrix(q) + np.asarray(d)[..., None] * np.eye(self.nv)
        return cholesky_solve(M, as_vector(tau, self.nv, "tau") - self.coriolis(q, v) - self.gravity(q))

    def friction_slope(self, v: np.ndarray) -> np.ndarray:
        """``dF_i / dv_i`` [N m s/rad], shape ``(..., nv)``: the diagonal of the friction's Jacobian.

        Every model's friction is joint-wise (``F_i`` depends on ``v_i`` alone), so one
        central difference with all rates perturbed at once gives the diagonal
        (step ``1e-6 max(1, |v_i|)``; the slope only linearizes the implicit step).
        """
        v = as_vector(v, self.nv, "v")
        eps = 1e-6 * np.maximum(1.0, np.abs(v))
        return (self.friction(v + eps) - self.friction(v - eps)) / (2.0 * eps)

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Inputs ``u`` with ``B u = M(q) a + h(q, v)`` (fully actuated models).

        Parameters
        ----------
        q : ndarray, shape (..., nq)
        v, a : ndarray, shape (..., nv)

        Returns
        -------
        u : ndarray, shape (..., nu)

        Raises
        ------
        NotImplementedError
            If ``B`` is not square (under-actuated without constraints).
        """
        q = as_vector(q, self.nq, "q")
        a = as_vector(a, self.nv, "a")
        tau = batched_matvec(self.mass_matrix(q), a) + self.bias(q, v)
        B = self.actuation
        if B.shape[0] != B.shape[1]:
            raise NotImplementedError(
                f"{type(self).__name__} is under-actuated (B is {B.shape}); "
                "no input reproduces an arbitrary acceleration"
            )
        if np.array_equal(B, np.eye(self.nv)):
            return tau
        return np.linalg.solve(B, tau[..., None])[..., 0]

    def kinetic_energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Kinetic energy ``T = v^T M(q) v / 2`` [J], shape ``(...)``."""
        v = as_vector(v, self.nv, "v")
        return 0.5 * np.einsum("...i,...i->...", v, batched_matvec(self.mass_matrix(q), v))

    def energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Total mechanical energy ``T + V`` [J], shape ``(...)``."""
        return self.kinetic_energy(q, v) + self.potential_energy(q)

    def input_power(self, v: np.ndarray, u: np.ndarray | None) -> np.ndarray:
        """Power of the inputs ``v . B u`` [W], shape ``(...)``."""
        v = as_vector(v, self.nv, "v")
        return np.einsum("...i,...i->...", v, self.generalized_input(u))

    def friction_power(self, v: np.ndarray) -> np.ndarray:
        """Power dissipated by friction ``v . F(v) >= 0`` [W], shape ``(...)``.

        Along any motion ``dE/dt = input_power - friction_power``.
        """
        v = as_vector(v, self.nv, "v")
        return np.einsum("...i,...i->...", v, self.friction(v))
