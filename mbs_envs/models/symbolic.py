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

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib.util
import keyword
import os
import pathlib
import sys
import threading
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..dynamics import constraints as _constraints
from ..dynamics.jit import package_stamp
from .base import Model, Params, as_vector, param
from .constrained import ConstrainedModel


def time_symbol() -> Any:
    """The time ``t``: ``sympy.Symbol("t")``, the symbol :mod:`sympy.physics.mechanics` differentiates by
    (``dynamicsymbols._t``, equal to it)."""
    import sympy as sp

    return sp.Symbol("t")


def dynamicsymbols(names: str) -> Any:
    """Coordinates as functions of time, ``q(t)``: what ``sympy.physics.mechanics.dynamicsymbols(names)`` returns
    (the same objects: equal, the same ``srepr``, so the same derivation cache entry), without importing
    :mod:`sympy.physics`, whose units package alone takes 0.1 s of a process's start (docs/performance.md). The
    derivation imports it when it derives; a warm process reading the cache never does.

    Parameters
    ----------
    names : str
        One name, or several separated by spaces or commas (``sympy.symbols``' syntax).

    Returns
    -------
    sympy expression, or list of them
        ``f(t)`` for each name, a list where ``names`` names several.
    """
    import sympy as sp

    fs = sp.symbols(names, cls=sp.Function)
    t = time_symbol()
    return [f(t) for f in fs] if isinstance(fs, (tuple, list)) else fs(t)


#: where generated modules are kept (``$MBS_ENVS_DERIVED_CACHE`` overrides)
CACHE = pathlib.Path(os.environ.get("MBS_ENVS_DERIVED_CACHE", pathlib.Path.home() / ".cache" / "mbs_envs" / "derived"))


@dataclasses.dataclass(frozen=True)
class Derivation:
    """The derived equations in plain symbols: ``q_i, v_i`` for the coordinates and their rates.

    Attributes
    ----------
    name : str
    q, v : tuple of sympy.Symbol
        Coordinates and rates.
    params : tuple of (str, float)
        Parameter names and defaults, in the order the kernels read them.
    M : sympy.Matrix, shape (n, n)
    Cv, G : sympy.Matrix, shape (n, 1)
    T, V : sympy.Expr
    B : ndarray, shape (n, nu)
    damping : tuple of str or None
        The viscous friction parameter of each coordinate (None: none).
    """

    name: str
    q: tuple
    v: tuple
    params: tuple
    M: Any
    Cv: Any
    G: Any
    T: Any
    V: Any
    B: np.ndarray
    damping: tuple
    phi: Any = None
    Psi: Any = None
    Psidv: Any = None
    independent: tuple = ()
    #: the validity check of each parameter (``"finite"``, ``"positive"``, ``"nonnegative"``), as ``params``
    checks: tuple = ()
    #: the friction law's generalized forces ``F_i(v)`` (sympy.Matrix (n, 1) in the rates and parameters), or None
    F: Any = None

    @property
    def nc(self) -> int:
        """Rows of ``Psi`` (0 without constraints)."""
        return 0 if self.Psi is None else self.Psi.shape[0]

    @property
    def nh(self) -> int:
        """Holonomic rows (the first ``nh`` rows of ``Psi`` are ``d phi / d q``)."""
        return 0 if self.phi is None else self.phi.shape[0]


#: the version of what a cached derivation holds (part of the cache key)
FORMAT = 3


