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

Fixed-step implicit methods for stiff cases (large friction, high-gain
loops, light links) are singly diagonally implicit, stiffly accurate and
L-stable (:data:`DIRK_TABLEAUX`, run by :class:`ImplicitRK`): implicit Euler
(order 1), Alexander's SDIRK2 (order 2) and SDIRK3 (order 3). Each stage is
solved by a simplified Newton iteration on the stage velocity with a
finite-difference Jacobian of ``a(t, q, v)``; where Newton fails the step is
halved (member by member), so a stiff start does not end an episode.
They cost O(n^3) per step (a dense Jacobian and solve); for long chains,
:class:`JointImplicitEuler` takes only the joint damping and a joint PD's
stiffness implicitly, which keeps the solve O(N) (MuJoCo's implicit damping).

Adaptive and stiff methods are scipy's solvers (:class:`ScipyIVP`), taking
``rtol`` and ``atol``.

Bounded work: every stepper returns within a fixed amount of work, whatever
the dynamics do. Explicit methods evaluate a fixed number of stages; the
implicit ones at most ``max_evaluations`` accelerations per step (then the
failing members get NaN); the scipy ones at most ``max_evaluations`` per
output interval, and stop at the first non-finite or runaway evaluation
(:data:`RUNAWAY`). A NaN state is how a step reports a blow-up: callers flag
it as divergence (:func:`mbs_envs.dynamics.simulate.diverged`), never raise.

All steppers are batched: ``q`` and ``v`` may carry leading batch dimensions.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from .. import validation as check
from .linalg import per_member

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
    "midpoint": Tableau.plain(c=(0.0, 0.5), A=((0.0, 0.0), (0.5, 0.0)), b=(0.0, 1.0), order=2),
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

#: Our names for scipy's ODE solvers (as :func:`scipy.integrate.solve_ivp` names them).
SCIPY_METHODS: dict[str, str] = {
    "rk45": "RK45",
    "dop853": "DOP853",
    "radau": "Radau",
    "bdf": "BDF",
    "lsoda": "LSODA",
}


def _scipy_solver(method: str) -> type:
    """scipy's solver class named ``method`` (``"RK45"``, ...; scipy.integrate imported on first use: 0.25-0.5 s of
    every process's import of the package otherwise)."""
    import scipy.integrate

    return getattr(scipy.integrate, method)


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


#: A state or acceleration entry beyond this magnitude (or non-finite) inside a
#: step is a runaway: the step stops and returns NaN (the caller flags divergence).
RUNAWAY = 1e150


@dataclasses.dataclass(frozen=True)
class ScipyIVP:
    """Adaptive or stiff integration with scipy's solvers (``RK45``, ``DOP853``, ``Radau``, ``BDF``, ``LSODA``).

    The batch is flattened into one first-order system ``y = (q, v)``. For
    stiff methods scipy estimates the Jacobian by finite differences.

    The solver is driven step by step (as :func:`scipy.integrate.solve_ivp`
    does) behind a guard on the right-hand side: a non-finite or runaway
    (``|y|`` or ``|dy/dt|`` beyond :data:`RUNAWAY`) evaluation, or more than
    ``max_evaluations`` evaluations per output interval, ends the solve there
    (scipy's step-size control loops forever on NaN, and Radau/BDF raise on
    it); what was reached is returned and ``success`` is False. So one
    control step costs at most ``max_evaluations`` evaluations, whatever the
    dynamics do.
    """

    name: str
    method: str
    rtol: float = 1e-8
    atol: float = 1e-10
    max_evaluations: int = 20_000
    #: running totals, for reports: ``steps`` (accepted), ``evaluations`` (right-hand sides), ``jacobians``; not compared
    counters: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)
    adaptive = True
    order = None

    def __post_init__(self) -> None:
        for key in ("rtol", "atol"):
            object.__setattr__(self, key, check.positive(getattr(self, key), key, 1.0))
        object.__setattr__(self, "max_evaluations", check.integer(self.max_evaluations, "max_evaluations", 10, 10**9))

    def solve(
        self,
        acc: Acceleration,
        t0: float,
        q: np.ndarray,
        v: np.ndarray,
        t_eval: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """Integrate from ``t0`` and return the states at the times ``t_eval`` (increasing, > ``t0``).

        Returns
        -------
        t : ndarray, shape (K,)
            The times reached (fewer than ``t_eval`` if the solve stopped early).
        q : ndarray, shape (K, ..., nq)
        v : ndarray, shape (K, ..., nv)
        success : bool
        """
        q = np.asarray(q, float)
        v = np.asarray(v, float)
        nq = q.size
        t_eval = np.asarray(t_eval, float)
        budget = self.max_evaluations * len(t_eval)
        guard = {"count": 0, "tripped": False}

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            guard["count"] += 1
            if guard["tripped"] or guard["count"] > budget or not np.all(np.abs(y) <= RUNAWAY):
                guard["tripped"] = True
                return np.zeros_like(y)  # finite, so the solver's step ends; the result is discarded
            qq = y[:nq].reshape(q.shape)
            vv = y[nq:].reshape(v.shape)
            dy = np.concatenate([vv.ravel(), np.asarray(acc(t, qq, vv), float).ravel()])
            if not np.all(np.abs(dy) <= RUNAWAY):
                guard["tripped"] = True
                return np.zeros_like(y)
            return dy

        y0 = np.concatenate([q.ravel(), v.ravel()])
        ts: list[float] = []
        ys: list[np.ndarray] = []
        with np.errstate(all="ignore"):
            solver = _scipy_solver(self.method)(rhs, t0, y0, float(t_eval[-1]), rtol=self.rtol, atol=self.atol)
            steps = 0
            while len(ts) < len(t_eval) and not guard["tripped"]:
                solver.step()
                steps += solver.status != "failed"
                if guard["tripped"] or solver.status == "failed":
                    break
                if t_eval[len(ts)] <= solver.t:
                    dense = solver.dense_output()
                    while len(ts) < len(t_eval) and t_eval[len(ts)] <= solver.t:
                        y = solver.y if t_eval[len(ts)] == solver.t else dense(t_eval[len(ts)])
                        if not np.all(np.abs(y) <= RUNAWAY):
                            guard["tripped"] = True
                            break
                        ts.append(float(t_eval[len(ts)]))
                        ys.append(y)
                if solver.status == "finished":
                    break
        for key, value in (
            ("steps", steps),
            ("evaluations", guard["count"]),
            ("jacobians", getattr(solver, "njev", 0)),
        ):
            self.counters[key] = self.counters.get(key, 0) + value
        K = len(ts)
        Y = np.array(ys).reshape(K, y0.size)
        qs = Y[:, :nq].reshape((K,) + q.shape)
        vs = Y[:, nq:].reshape((K,) + v.shape)
        return np.array(ts), qs, vs, K == len(t_eval)

    def step(
        self, acc: Acceleration, t: float, q: np.ndarray, v: np.ndarray, h: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Advance from ``t`` to ``t + h`` (one adaptive solve); NaN state on failure."""
        ts, qs, vs, ok = self.solve(acc, t, q, v, np.array([t + h]))
        if not ok or len(ts) == 0:
            nan = np.full(np.shape(q), np.nan), np.full(np.shape(v), np.nan)
            return nan
        return qs[-1], vs[-1]


@dataclasses.dataclass(frozen=True)
class DirkTableau:
    """A singly diagonally implicit, stiffly accurate Runge-Kutta method.

    Attributes
    ----------
    c : tuple, shape (s,)
    A : tuple of tuples, shape (s, s)
        Lower triangular, every diagonal entry ``gamma``; the last row is the
        weights ``b`` (stiffly accurate: the step's result is the last stage).
    order : int
    """

    c: tuple
    A: tuple
    order: int

    def __post_init__(self) -> None:
        A = np.array(self.A, float)
        s = len(self.c)
        if A.shape != (s, s) or np.any(np.triu(A, 1) != 0):
            raise ValueError("a DIRK tableau is lower triangular (s, s)")
        if not np.allclose(np.diag(A), A[0, 0]) or A[0, 0] <= 0:
            raise ValueError("a singly diagonally implicit tableau has one positive diagonal value")
        if not np.allclose(A.sum(axis=1), self.c, rtol=0, atol=1e-14):
            raise ValueError("row sums of A must equal c")

    @property
    def gamma(self) -> float:
        return float(self.A[0][0])


_G2 = 1.0 - np.sqrt(0.5)  # Alexander (1977), 2 stages, order 2, L-stable
_G3 = 0.43586652150845899942  # root of x^3 - 3x^2 + 3x/2 - 1/6 in (1/6, 1/2)
DIRK_TABLEAUX: dict[str, DirkTableau] = {
    # implicit (backward) Euler, order 1, L-stable
    "implicit_euler": DirkTableau(c=(1.0,), A=((1.0,),), order=1),
    "sdirk2": DirkTableau(c=(_G2, 1.0), A=((_G2, 0.0), (1.0 - _G2, _G2)), order=2),
    # Alexander (1977), 3 stages, order 3, L-stable
    "sdirk3": DirkTableau(
        c=(_G3, (1.0 + _G3) / 2, 1.0),
        A=(
            (_G3, 0.0, 0.0),
            ((1.0 - _G3) / 2, _G3, 0.0),
            (-(6 * _G3**2 - 16 * _G3 + 1) / 4, (6 * _G3**2 - 20 * _G3 + 5) / 4, _G3),
        ),
        order=3,
    ),
}


def acceleration_jacobian(
    acc: Acceleration, t: float, q: np.ndarray, v: np.ndarray, a0: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Forward-difference Jacobians ``(da/dq, da/dv)`` of ``a(t, q, v)``.

    All ``2 n`` perturbed states go through ``acc`` as one batch (stacked on
    a new leading axis), so the cost is one batched call.

    Parameters
    ----------
    acc : callable ``a(t, q, v)``, batched over leading dimensions
    t : float
    q, v : ndarray, shape (..., n)
    a0 : ndarray, shape (..., n), optional
        ``acc(t, q, v)`` if already known.

    Returns
    -------
    A_q, A_v : ndarray, shape (..., n, n)
        ``A_q[..., i, j] = d a_i / d q_j``.
    """
    n = q.shape[-1]
    if a0 is None:
        a0 = acc(t, q, v)
    eps_q = np.sqrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(q))  # (..., n)
    eps_v = np.sqrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(v))
    eye = np.eye(n)
    # perturbation k on axis 0: (n, ..., n)
    dq = np.moveaxis(eps_q[..., None, :] * eye, -2, 0)
    dv = np.moveaxis(eps_v[..., None, :] * eye, -2, 0)
    zeros = np.zeros_like(dq)
    Q = np.concatenate([q + dq, q + zeros])
    V = np.concatenate([v + zeros, v + dv])
    a = np.asarray(acc(t, Q, V))
    da = a - a0  # (2n, ..., n): [k, ..., i] = a_i(perturb k) - a_i
    A_q = np.moveaxis(da[:n], 0, -1) / eps_q[..., None, :]
    A_v = np.moveaxis(da[n:], 0, -1) / eps_v[..., None, :]
    return A_q, A_v


@dataclasses.dataclass(frozen=True)
class ImplicitRK:
    """Fixed-step stepper running a :class:`DirkTableau` (see the module docstring).

    Stage ``i`` with ``Qh = q + h sum_{j<i} a_ij V_j``, ``Vh = v + h sum_{j<i} a_ij K_j``
    solves, with ``g = h gamma``,

        R(V) = V - Vh - g a(t + c_i h, Qh + g V, V) = 0

    by simplified Newton with ``J = I - g (g da/dq + da/dv)`` (the Jacobian
    at the step's start, one inversion per step; re-evaluated at the iterate
    when a stage converges slowly), then ``K_i = (V - Vh) / g``.

    Attributes
    ----------
    name : str
    tableau : DirkTableau
    newton_tol : float
        Converged when ``|dV| <= newton_tol (1 + |V|)`` (max norm) per member.
    max_iter : int
        Simplified Newton iterations per Jacobian.
    max_refresh : int
        Jacobian re-evaluations (at the current iterate) per stage before
        the step is halved.
    max_halvings : int
        Depth of step halving before the member's state is set to NaN
        (reported as divergence by the caller).
    max_evaluations : int
        Calls of ``a`` per step (a Jacobian is one batched call): once spent,
        no further halving, members that have not converged get NaN. Bounds
        the cost of a diverging step (a normal one takes about 10).
    """

    name: str
    tableau: DirkTableau
    newton_tol: float = 1e-10
    max_iter: int = 8
    max_refresh: int = 3
    max_halvings: int = 6
    max_evaluations: int = 300
    #: running totals, for reports: ``halvings`` (steps split because Newton failed); not compared
    counters: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)
    adaptive = False

    @property
    def order(self) -> int:
        return self.tableau.order

    def step(
        self, acc: Acceleration, t: float, q: np.ndarray, v: np.ndarray, h: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Advance ``(q, v)`` from ``t`` to ``t + h``; batched, NaN for members that fail.

        Returns
        -------
        q, v : ndarray
        """
        calls = [0]

        def counted(t, q, v):
            calls[0] += 1
            return acc(t, q, v)

        return self._step(counted, t, np.asarray(q, float), np.asarray(v, float), h, self.max_halvings, calls)

    def _step(self, acc, t, q, v, h, halvings, calls):
        q1, v1, ok = self._try_step(acc, t, q, v, h)
        if np.all(ok):
            return q1, v1
        if halvings == 0 or calls[0] >= self.max_evaluations:
            bad = ~ok[..., None]
            return np.where(bad, np.nan, q1), np.where(bad, np.nan, v1)
        self.counters["halvings"] = self.counters.get("halvings", 0) + 1
        qm, vm = self._step(acc, t, q, v, h / 2, halvings - 1, calls)
        q2, v2 = self._step(acc, t + h / 2, qm, vm, h / 2, halvings - 1, calls)
        keep = ok[..., None]
        return np.where(keep, q1, q2), np.where(keep, v1, v2)

    def _try_step(self, acc, t, q, v, h):
        tab = self.tableau
        g = h * tab.gamma
        J_inv = self._newton_matrix(acc, t, q, v, g)
        ok = np.ones(q.shape[:-1], bool)
        V: list[np.ndarray] = []
        K: list[np.ndarray] = []
        for i, ci in enumerate(tab.c):
            Qh, Vh = q, v
            for j in range(i):
                Qh = Qh + (h * tab.A[i][j]) * V[j]
                Vh = Vh + (h * tab.A[i][j]) * K[j]
            ti = t + ci * h
            Vi, conv = self._newton(acc, ti, Qh, Vh, g, J_inv, v if i == 0 else V[-1], ~ok)
            for _ in range(self.max_refresh):  # slow convergence: Jacobian at the iterate
                if np.all(conv | ~ok):
                    break
                J_new = self._newton_matrix(acc, ti, Qh + g * Vi, Vi, g)
                Vi, conv = self._newton(acc, ti, Qh, Vh, g, J_new, Vi, conv | ~ok)
            ok = ok & conv
            V.append(Vi)
            K.append((Vi - Vh) / g)
        # stiffly accurate: the last stage is the result
        Qs = q + h * sum(tab.A[-1][j] * V[j] for j in range(len(V)))
        return Qs, V[-1], ok

    @staticmethod
    def _newton_matrix(acc, t, q, v, g):
        """``(I - g (g da/dq + da/dv))^-1`` at ``(t, q, v)``; identity where not finite."""
        A_q, A_v = acceleration_jacobian(acc, t, q, v)
        n = q.shape[-1]
        J = np.eye(n) - g * (g * A_q + A_v)
        finite = np.all(np.isfinite(J), axis=(-2, -1))
        J = np.where(finite[..., None, None], J, np.eye(n))
        try:
            return np.linalg.inv(J)
        except np.linalg.LinAlgError:  # singular members: zero, so their Newton fails and halves
            return per_member(np.linalg.inv, J, 0.0)

    def _newton(self, acc, t, Qh, Vh, g, J_inv, V0, frozen):
        """Solve ``V - Vh - g a(t, Qh + g V, V) = 0`` for the members not ``frozen``.

        Returns the iterate and which members converged (frozen ones keep ``V0``
        and count as converged).
        """
        V = V0
        done = np.array(frozen, bool)
        for _ in range(self.max_iter):
            R = V - Vh - g * np.asarray(acc(t, Qh + g * V, V))
            dV = -np.einsum("...ij,...j->...i", J_inv, R)
            finite = np.all(np.isfinite(dV), axis=-1)
            dV = np.where((done | ~finite)[..., None], 0.0, dV)
            V = V + dV
            small = np.max(np.abs(dV), axis=-1) <= self.newton_tol * (1.0 + np.max(np.abs(V), axis=-1))
            done = done | (small & finite)
            if np.all(done | ~finite):
                break
        return V, done


@dataclasses.dataclass(frozen=True)
class JointImplicitEuler:
    """Semi-implicit Euler with the joint-space linear forces taken implicitly: O(N) on chains.

    MuJoCo's Euler integrator with implicit joint damping, extended by the
    stiffness of a joint PD input (:class:`mbs_envs.dynamics.inputs.JointPD`).
    With the friction linearized at the step's start, ``F(v+) ~ F(v) + D (v+ - v)``
    (``D = diag(dF/dv)``, :meth:`~mbs_envs.models.base.Model.friction_slope`), and
    the PD input ``u = u_ff + K_p (q_ref - q+) - K_d v+`` at the *new* state, the
    step ``v+ = v + h a``, ``q+ = q + h v+`` solves

        (M + h (D + K_d) + h^2 K_p) a = B u_ff + K_p (q_ref - q - h v) - K_d v - F(v) - C(q, v) v - G(q)

    with ``K_p, K_d`` mapped to the joints through the actuation matrix. The
    added matrix is diagonal, so :meth:`~mbs_envs.models.base.Model.shifted_forward_dynamics`
    solves it: one articulated-body pass, O(N), for
    :class:`~mbs_envs.models.serial_chain.SerialChain` (one force evaluation per
    step against RK4's four), Cholesky for the others. Any other input
    (array, callable) enters explicitly, at ``(t, q, v)``.

    First order. The linear damped oscillator ``m a = -d v - k q`` is stable
    for every ``h > 0`` (the step's amplification matrix has spectral radius
    below 1 for ``d >= 0, k > 0``), where RK4 needs ``h rho < 2.785``.
    Unconstrained models with joint coordinates (``nq = nv``) only.
    """

    name: str = "joint_implicit_euler"
    adaptive = False
    order = 1

    def step(self, acc: Acceleration, t: float, q: np.ndarray, v: np.ndarray, h: float):
        raise ValueError(
            f"integrator {self.name!r} steps a model, not an acceleration function: use it through "
            "simulate(), advance() or an environment (it needs the model's mass matrix structure)"
        )

    @staticmethod
    def check_model(model: Any) -> None:
        """``ValueError`` unless ``model`` is unconstrained with joint coordinates."""
        if getattr(model, "nc", 0) or model.nq != model.nv:
            raise ValueError(
                f"integrator 'joint_implicit_euler' takes unconstrained models with nq = nv; "
                f"{type(model).__name__} has nc = {getattr(model, 'nc', 0)}, nq = {model.nq}, nv = {model.nv}"
            )

    def step_model(
        self, model: Any, u: Callable, law: Any, t: float, q: np.ndarray, v: np.ndarray, h: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Advance ``(q, v)`` of ``model`` from ``t`` to ``t + h``.

        Parameters
        ----------
        model : Model
        u : callable ``u(t, q, v)``
            The input (:func:`mbs_envs.dynamics.simulate.input_function`), evaluated at ``(t, q, v)``.
        law : :class:`~mbs_envs.dynamics.inputs.JointPD` or None
            The PD law behind ``u``, if it is one: its stiffness and damping then enter implicitly.
        q, v : ndarray, shape (..., n)
        h : float
            [s]

        Returns
        -------
        q, v : ndarray
        """
        self.check_model(model)
        d = h * model.friction_slope(v)
        tau = model.generalized_input(u(t, q, v)) - model.friction(v)
        if law is not None:
            # the PD input at the new state: u(q+, v+) ~ u(q, v) - K_p (h v + h^2 a) - K_d h a (joint space)
            kp, kd = law.diagonals(model.actuation)
            tau = tau - kp * (h * v)
            d = d + h * kd + h * h * kp
        a = model.shifted_forward_dynamics(q, v, tau, d)
        v_new = v + h * a
        return q + h * v_new, v_new


Stepper = ExplicitRK | ImplicitRK | ScipyIVP | JointImplicitEuler


def applies(stepper: Stepper | str, model: Any) -> bool:
    """Whether ``stepper`` (or the integrator of that name) can step ``model``:
    every one can, except :class:`JointImplicitEuler` on constrained models or ``nq != nv``."""
    stepper = get(stepper) if isinstance(stepper, str) else stepper
    if isinstance(stepper, JointImplicitEuler):
        try:
            stepper.check_model(model)
        except ValueError:
            return False
    return True


def available() -> tuple[str, ...]:
    """Names accepted by :func:`get`, ``simulate`` and the environments."""
    return tuple(TABLEAUX) + tuple(DIRK_TABLEAUX) + (JointImplicitEuler.name,) + tuple(SCIPY_METHODS)


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
    if isinstance(name, Stepper) and not options:
        return name  # a ready stepper (e.g. one whose counters a report reads)
    if not isinstance(name, str):
        raise ValueError(f"integrator must be a name (str) or a stepper, got {name!r}")
    key = name.lower()
    if key in TABLEAUX:
        if options:
            raise ValueError(f"integrator {name!r} is fixed-step and takes no options, got {sorted(options)}")
        return ExplicitRK(key, TABLEAUX[key])
    if key in DIRK_TABLEAUX:
        if options:
            raise ValueError(f"integrator {name!r} is fixed-step and takes no options, got {sorted(options)}")
        return ImplicitRK(key, DIRK_TABLEAUX[key])
    if key == JointImplicitEuler.name:
        if options:
            raise ValueError(f"integrator {name!r} is fixed-step and takes no options, got {sorted(options)}")
        return JointImplicitEuler()
    if key in SCIPY_METHODS:
        unknown = sorted(set(options) - {"rtol", "atol"})
        if unknown:
            raise ValueError(f"integrator {name!r} takes rtol and atol only, got {unknown}")
        return ScipyIVP(key, SCIPY_METHODS[key], **{k: check.positive(v, k, 1.0) for k, v in options.items()})
    raise ValueError(f"unknown integrator {name!r}; available: {list(available())}")
