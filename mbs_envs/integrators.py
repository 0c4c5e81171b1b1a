"""Time integrators for ``dq/dt = v, dv/dt = a(t, q, v)``, chosen by name.

Fixed-step explicit methods are *data*: partitioned Runge-Kutta tableaux run by
one generic stepper (:class:`ExplicitRK`). The stages of a tableau are

    V_i = v + h sum_{j<i}  A_v[i, j] K_j
    Q_i = q + h sum_{j<=i} A_q[i, j] V_j          (V_i is known: explicit)
    K_i = a(t + c_i h, Q_i, V_i)

and the step is ``q+ = q + h sum b_q[i] V_i``, ``v+ = v + h sum b_v[i] K_i``.
A plain RK method has ``A_q = A_v`` and ``b_q = b_v``; semi-implicit
(symplectic) Euler differs only in its ``q`` coefficients. A stage whose
acceleration nobody reads is not evaluated.

Adaptive and stiff methods come from :func:`scipy.integrate.solve_ivp`
(:class:`ScipyIVP`), taking ``rtol`` and ``atol``.

All steppers are batched: ``q`` and ``v`` may carry leading batch dimensions.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

#: ``a(t, q, v) -> accelerations``, batched like ``q`` and ``v``.
Acceleration = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


@dataclasses.dataclass(frozen=True)
class Tableau:
    """A partitioned explicit Runge-Kutta method (see the module docstring).

    Attributes
    ----------
    c : tuple, shape (s,)
        Stage times as fractions of the step.
    A_v : tuple of tuples, shape (s, s)
        Velocity-stage coefficients, strictly lower triangular.
    b_v : tuple, shape (s,)
        Velocity update weights.
    A_q : tuple of tuples, shape (s, s)
        Position-stage coefficients, lower triangular (diagonal allowed).
    b_q : tuple, shape (s,)
        Position update weights.
    order : int
        Global order of accuracy.
    """

    c: tuple
    A_v: tuple
    b_v: tuple
    A_q: tuple
    b_q: tuple
    order: int

    def __post_init__(self) -> None:
        s = len(self.c)
        A_v, A_q = np.array(self.A_v, float), np.array(self.A_q, float)
        if A_v.shape != (s, s) or A_q.shape != (s, s):
            raise ValueError("tableau matrices must be (s, s)")
        if np.any(np.triu(A_v) != 0) or np.any(np.triu(A_q, 1) != 0):
            raise ValueError("tableau is not explicit")

    @classmethod
    def plain(cls, c, A, b, order) -> "Tableau":
        """A non-partitioned method: the same coefficients for ``q`` and ``v``."""
        return cls(c=c, A_v=A, b_v=b, A_q=A, b_q=b, order=order)

    @property
    def needs_acceleration(self) -> tuple[bool, ...]:
        """Whether stage ``i``'s acceleration is used at all."""
        A_v, b_v = np.array(self.A_v, float), np.array(self.b_v, float)
        return tuple(bool(b_v[i] != 0 or np.any(A_v[:, i] != 0)) for i in range(len(self.c)))


TABLEAUX: dict[str, Tableau] = {
    # explicit (forward) Euler, order 1
    "euler": Tableau.plain(c=(0.0,), A=((0.0,),), b=(1.0,), order=1),
    # semi-implicit (symplectic) Euler: v+ = v + h a(q, v), then q+ = q + h v+.
    # Stage 2 only forms V_2 = v+ (its acceleration is never evaluated).
    "semi_implicit_euler": Tableau(
        c=(0.0, 1.0),
        A_v=((0.0, 0.0), (1.0, 0.0)),
        b_v=(1.0, 0.0),
        A_q=((0.0, 0.0), (0.0, 0.0)),
        b_q=(0.0, 1.0),
        order=1,
    ),
    # explicit midpoint, order 2
    "midpoint": Tableau.plain(
        c=(0.0, 0.5), A=((0.0, 0.0), (0.5, 0.0)), b=(0.0, 1.0), order=2
    ),
    # classical Runge-Kutta, order 4
    "rk4": Tableau.plain(
        c=(0.0, 0.5, 0.5, 1.0),
        A=(
            (0.0, 0.0, 0.0, 0.0),
            (0.5, 0.0, 0.0, 0.0),
            (0.0, 0.5, 0.0, 0.0),
            (0.0, 0.0, 1.0, 0.0),
        ),
        b=(1 / 6, 1 / 3, 1 / 3, 1 / 6),
        order=4,
    ),
}

#: Our names for :func:`scipy.integrate.solve_ivp` methods.
SCIPY_METHODS: dict[str, str] = {
    "rk45": "RK45",
    "dop853": "DOP853",
    "radau": "Radau",
    "bdf": "BDF",
    "lsoda": "LSODA",
}