def derive_equations(name: str, q: Sequence[Any], T: Any, V: Any, params: Mapping[str, float],
                     actuation: Any = None, damping: Mapping[Any, str] | None = None, constraints: Sequence[Any] = (),
                     velocity_constraints: Sequence[Any] = (), independent: Sequence[Any] | None = None, *,
                     friction: Mapping[Any, Any] | None = None) -> Derivation:  # fmt: skip
    """Lagrange's equations of ``L = T - V`` by :class:`sympy.physics.mechanics.LagrangesMethod`.

    Parameters
    ----------
    name : str
        A Python identifier (the model's class name).
    q : sequence of sympy dynamicsymbols
        The generalized coordinates ``q_i(t)``; ``T`` holds their rates as ``q_i.diff(t)``.
    T, V : sympy expressions
        Kinetic and potential energy [J].
    params : mapping
        Every other symbol in ``T`` and ``V`` by name, with its default value, or ``(default, check)`` with
        ``check`` one of ``"finite"`` (the default), ``"positive"``, ``"nonnegative"``: what the model's parameter
        dataclass accepts (a mass of 0 refused with a ``ValueError`` naming it, as the hand-written models').
    actuation : array_like, shape (n, nu), optional
        ``B`` (default the identity: every coordinate driven).
    damping : mapping, optional
        Coordinate -> name of its viscous friction parameter (a key of ``params``).
    friction : mapping, optional
        Coordinate -> its friction law, the generalized force ``F_i`` opposing the motion [N m or N] as an expression
        in the rates ``q_j.diff(t)`` and the parameters (e.g. Coulomb smoothed and a Stribeck peak,
        ``f tanh(w / v_s) + df exp(-(w / v_st)^2) tanh(w / v_s)`` with ``w = q_i.diff(t)``); added to ``damping``'s.
    constraints : sequence of sympy expressions, optional
        Holonomic constraints ``phi_k(q) = 0`` [m or rad] (loop closures): functions of the coordinates alone.
        Their Jacobian ``d phi / d q`` is the first rows of ``Psi``.
    velocity_constraints : sequence of sympy expressions, optional
        Non-holonomic constraints ``A_k(q) dq/dt = 0`` (rolling): linear and homogeneous in the rates; the
        coefficients ``A_k`` are the further rows of ``Psi``.
    independent : sequence of coordinates (or their indices), optional
        With constraints: the ``n - nc`` coordinates whose rates parametrize the motion (the ones a task
        prescribes); the constraints must determine the others' rates from them.

    Raises
    ------
    ValueError
        Naming the culprit (module docstring).
    """
    import sympy as sp
    from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols

    if not (isinstance(name, str) and name.isidentifier()):
        raise ValueError(f"name must be a Python identifier, got {name!r}")
    q = tuple(q)
    n = len(q)
    if n == 0:
        raise ValueError("q: at least one coordinate")
    t = dynamicsymbols._t
    qs = sp.symbols(f"q0:{n}", real=True)
    vs = sp.symbols(f"v0:{n}", real=True)
    names = {str(s) for s in qs + vs}
    params, checks = _split_params(params, names)
    T, V = sp.sympify(T), sp.sympify(V)
    unknown = sorted(str(s) for s in (T.free_symbols | V.free_symbols) - {t} if str(s) not in params)
    if unknown:
        raise ValueError(f"T and V use symbols without a value in params: {unknown}")
    rates = {qi.diff(t): vi for qi, vi in zip(q, vs)}
    coords = {qi: qs_i for qi, qs_i in zip(q, qs)}

    def plain(
        e,
    ):  # rates first (a coordinate replaced inside its derivative would leave d(q0)/dt); no simplify: CSE does the work
        return sp.sympify(e).xreplace(rates).xreplace(coords)

    for label, e in (("T", T), ("V", V)):
        supported_terms(plain(e), label, t)

    lm = LagrangesMethod(T - V, list(q))
    lm.form_lagranges_equations()
    M = lm.mass_matrix.applyfunc(plain)
    forcing = lm.forcing.applyfunc(plain)
    for i in range(n):
        if all(M[i, j] == 0 for j in range(n)):
            raise ValueError(f"coordinate {q[i]} is missing from T: its rate does not appear, its row of M is zero")
    if any(s in M.free_symbols for s in vs):
        raise ValueError("the mass matrix depends on the rates: T must be quadratic in the rates")
    Vp = plain(V)
    G = sp.Matrix([sp.diff(Vp, qi) for qi in qs])
    Cv = (-forcing - G).applyfunc(sp.expand)
    B = np.eye(n) if actuation is None else np.asarray(actuation, float)
    if B.ndim != 2 or B.shape[0] != n or not np.all(np.isfinite(B)):
        raise ValueError(f"actuation must be a finite (n, nu) array with n = {n}, got shape {B.shape}")
    damp = [None] * n
    for coord, pname in (damping or {}).items():
        if coord not in q:
            raise ValueError(f"damping: {coord} is not a coordinate")
        if pname not in params:
            raise ValueError(f"damping: parameter {pname!r} is not in params")
        damp[q.index(coord)] = pname
    d = Derivation(name, qs, vs, tuple((k, float(v)) for k, v in params.items()), M, Cv, G, plain(T), Vp, B, tuple(damp),
                   checks=checks, F=_friction_rows(q, qs, vs, plain, params, friction))  # fmt: skip
    _check_mass_matrix(d)
    if not (constraints or velocity_constraints):
        if independent is not None:
            raise ValueError("independent: only a mechanism with constraints names independent coordinates")
        return d
    phi, Psi, Psidv = _constraint_rows(q, qs, vs, plain, params, constraints, velocity_constraints)
    d = dataclasses.replace(d, phi=phi, Psi=Psi, Psidv=Psidv)
    return dataclasses.replace(d, independent=_independent(d, q, independent))


def _friction_rows(q, qs, vs, plain, params, friction) -> Any:
    """The friction law's ``F (n, 1)`` in plain symbols (zero where no law), or None without laws; refuses a law on
    a non-coordinate, one that holds a coordinate (a law of the rates alone), or unknown symbols, by name."""
    import sympy as sp
    from sympy.physics.mechanics import dynamicsymbols

    if not friction:
        return None
    if not isinstance(friction, Mapping):
        raise ValueError(f"friction must be a mapping of coordinates to expressions, got {type(friction).__name__}")
    F = [sp.Integer(0)] * len(q)
    for coord, law in friction.items():
        if coord not in q:
            raise ValueError(f"friction: {coord} is not a coordinate")
        e = plain(law)
        held = sorted(str(q[i]) for i, x in enumerate(qs) if x in e.free_symbols)
        if held:
            raise ValueError(f"friction: the law of {coord} is not a function of the rates alone: it holds {held}")
        unknown = sorted(str(x) for x in e.free_symbols - set(vs) - {dynamicsymbols._t} if str(x) not in params)
        if unknown:
            raise ValueError(f"friction: the law of {coord} uses symbols without a value in params: {unknown}")
        supported_terms(e, f"friction: the law of {coord}", dynamicsymbols._t)
        F[q.index(coord)] = e
    return sp.Matrix(F)


def supported_terms(e: Any, label: str, t: Any) -> None:
    """Refuse, naming the term, what the generated code cannot compute smoothly: a function other than the smooth
    elementary ones (``Abs``, ``sign``, ``floor``, ``Heaviside``, ``Piecewise``, ``Max``, an undefined function),
    a complex number, and an explicit dependence on time ``t`` (``e`` is in the plain symbols: coordinates replaced).

    Raises
    ------
    ValueError
        Naming ``label`` and the first such term.
    """
    import sympy as sp
    from sympy.core.function import Application

    smooth = (sp.sin, sp.cos, sp.tan, sp.exp, sp.log, sp.tanh, sp.sinh, sp.cosh, sp.atan, sp.asin, sp.acos, sp.atan2)
    for node in sp.preorder_traversal(e):
        if node == t:
            raise ValueError(f"{label} depends on time explicitly (the term {e}): only through the coordinates")
        if node.is_number and node.is_real is False:
            raise ValueError(f"{label} holds a complex number ({node}): T, V and the laws must be real")
        if isinstance(node, Application) and not isinstance(node, smooth):
            raise ValueError(f"{label} holds {node}: {type(node).__name__} is not supported (smooth elementary functions "
                             "only: sin, cos, tan, exp, log, sqrt and powers, tanh, sinh, cosh, atan, asin, acos, atan2)")  # fmt: skip


