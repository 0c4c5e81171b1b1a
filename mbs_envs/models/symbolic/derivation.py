"""The equations of motion from a Lagrangian, in plain symbols (:class:`Derivation`): SymPy's
:class:`~sympy.physics.mechanics.LagrangesMethod`, the friction and constraint rows, and the checks that refuse
what cannot be simulated (the package docstring, :mod:`mbs_envs.models.symbolic`)."""

from __future__ import annotations

import dataclasses
import keyword
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


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
    from ..base import _CHECKS

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