@dataclasses.dataclass(frozen=True)
class ExplicitRK:
    """Fixed-step stepper running a :class:`Tableau`."""

    name: str
    tableau: Tableau
    adaptive = False

    @property
    def order(self) -> int:
        return self.tableau.order

    def step(
        self, acc: Acceleration, t: float, q: np.ndarray, v: np.ndarray, h: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Advance ``(q, v)`` from ``t`` to ``t + h``.

        Parameters
        ----------
        acc : callable ``a(t, q, v)``
        t : float
        q : ndarray, shape (..., nq)
        v : ndarray, shape (..., nv)
        h : float
            Step size [s].

        Returns
        -------
        q, v : ndarray
            The state at ``t + h`` (new arrays).
        """
        tab = self.tableau
        needed = tab.needs_acceleration
        V: list[np.ndarray] = []
        K: list[np.ndarray | None] = []
        for i, ci in enumerate(tab.c):
            Vi = v
            for j in range(i):
                if tab.A_v[i][j]:
                    Vi = Vi + (h * tab.A_v[i][j]) * K[j]
            V.append(Vi)
            Qi = q
            for j in range(i + 1):
                if tab.A_q[i][j]:
                    Qi = Qi + (h * tab.A_q[i][j]) * V[j]
            K.append(acc(t + ci * h, Qi, Vi) if needed[i] else None)
        q_new, v_new = q, v
        for i in range(len(tab.c)):
            if tab.b_q[i]:
                q_new = q_new + (h * tab.b_q[i]) * V[i]
            if tab.b_v[i]:
                v_new = v_new + (h * tab.b_v[i]) * K[i]
        return q_new, v_new


@dataclasses.dataclass(frozen=True)
class ScipyIVP:
    """Adaptive or stiff integration through :func:`scipy.integrate.solve_ivp`.

    The batch is flattened into one first-order system ``y = (q, v)``. For
    stiff methods scipy estimates the Jacobian by finite differences.
    """

    name: str
    method: str
    rtol: float = 1e-8
    atol: float = 1e-10
    adaptive = True
    order = None

    def __post_init__(self) -> None:
        for key in ("rtol", "atol"):
            value = getattr(self, key)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{key} must be a positive finite number, got {value!r}")

    def solve(
        self,
        acc: Acceleration,
        t0: float,
        q: np.ndarray,
        v: np.ndarray,
        t_eval: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """Integrate from ``t0`` and return the states at the times ``t_eval``.

        Returns
        -------
        t : ndarray, shape (K,)
            The times reached (fewer than ``t_eval`` if the solver failed).
        q : ndarray, shape (K, ..., nq)
        v : ndarray, shape (K, ..., nv)
        success : bool
        """
        q = np.asarray(q, float)
        v = np.asarray(v, float)
        nq = q.size

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            qq = y[:nq].reshape(q.shape)
            vv = y[nq:].reshape(v.shape)
            return np.concatenate([vv.ravel(), np.asarray(acc(t, qq, vv)).ravel()])

        y0 = np.concatenate([q.ravel(), v.ravel()])
        t_eval = np.asarray(t_eval, float)
        with np.errstate(all="ignore"):
            sol = solve_ivp(
                rhs,
                (t0, float(t_eval[-1])),
                y0,
                method=self.method,
                t_eval=t_eval,
                rtol=self.rtol,
                atol=self.atol,
            )
        K = sol.y.shape[1]
        qs = sol.y[:nq].T.reshape((K,) + q.shape)
        vs = sol.y[nq:].T.reshape((K,) + v.shape)
        return sol.t, qs, vs, bool(sol.success)

    def step(
        self, acc: Acceleration, t: float, q: np.ndarray, v: np.ndarray, h: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Advance from ``t`` to ``t + h`` (one adaptive solve); NaN state on failure."""
        ts, qs, vs, ok = self.solve(acc, t, q, v, np.array([t + h]))
        if not ok or len(ts) == 0:
            nan = np.full(np.shape(q), np.nan), np.full(np.shape(v), np.nan)
            return nan
        return qs[-1], vs[-1]


Stepper = ExplicitRK | ScipyIVP


def available() -> tuple[str, ...]:
    """Names accepted by :func:`get`, ``simulate`` and the environments."""
    return tuple(TABLEAUX) + tuple(SCIPY_METHODS)


def get(name: str, **options: Any) -> Stepper:
    """The integrator called ``name``.

    Parameters
    ----------
    name : str
        One of :func:`available`.
    **options
        ``rtol``, ``atol`` for the adaptive (scipy) methods; none otherwise.

    Raises
    ------
    ValueError
        For an unknown name or an option the method does not take.
    """
    if not isinstance(name, str):
        raise ValueError(f"integrator must be a name (str), got {name!r}")
    key = name.lower()
    if key in TABLEAUX:
        if options:
            raise ValueError(
                f"integrator {name!r} is fixed-step and takes no options, got {sorted(options)}"
            )
        return ExplicitRK(key, TABLEAUX[key])
    if key in SCIPY_METHODS:
        unknown = sorted(set(options) - {"rtol", "atol"})
        if unknown:
            raise ValueError(f"integrator {name!r} takes rtol and atol only, got {unknown}")
        return ScipyIVP(key, SCIPY_METHODS[key], **{k: float(v) for k, v in options.items()})
    raise ValueError(f"unknown integrator {name!r}; available: {list(available())}")