def _split_params(params: Mapping[str, Any], names: set) -> tuple[dict, tuple]:
    """``params`` as ``{name: default}`` and the checks in its order (see :func:`derive_equations`), validated."""
    from .base import _CHECKS

    defaults, checks = {}, []
    for key, value in dict(params).items():
        if not (isinstance(key, str) and key.isidentifier()) or key in names or keyword.iskeyword(key):
            raise ValueError(f"params: {key!r} is not a usable parameter name (identifiers other than Python's keywords "
                             f"and {sorted(names)})")  # fmt: skip
        default, kind = value if isinstance(value, tuple) and len(value) == 2 else (value, "finite")
        if kind not in _CHECKS:
            raise ValueError(f"params: {key!r} has the check {kind!r}; one of {sorted(_CHECKS)}")
        try:
            ok = bool(np.isfinite(float(default)) and _CHECKS[kind][0](float(default)))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"params: {key!r} needs a finite default that is {kind}, got {value!r}")
        defaults[key] = float(default)
        checks.append(kind)
    return defaults, tuple(checks)


def _numeric(d: Derivation, exprs: Any, samples: int = 3) -> list[np.ndarray]:
    """``exprs`` (a matrix in ``q``) at ``samples`` random configurations ``q ~ U(-pi, pi)`` and the default parameters."""
    import sympy as sp

    exprs = sp.Matrix(exprs)
    values = dict(d.params)
    f = sp.lambdify([d.q], exprs.xreplace({s: values[str(s)] for s in exprs.free_symbols if str(s) in values}), "numpy")
    rng = np.random.default_rng(0)
    return [np.asarray(f(x), float) for x in rng.uniform(-np.pi, np.pi, (samples, len(d.q)))]


def _check_mass_matrix(d: Derivation) -> None:
    """Refuse a mass matrix that is singular at the default parameters (at every one of three random
    configurations: ``T`` then does not fix every acceleration, e.g. two rates only ever appearing summed)."""
    values = [np.linalg.eigvalsh(M) for M in _numeric(d, d.M)]
    if all(not (w[0] > 1e-12 * max(abs(w[-1]), 1e-300)) for w in values):
        w = values[0]
        raise ValueError(f"the mass matrix of {d.name} is singular (eigenvalues {np.round(w, 12).tolist()} at a random q with "
                         "the default params): T does not determine every acceleration (a coordinate only appears in a "
                         "combination with others, or a body without mass or inertia)")  # fmt: skip


def _constraint_rows(q, qs, vs, plain, params, constraints, velocity_constraints):
    """``phi`` (nh, 1), ``Psi`` (nc, n) and ``Psi_dot v`` (nc, 1) of the constraints, each checked (see
    :func:`derive_equations`)."""
    import sympy as sp

    known = set(qs) | set(vs) | {sp.Symbol(k) for k in params} | {sp.Symbol(k, real=True) for k in params}

    def checked(kind, k, c):
        e = plain(c)
        unknown = sorted(str(s) for s in e.free_symbols - known if str(s) not in params)
        if unknown:
            raise ValueError(f"{kind}[{k}] = {c} uses symbols without a value in params: {unknown}")
        return e

    phi = []
    for k, c in enumerate(constraints):
        e = checked("constraints", k, c)
        if e.free_symbols & set(vs):
            raise ValueError(f"constraints[{k}] = {c} is not a function of the coordinates alone: it holds their rates "
                             "(a constraint on the rates goes in velocity_constraints)")  # fmt: skip
        if not e.free_symbols & set(qs):
            raise ValueError(f"constraints[{k}] = {c} is not a function of the coordinates: it holds none of {list(q)}")
        phi.append(e)
    rows = [[sp.diff(e, x) for x in qs] for e in phi]
    for k, c in enumerate(velocity_constraints):
        e = checked("velocity_constraints", k, c)
        A = [sp.diff(e, w) for w in vs]
        linear = not any(a.free_symbols & set(vs) for a in A) and sp.expand(e - sum(a * w for a, w in zip(A, vs))) == 0
        if not linear or all(a == 0 for a in A):
            raise ValueError(
                f"velocity_constraints[{k}] = {c} must be linear and homogeneous in the rates, A(q) dq/dt = 0"
            )
        rows.append(A)
    Psi = sp.Matrix(rows)
    n = len(qs)
    Psidv = sp.Matrix([sum(sp.diff(sum(Psi[k, j] * vs[j] for j in range(n)), qs[i]) * vs[i] for i in range(n))
                       for k in range(Psi.shape[0])])  # fmt: skip
    return sp.Matrix(phi) if phi else None, Psi, Psidv.applyfunc(sp.expand)


def _independent(d: Derivation, q: tuple, independent: Any) -> tuple:
    """The indices of the independent coordinates, checked: ``n - nc`` of them, the others' rates fixed by the
    constraints (``Psi`` restricted to the dependent columns is regular at random configurations)."""
    n, nc = len(q), d.nc
    if nc >= n:
        raise ValueError(f"constraints: {nc} constraint rows leave no motion to {n} coordinates")
    if independent is None:
        raise ValueError(
            f"independent: a constrained mechanism names the {n - nc} coordinates that parametrize its motion"
        )
    idx = []
    for c in independent:
        i = c if isinstance(c, (int, np.integer)) and not isinstance(c, bool) else (q.index(c) if c in q else None)
        if i is None or not 0 <= i < n or i in idx:
            raise ValueError(f"independent: {c!r} is not one of the coordinates {list(q)} (each once)")
        idx.append(int(i))
    if len(idx) != n - nc:
        raise ValueError(f"independent: {len(idx)} coordinates given, but {n} coordinates with {nc} constraint rows "
                         f"move with {n - nc}")  # fmt: skip
    dep = [i for i in range(n) if i not in idx]
    if all(np.linalg.matrix_rank(P[:, dep]) < nc for P in _numeric(d, d.Psi)):
        raise ValueError(f"constraints / independent: the constraint rows are dependent, or do not fix the rates of "
                         f"{[q[i] for i in dep]} from those of {[q[i] for i in idx]} (Psi's dependent columns are singular)")  # fmt: skip
    return tuple(idx)


# ---------------------------------------------------------------------------------------------
# code generation


