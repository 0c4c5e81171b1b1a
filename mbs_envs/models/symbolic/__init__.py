"""Models derived from a Lagrangian: SymPy derives, code generation compiles.

The lecture's method: write the kinetic and the potential energy in generalized coordinates, let a
computer-algebra system derive the equations of motion, simulate. Here
:class:`sympy.physics.mechanics.LagrangesMethod` derives them from ``L = T - V``::

    M(q) a = -(C(q, v) v + G(q)) + B u - F(v)

and :func:`derive` returns a :class:`~mbs_envs.models.base.Model` with the interface of the hand-written
ones (``mass_matrix``, ``coriolis``, ``gravity``, ``bias``, ``forward_dynamics``, ``inverse_dynamics``,
``energy``), so ``simulate``, the integrators and PD / computed torque / LQR work on it unchanged.

What is derived, and how:

- ``M`` is LagrangesMethod's mass matrix, ``-(C v + G)`` its forcing with no applied forces; ``G = dV/dq``
  is differentiated directly and ``C v`` is the rest (so ``coriolis`` and ``gravity`` are separate, as in
  the hand-written models). Viscous joint friction ``F_i = b_i v_i`` with ``b_i`` a parameter named per
  coordinate (``damping``), and any friction law of the rates as an expression (``friction``: Coulomb smoothed by
  ``tanh``, a Stribeck peak, ...), generated with the rest; the inputs enter through a constant actuation matrix ``B``.
- Code generation: SymPy's common-subexpression elimination over ``M`` (upper triangle), ``C v``, ``G``,
  ``T`` and ``V`` together, printed as straight-line Python of one member's scalars, compiled by numba in a
  module written to a cache folder and named by the SHA-256 of its source: a second process imports it
  (numba's own on-disk cache holds the machine code) and derives nothing again for the same expressions
  (:data:`CACHE`, default ``~/.cache/mbs_envs/derived``, or ``$MBS_ENVS_DERIVED_CACHE``).
- The compiled path: the generated module also holds the model's ``acceleration_kernel`` (``M`` by the
  generated code, a Cholesky solve), ``energy_kernel`` and ``advance_kernel`` (its binding of
  :func:`mbs_envs.dynamics.compiled.rk_run`), on the batch in columns as every model's
  (:mod:`mbs_envs.dynamics.compiled`); the numpy methods call the same generated code row by row. A derived
  model's parameters are the same for every member (one parameter column), so the accelerations run SIMD over
  the members (the sines and cosines of each distinct argument in one vectorized pass, the terms per member, the
  Cholesky solve over the columns), as fast as the hand-written ``Planar2R``'s step (``scripts/bench_derived.py``).
- Constraints: holonomic ``phi(q) = 0`` (loop closures) and non-holonomic ``A(q) v = 0`` (rolling) give
  ``Psi = [d phi / dq; A]`` and ``Psi_dot v``, generated with the rest; the model is a
  :class:`ConstrainedDerivedModel` (:class:`~mbs_envs.models.constrained.ConstrainedModel`'s Schur complement,
  multipliers and projection), its batch kernels SIMD over the members as well (:func:`_constrained_body`).

Refused with a ``ValueError`` naming the culprit: a coordinate whose rate does not appear in ``T`` (its row
of ``M`` is zero), a mass matrix that depends on the rates or is singular at the defaults, parameters without
defaults, with names that clash with the coordinates or with an unknown check, an actuation matrix of the wrong
shape, friction laws that hold coordinates or unknown symbols, and constraints that hold rates (holonomic) or are not linear in them (non-holonomic), that are dependent,
or whose ``independent`` coordinates do not fix the others' rates.
"""

from .cache import CACHE, cached_derivation, load_generated, source_of
from .codegen import generate_source
from .derivation import FORMAT, Derivation, derive_equations, dynamicsymbols, supported_terms, time_symbol
from .model import ConstrainedDerivedModel, DerivedModel, DerivedParams, derive, model_class

__all__ = [
    "CACHE",
    "ConstrainedDerivedModel",
    "Derivation",
    "DerivedModel",
    "DerivedParams",
    "FORMAT",
    "cached_derivation",
    "derive",
    "derive_equations",
    "dynamicsymbols",
    "generate_source",
    "load_generated",
    "model_class",
    "source_of",
    "supported_terms",
    "time_symbol",
]