def generate_source(d: Derivation) -> str:
    """The module of one derived model: ``terms(q, v, p, M, Cv, G, E)`` of one member and ``rows`` over rows (the
    numpy path's; straight-line code after common-subexpression elimination), the kernels over columns
    (:func:`_columns_body`, or :func:`_constrained_body` with constraints), ``energy_kernel``, ``advance_kernel``
    and the tracking scene's ``step_kernel``."""
    import sympy as sp
    from sympy.printing.numpy import NumPyPrinter

    n = len(d.q)
    psyms = [
        sp.Symbol(f"_p{k}", real=True) for k in range(len(d.params))
    ]  # the code's names: no clash with its locals (b, A, S, C, ...)
    by_name = {k: s for (k, _), s in zip(d.params, psyms)}

    def plain(e):  # the parameters as the real symbols the code reads, whatever assumptions the user's carried
        e = sp.sympify(e)
        return e.xreplace({s: by_name[str(s)] for s in e.free_symbols if str(s) in by_name})

    upper = [(i, j) for i in range(n) for j in range(i, n)]
    exprs = [plain(e) for e in [d.M[i, j] for i, j in upper] + list(d.Cv) + list(d.G) + [d.T, d.V]]
    reps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("x"), optimizations="basic")
    printer = NumPyPrinter({"fully_qualified_modules": True, "inline": True, "allow_unknown_functions": False})

    def code(e):
        return printer.doprint(e).replace("numpy.", "np.")

    head = [f"    {s} = q[{i}]" for i, s in enumerate(d.q)] + [f"    {s} = v[{i}]" for i, s in enumerate(d.v)]
    head += [f"    {s} = p[{k}]" for k, s in enumerate(psyms)]
    body = [f"    {s} = {code(e)}" for s, e in reps]
    out = [
        f"    M[{i}, {j}] = {code(reduced[k])}" + (f"\n    M[{j}, {i}] = M[{i}, {j}]" if i != j else "")
        for k, (i, j) in enumerate(upper)
    ]
    m = len(upper)
    out += [f"    Cv[{i}] = {code(reduced[m + i])}" for i in range(n)]
    out += [f"    G[{i}] = {code(reduced[m + n + i])}" for i in range(n)]
    out += [f"    E[0] = {code(reduced[m + 2 * n])}", f"    E[1] = {code(reduced[m + 2 * n + 1])}"]
    damp = [
        (i, [k for k, (name, _) in enumerate(d.params) if name == pname][0])
        for i, pname in enumerate(d.damping)
        if pname
    ]
    mass = exprs[:m]
    force = [sp.Symbol(f"tau[{i}, b]") - exprs[m + i] - exprs[m + n + i] for i in range(n)]  # tau - C v - G of member b
    if d.F is not None:  # the friction law's forces, after the viscous damping
        force = [f - plain(e) for f, e in zip(force, d.F)]
    if d.nc:
        columns = _constrained_body(d, plain, head, damp, code, mass, force, psyms, upper)
        after, info = "_this.project_kernel", "_this.constraint_info_kernel"
    else:
        columns = _columns_body(d, mass, force, psyms, upper, damp, code)
        after, info = "_compiled.no_projection", "_compiled.no_constraint_info"
    lines = [
        f'"""Generated by mbs_envs.models.symbolic for {d.name!r}: do not edit (named by the hash of this text)."""',
        "import sys",
        "import numpy as np",
        "from mbs_envs.dynamics.jit import njit",
        "from mbs_envs.dynamics import compiled as _compiled",
        "from mbs_envs.dynamics import constraints as _constraints",
        "from mbs_envs.dynamics.compiled import rk_run",
        "from mbs_envs.dynamics.trig import sincos_columns",
        "from numba import objmode",
        "from mbs_envs.envs.engine import engine_step",
        "from mbs_envs.envs import tracking as _tracking",
        "from mbs_envs.envs import derived_swingup as _swingup",
        "",
        f"N = {n}",
        f"DAMPING = {tuple(damp)!r}",
        "",
        "",
        "@njit(cache=True, inline='always')",
        "def terms(q, v, p, M, Cv, G, E):",
        '    """M (n, n), C v, G (n,), (T, V) of one member into the arrays given."""',
        *head,
        *body,
        *out,
        "",
        "",
        "@njit(cache=True)",
        "def rows(q, v, p):",
        '    """terms() of rows (B, n): M (B, n, n), Cv, G (B, n), E (B, 2)."""',
        "    B = q.shape[0]",
        "    M = np.empty((B, N, N))",
        "    Cv = np.empty((B, N))",
        "    G = np.empty((B, N))",
        "    E = np.empty((B, 2))",
        "    for b in range(B):",
        "        terms(q[b], v[b], p, M[b], Cv[b], G[b], E[b])",
        "    return M, Cv, G, E",
        "",
        "",
        *_friction_body(d, plain, psyms, code),
        *columns,
        "",
        "",
        "@njit(cache=True)",
        "def energy_kernel(q, v, theta, E):",
        '    """E = T + V of a batch in columns; theta (P, 1) or (P, B) of equal columns."""',
        "    B = q.shape[1]",
        "    M, Cv, G, TV = np.empty((N, N)), np.empty(N), np.empty(N), np.empty(2)",
        "    qk, vk = np.empty(N), np.empty(N)",
        "    p = np.empty(theta.shape[0])",
        "    for i in range(theta.shape[0]):  # the parameters are the same for every member",
        "        p[i] = theta[i, 0]",
        "    for k in range(B):",
        "        for i in range(N):",
        "            qk[i] = q[i, k]",
        "            vk[i] = v[i, k]",
        "        terms(qk, vk, p, M, Cv, G, TV)",
        "        E[k] = TV[0] + TV[1]",
        "",
        "",
        "_this = sys.modules[__name__]",
        "",
        "",
        "@njit(cache=True)",
        "def advance_kernel(theta, stepper, q, v, tau):",
        f"    rk_run(_this.acceleration_kernel, {after}, theta, stepper, q, v, tau)",
        "",
        "",
        "@njit(cache=True)",
        "def step_kernel(theta, stepper, control, task, state, out):",
        '    """The joint-tracking scene\'s compiled step on this model (mbs_envs.envs.derived)."""',
        f"    engine_step(_this.advance_kernel, _this.energy_kernel, {info}, _compiled.never_singular,",
        "                _tracking.tracking_task, theta, stepper, control, task, state, out)",
        "",
        "",
        *_swingup_body(d, plain, psyms, code, info),
    ]
    return "\n".join(lines)


def _swingup_body(d: Derivation, plain, psyms: list, code, info: str) -> list[str]:
    """The swing-up scene's kernels (:mod:`mbs_envs.envs.derived_swingup`, compiled on first use):
    ``potential_columns(q, theta, V)`` (``V(q)`` of a batch in columns, SIMD by :func:`_simd_lines`), the task
    kernel ``swingup_task`` (its height from ``V``) and ``swingup_step_kernel``."""
    return [
        "@njit(cache=True)",
        "def potential_columns(q, theta, V):",
        '    """V(q) [J] of a batch in columns (n, B), theta (P, 1)."""',
        "    B = q.shape[1]",
        *[f"    {x} = theta[{k}, 0]" for k, x in enumerate(psyms)],
        *_simd_lines(d, [plain(d.V)], ["V[b]"], code, False, "z"),
        "",
        "",
        "@njit(cache=True)",
        "def swingup_task(q, v, t, action, task, obs, info, terminated):",
        '    """The derived swing-up task kernel: the potential energy at the task\'s parameters, then its rows."""',
        "    V = np.empty(q.shape[1])",
        "    potential_columns(q, task[0], V)",
        "    _swingup.swingup_columns(q, v, t, action, V, task, obs, info, terminated)",
        "",
        "",
        "@njit(cache=True)",
        "def swingup_step_kernel(theta, stepper, control, task, state, out):",
        '    """The swing-up scene\'s compiled step on this model (mbs_envs.envs.derived_swingup)."""',
        f"    engine_step(_this.advance_kernel, _this.energy_kernel, {info}, _compiled.never_singular,",
        "                _this.swingup_task, theta, stepper, control, task, state, out)",
        "",
    ]


def _friction_body(d: Derivation, plain, psyms: list, code) -> list[str]:
    """With a friction law: ``friction_member(v, p, F)`` (one member's ``F``, straight-line after common-subexpression
    elimination) and ``friction_rows(v, p)`` over rows (the numpy path's); nothing without one."""
    import sympy as sp

    if d.F is None:
        return []
    reps, reduced = sp.cse([plain(e) for e in d.F], symbols=sp.numbered_symbols("w"), optimizations="basic")
    return [
        "@njit(cache=True, inline='always')",
        "def friction_member(v, p, F):",
        '    """The friction law\'s forces F (n,) of one member at rates v (n,)."""',
        *[f"    {s} = v[{i}]" for i, s in enumerate(d.v)],
        *[f"    {s} = p[{k}]" for k, s in enumerate(psyms)],
        *[f"    {s} = {code(e)}" for s, e in reps],
        *[f"    F[{i}] = {code(e)}" for i, e in enumerate(reduced)],
        "",
        "",
        "@njit(cache=True)",
        "def friction_rows(v, p):",
        '    """friction_member() of rows (B, n)."""',
        "    F = np.empty(v.shape)",
        "    for b in range(v.shape[0]):",
        "        friction_member(v[b], p, F[b])",
        "    return F",
        "",
        "",
    ]


def _simd_lines(d: Derivation, exprs: list, targets: list[str], code, uses_v: bool, prefix: str) -> list[str]:
    """Lines (indented for a function body) computing ``targets[k] = exprs[k]`` for every member ``b`` of a batch in
    columns, the member loop innermost so that it runs SIMD: the sines and cosines of each distinct argument in one
    :func:`~mbs_envs.dynamics.trig.sincos_columns` pass, then the straight-line terms after common-subexpression
    elimination (symbols ``<prefix>0, ...``). The caller binds the parameters and ``B``."""
    import sympy as sp

    args = sorted({f.args[0] for e in exprs for f in e.atoms(sp.sin, sp.cos)}, key=sp.default_sort_key)
    sc = [(sp.Symbol(f"{prefix}s{k}", real=True), sp.Symbol(f"{prefix}c{k}", real=True)) for k in range(len(args))]
    trig = {}
    for a_, (s_, c_) in zip(args, sc):
        trig[sp.sin(a_)], trig[sp.cos(a_)] = s_, c_
    reps, reduced = sp.cse(
        [e.xreplace(trig) for e in exprs], symbols=sp.numbered_symbols(prefix), optimizations="basic"
    )
    K = max(len(args), 1)
    state = [f"        {x} = q[{i}, b]" for i, x in enumerate(d.q)] + (
        [f"        {x} = v[{i}, b]" for i, x in enumerate(d.v)] if uses_v else []
    )
    return [
        f"    A = np.empty(({K}, B))",
        f"    S = np.empty(({K}, B))",
        f"    C = np.empty(({K}, B))",
        "    for b in range(B):",
        *state,
        *[f"        A[{k}, b] = {code(a_)}" for k, a_ in enumerate(args)],
        "        pass",
        *[f"    sincos_columns(A[{k}], S[{k}], C[{k}])" for k in range(len(args))],
        "    for b in range(B):",
        *state,
        *[f"        {s_} = S[{k}, b]\n        {c_} = C[{k}, b]" for k, (s_, c_) in enumerate(sc)],
        *[f"        {x} = {code(e)}" for x, e in reps],
        *[f"        {t} = {code(e)}" for t, e in zip(targets, reduced)],
    ]


def _constrained_body(d: Derivation, plain, head: list, damp: list, code, mass: list, force: list, psyms: list,
                      upper: list) -> list[str]:  # fmt: skip
    """The constraint code of a constrained model: ``constraint_terms`` (``phi``, ``Psi``, ``Psi_dot v`` of one
    member after common-subexpression elimination), ``constraint_rows`` (the numpy path's), and the member kernels
    (``q, v, tau`` (n, 1), ``p`` (P, 1)) that :mod:`mbs_envs.dynamics.constraints`' general column loops take; then the
    batch kernels, SIMD over the members (the terms as straight-line code over the batch, the solves of
    :func:`~mbs_envs.dynamics.constraints.schur_columns` and :func:`~mbs_envs.dynamics.constraints.project_simd`):
    ``acceleration_kernel`` (Schur complement), ``project_kernel`` (Gauss-Newton on ``phi``, then ``v`` onto
    ``Psi v = 0`` in the kinetic-energy metric) and ``constraint_info_kernel`` (``max |phi|``, multipliers). A member
    those cannot decide (see there) is recomputed by the general member path (compiled on first use, from object
    mode), so both paths give the same results."""
    import sympy as sp

    n, nc, nh = len(d.q), d.nc, d.nh
    exprs = [plain(e) for e in (list(d.phi) if nh else []) + list(d.Psi) + list(d.Psidv)]
    reps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("z"), optimizations="basic")
    out = [f"    phi[{k}] = {code(reduced[k])}" for k in range(nh)]
    out += [f"    Psi[{k}, {j}] = {code(reduced[nh + k * n + j])}" for k in range(nc) for j in range(n)]
    out += [f"    Pdv[{k}] = {code(reduced[nh + nc * n + k])}" for k in range(nc)]
    params = [f"    {x} = theta[{k}, 0]" for k, x in enumerate(psyms)]
    phis = exprs[:nh]
    rows_P = exprs[nh : nh + nc * n]
    pdv = exprs[nh + nc * n :]
    return [
        f"NC = {nc}",
        f"NH = {nh}",
        f"ROWS = np.arange({nh})",
        "",
        "",
        "@njit(cache=True, inline='always')",
        "def constraint_terms(q, v, p, phi, Psi, Pdv):",
        '    """phi (nh,), Psi (nc, n), Psi_dot v (nc,) of one member into the arrays given."""',
        *head,
        *[f"    {s} = {code(e)}" for s, e in reps],
        *out,
        "    return",
        "",
        "",
        "@njit(cache=True)",
        "def constraint_rows(q, v, p):",
        '    """constraint_terms() of rows (B, n): phi (B, nh), Psi (B, nc, n), Pdv (B, nc)."""',
        "    B = q.shape[0]",
        "    phi, Psi, Pdv = np.empty((B, NH)), np.empty((B, NC, N)), np.empty((B, NC))",
        "    for b in range(B):",
        "        constraint_terms(q[b], v[b], p, phi[b], Psi[b], Pdv[b])",
        "    return phi, Psi, Pdv",
        "",
        "",
        "@njit(inline='always')",
        "def _flat(x):",
        "    out = np.empty(x.shape[0])",
        "    for i in range(x.shape[0]):",
        "        out[i] = x[i, 0]",
        "    return out",
        "",
        "",
        "@njit(cache=True)",
        "def mass_member(q, p, M):",
        "    Cv, G, E = np.empty(N), np.empty(N), np.empty(2)",
        "    terms(_flat(q), np.zeros(N), _flat(p), M, Cv, G, E)",
        "",
        "",
        "@njit(cache=True)",
        "def residual_member(q, p, phi):",
        "    ph, Psi, Pdv = np.empty(NH), np.empty((NC, N)), np.empty(NC)",
        "    constraint_terms(_flat(q), np.zeros(N), _flat(p), ph, Psi, Pdv)",
        "    for i in range(NH):",
        "        phi[i] = ph[i]",
        "",
        "",
        "@njit(cache=True)",
        "def jacobian_member(q, p, Psi):",
        "    ph, Pdv = np.empty(NH), np.empty(NC)",
        "    constraint_terms(_flat(q), np.zeros(N), _flat(p), ph, Psi, Pdv)",
        "",
        "",
        "@njit(cache=True)",
        "def terms_member(q, v, tau, p, M, f, Psi, gamma):",
        '    """M, f = tau - (C v + G + F), Psi, gamma = -Psi_dot v of one member (constraints.constrained_acceleration_columns)."""',
        "    qk, vk, pk = _flat(q), _flat(v), _flat(p)",
        "    Cv, G, E = np.empty(N), np.empty(N), np.empty(2)",
        "    terms(qk, vk, pk, M, Cv, G, E)",
        "    ph, Pdv = np.empty(NH), np.empty(NC)",
        "    constraint_terms(qk, vk, pk, ph, Psi, Pdv)",
        "    for i in range(N):",
        "        f[i] = tau[i, 0] - Cv[i] - G[i]",
        *[f"    f[{i}] -= pk[{j}] * vk[{i}]" for i, j in damp],
        *(
            ["    F = np.empty(N)", "    friction_member(vk, pk, F)", "    for i in range(N):", "        f[i] -= F[i]"]
            if d.F is not None
            else []
        ),
        "    for i in range(NC):",
        "        gamma[i] = -Pdv[i]",
        "",
        "",
        "@njit(cache=True)",
        "def general_acceleration(q, v, tau, theta, a):",
        "    _constraints.constrained_acceleration_columns(_this.terms_member, NC, q, v, tau, theta, a)",
        "",
        "",
        "@njit(cache=True)",
        "def general_projection(q, v, theta, tol):",
        "    _constraints.project_columns(_this.residual_member, _this.jacobian_member, _this.mass_member, ROWS, NC, q, v, theta, tol)",
        "",
        "",
        "@njit(cache=True)",
        "def general_constraint_info(q, v, tau, theta, res, lam):",
        "    _constraints.constraint_info_columns(_this.terms_member, _this.residual_member, q, v, tau, theta, res, lam)",
        "",
        "",
        "@njit(cache=True)",
        "def dynamics_columns(q, v, tau, theta, M, X, P, g):",
        '    """M (n, n, B), f = tau - (C v + G + F) into X[0] (n, B), Psi (nc, n, B), gamma = -Psi_dot v (nc, B)."""',
        "    B = q.shape[1]",
        *params,
        *_simd_lines(
            d,
            mass + force + rows_P + [-e for e in pdv],
            [f"M[{i}, {j}, b]" for i, j in upper]
            + [f"X[0, {i}, b]" for i in range(n)]
            + [f"P[{k}, {j}, b]" for k in range(nc) for j in range(n)]
            + [f"g[{k}, b]" for k in range(nc)],
            code,
            True,
            "y",
        ),
        *[f"        M[{j}, {i}, b] = M[{i}, {j}, b]" for i, j in upper if i != j],
        *[f"        X[0, {i}, b] -= {psyms[j]} * v[{i}, b]" for i, j in damp],
        "",
        "",
        "@njit(cache=True)",
        "def residual_columns(q, theta, phi):",
        "    B = q.shape[1]",
        *params,
        *_simd_lines(d, phis, [f"phi[{k}, b]" for k in range(nh)], code, False, "y"),
        "",
        "",
        "@njit(cache=True)",
        "def projection_columns(q, theta, phi, P, M):",
        '    """phi (nh, B), Psi (nc, n, B) and M (n, n, B) of a batch in columns, one pass."""',
        "    B = q.shape[1]",
        *params,
        *_simd_lines(
            d,
            phis + rows_P + mass,
            [f"phi[{k}, b]" for k in range(nh)]
            + [f"P[{k}, {j}, b]" for k in range(nc) for j in range(n)]
            + [f"M[{i}, {j}, b]" for i, j in upper],
            code,
            False,
            "y",
        ),
        *[f"        M[{j}, {i}, b] = M[{i}, {j}, b]" for i, j in upper if i != j],
        "",
        "",
        "@njit(cache=True)",
        "def acceleration_kernel(q, v, tau, theta, a):",
        '    """Forward dynamics with the constraints enforced (Schur complement), a batch in columns (n, B), SIMD."""',
        "    B = q.shape[1]",
        "    M, X, P, g = np.empty((N, N, B)), np.empty((NC + 1, N, B)), np.empty((NC, N, B)), np.empty((NC, B))",
        "    dynamics_columns(q, v, tau, theta, M, X, P, g)",
        "    lam, ok = np.empty((NC, B)), np.ones(B, np.bool_)",
        "    _constraints.schur_columns(M, X, P, g, _constraints.RCOND, a, lam, ok)",
        "    for b in range(B):",
        "        if not ok[b]:  # the general member path",
        "            qb, vb, tb, pb = _constraints.column(q, b), _constraints.column(v, b), _constraints.column(tau, b), _constraints.column(theta, 0)",
        "            ab = np.empty((N, 1))",
        "            with objmode():",
        "                _this.general_acceleration(qb, vb, tb, pb, ab)",
        "            for i in range(N):",
        "                a[i, b] = ab[i, 0]",
        "",
        "",
        "@njit(cache=True)",
        "def project_kernel(q, v, theta, tol):",
        '    """Projection onto the constraints of a batch in columns, in place, SIMD (the general path for the rest)."""',
        "    B = q.shape[1]",
        "    q_in, v_in = q.copy(), v.copy()",
        "    general = np.zeros(B, np.bool_)",
        "    _constraints.project_simd(_this.projection_columns, NH, NC, q, v, theta, tol, general)",
        "    for b in range(B):",
        "        if general[b]:  # from the member's state as it came in",
        "            qb, vb, pb = _constraints.column(q_in, b), _constraints.column(v_in, b), _constraints.column(theta, 0)",
        "            with objmode():",
        "                _this.general_projection(qb, vb, pb, tol)",
        "            for i in range(N):",
        "                q[i, b], v[i, b] = qb[i, 0], vb[i, 0]",
        "",
        "",
        "@njit(cache=True)",
        "def constraint_info_kernel(q, v, tau, theta, res, lam):",
        '    """max |phi| (B,) and the multipliers (B, nc) of a batch in columns (lam without rows: max |phi| only)."""',
        "    B = q.shape[1]",
        "    phi = np.empty((NH, B))",
        "    residual_columns(q, theta, phi)",
        "    for b in range(B):",
        "        worst = 0.0",
        "        for i in range(NH):",
        "            x = abs(phi[i, b])",
        "            if x > worst or x != x:  # NaN stays",
        "                worst = x",
        "        res[b] = worst",
        "    if lam.shape[0] == 0:",
        "        return",
        "    M, X, P, g = np.empty((N, N, B)), np.empty((NC + 1, N, B)), np.empty((NC, N, B)), np.empty((NC, B))",
        "    dynamics_columns(q, v, tau, theta, M, X, P, g)",
        "    a, lc, ok = np.empty((N, B)), np.empty((NC, B)), np.ones(B, np.bool_)",
        "    _constraints.schur_columns(M, X, P, g, _constraints.RCOND, a, lc, ok)",
        "    for b in range(B):",
        "        if ok[b]:",
        "            for i in range(NC):",
        "                lam[b, i] = lc[i, b]",
        "        else:",
        "            rb, lb = np.empty(1), np.empty((1, NC))",
        "            qb, vb, tb, pb = _constraints.column(q, b), _constraints.column(v, b), _constraints.column(tau, b), _constraints.column(theta, 0)",
        "            with objmode():",
        "                _this.general_constraint_info(qb, vb, tb, pb, rb, lb)",
        "            res[b] = rb[0]",
        "            for i in range(NC):",
        "                lam[b, i] = lb[0, i]",
    ]


def _columns_body(d: Derivation, mass: list, force: list, psyms: list, upper: list, damp: list, code) -> list[str]:
    """``acceleration_kernel(q, v, tau, theta, a)``: ``a = M^-1 (tau - b v - C v - G)`` of the batch in columns
    with its one parameter column (``theta (P, 1)``: a derived model's parameters are the same for every member,
    ``DerivedModel.shared_theta``), SIMD over the members: ``M`` and the force by :func:`_simd_lines`, then
    :func:`~mbs_envs.dynamics.compiled.cholesky_columns` and its solve; NaN for a member whose ``M`` is not
    positive definite (as the numpy path's batched Cholesky)."""
    n = len(d.q)
    return [
        "@njit(cache=True)",
        "def acceleration_kernel(q, v, tau, theta, a):",
        '    """a = M^-1 (tau - b v - C v - G) of a batch in columns (n, B), theta (P, 1): SIMD over the members."""',
        "    B = q.shape[1]",
        *[f"    {x} = theta[{k}, 0]" for k, x in enumerate(psyms)],
        "    M = np.empty((N, N, B))",
        "    r = np.empty((N, B))",
        *_simd_lines(
            d, mass + force, [f"M[{i}, {j}, b]" for i, j in upper] + [f"r[{i}, b]" for i in range(n)], code, True, "y"
        ),
        *[f"        M[{j}, {i}, b] = M[{i}, {j}, b]" for i, j in upper if i != j],
        *[f"        r[{i}, b] -= {psyms[j]} * v[{i}, b]" for i, j in damp],
        "    ok = np.ones(B, np.bool_)",
        "    _compiled.cholesky_columns(M, ok)",
        "    _compiled.cholesky_solve_columns(M, r)",
        "    for i in range(N):",
        "        for b in range(B):",
        "            a[i, b] = r[i, b] if ok[b] else np.nan",
    ]


#: one generated module loads at a time in a process (reentrant: loading may derive)
_LOAD_LOCK = threading.RLock()


def load_generated(source: str, cache: pathlib.Path | None = None):
    """The generated module of ``source``, written once to ``cache`` as ``derived_<sha256>.py`` and imported
    (numba then caches its machine code beside it)."""
    folder = pathlib.Path(cache or CACHE)
    digest = hashlib.sha256(source.encode()).hexdigest()[:32]
    modname = f"mbs_envs_derived_{digest}"
    with _LOAD_LOCK:  # the module is in sys.modules while it runs (it reads itself there): no other thread meanwhile
        if modname in sys.modules:
            return sys.modules[modname]
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{modname}.py"
        if not path.exists() or path.read_text() != source:
            _write(path, source.encode())
        spec = importlib.util.spec_from_file_location(modname, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[modname] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[modname]
            raise
        return module


# ---------------------------------------------------------------------------------------------
# the model


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


def cached_derivation(name: str, q: Sequence[Any], T: Any, V: Any, params: Mapping[str, float], actuation: Any = None,
                      damping: Mapping[Any, str] | None = None, cache: pathlib.Path | None = None, *,
                      constraints: Sequence[Any] = (), velocity_constraints: Sequence[Any] = (),
                      independent: Sequence[Any] | None = None, friction: Mapping[Any, Any] | None = None) -> Derivation:  # fmt: skip
    """:func:`derive_equations`, kept on disk (a pickle in ``cache``, default :data:`CACHE`) under the SHA-256 of the
    inputs' exact SymPy form (``srepr``): a second process with the same Lagrangian does not derive again."""
    import pickle

    import sympy as sp

    B = None if actuation is None else np.asarray(actuation, float).tolist()
    damp = None if damping is None else sorted((sp.srepr(k), v) for k, v in damping.items())
    ind = None if independent is None else [x if isinstance(x, (int, np.integer)) else sp.srepr(x) for x in independent]
    fric = None if not friction else sorted((sp.srepr(k), sp.srepr(sp.sympify(e))) for k, e in dict(friction).items())
    key = repr((FORMAT, name, [sp.srepr(x) for x in q], sp.srepr(sp.sympify(T)), sp.srepr(sp.sympify(V)), sorted((k, repr(v)) for k, v in dict(params).items()),
                B, damp, [sp.srepr(sp.sympify(c)) for c in constraints], [sp.srepr(sp.sympify(c)) for c in velocity_constraints], ind, fric))  # fmt: skip
    folder = pathlib.Path(cache or CACHE)
    path = folder / f"derivation_{hashlib.sha256(key.encode()).hexdigest()[:32]}.pkl"
    source = path.with_suffix(f".{package_stamp()[:16]}.source")  # its generated code, by this version of the package
    if path.exists():
        try:
            stored = pickle.loads(path.read_bytes())
            if stored[0] == key:
                _SOURCES[id(stored[1])] = (stored[1], source)
                return stored[1]
        except Exception:  # a damaged or foreign file: derive again and overwrite it
            pass
    d = derive_equations(
        name, q, T, V, params, actuation, damping, constraints, velocity_constraints, independent, friction=friction
    )
    folder.mkdir(parents=True, exist_ok=True)
    _write(path, pickle.dumps((key, d)))
    _SOURCES[id(d)] = (d, source)
    return d


def _write(path: pathlib.Path, data: bytes) -> None:
    """``data`` to ``path`` atomically (a concurrent process reads the whole file or none)."""
    tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")  # one per writer, threads included
    tmp.write_bytes(data)
    os.replace(tmp, path)


#: derivations of :func:`cached_derivation` -> (the derivation, where its generated source is kept): a warm process
#: reads it instead of printing the equations again (SymPy's printing: 0.35 s of a derived scene's warm first step)
_SOURCES: dict[int, tuple[Derivation, pathlib.Path]] = {}


def source_of(d: Derivation) -> str:
    """:func:`generate_source` of ``d``, read from the derivation cache where :func:`cached_derivation` kept it (keyed
    by the package's sources as well: any edit of the generator generates again)."""
    kept = _SOURCES.get(id(d))
    path = kept[1] if kept is not None and kept[0] is d else None
    if path is not None:
        with contextlib.suppress(OSError):
            head, _, text = path.read_text().partition("\n")
            if head == _source_stamp(text):
                return text
            warnings.warn(f"damaged derivation cache file {path} (its checksum does not match): generated again",
                          stacklevel=2)  # fmt: skip
    source = generate_source(d)
    if path is not None:
        with contextlib.suppress(OSError):
            _write(path, f"{_source_stamp(source)}\n{source}".encode())
    return source


def _source_stamp(text: str) -> str:
    """The first line of a kept source file: the checksum of the rest (a truncated or altered file fails it)."""
    return "# sha256 " + hashlib.sha256(text.encode()).hexdigest()
