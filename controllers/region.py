"""The upright balance under the torque limit: what physics allows, and what an LQR catches.

Two figures for a 2R arm with one motor about upright, both on the linearization
``dx/dt = A x + B u`` (``x = (dq, dv)``), ``|u| <= u_max``:

- :func:`saturation_bound` -- **what physics allows.** For an unstable eigenvalue
  ``lambda > 0`` with left eigenvector ``w`` (``w^T A = lambda w^T``) the mode
  ``z = w^T x`` obeys ``dz/dt = lambda z + (w^T B) u``; once ``|z| >= |w^T B| u_max / lambda``
  no admissible input brings it back. A state is catchable only inside every such slab;
  along one coordinate ``j`` (the others zero) that is ``|x_j| < |w^T B| u_max / (lambda |w_j|)``,
  minimized over the unstable modes. It is a necessary condition of the linearization
  (the nonlinear arm near upright is close to it): an offset beyond it is lost whatever the
  controller does.
- :func:`noise_floor` -- **what observation noise allows**: the smallest stationary spread about upright any
  controller achieves with the observations noisy (the LQG optimum as the input weight vanishes).
- :func:`hold_shares` (and :func:`lqg_hold_share`, the best of a grid of LQG controllers) -- **what observation noise
  leaves of a hold**: the share of windows in which given gains with a given filter keep both angles within a
  tolerance on the noisy linearization, by simulation (an estimate, not a bound).
- :func:`estimate_region` -- **what a given feedback catches**, by simulation: states are
  drawn uniformly in a box about upright, then below the level found so far, and each is run in closed loop ``u = clip(-K x)`` on
  the discrete map the env integrates (:func:`controllers.control_map.fast_map`: compiled for the 2R arm), on every plant
  of a set (the nominal and mismatched ones, optionally with the input applied one step late);
  the estimate is the largest level ``c*`` of the LQR's cost-to-go ``x^T S x`` below which no
  sample failed. It is a sampled estimate, not a certificate: the tests check that fresh states
  inside it are caught and that states well outside the saturation bound are not.
  (The box, not the shells of ``S``, is sampled: ``S`` of the acrobot's LQR has eigenvalues from
  0.08 to 1.2e7, so its sublevel sets reach far out along the rates, to states no swing-up produces.)
  - :func:`axis_catch` -- the same, along one coordinate: the largest offset caught.
"""

from __future__ import annotations

import contextlib
import dataclasses
import warnings
from typing import Any, Iterator

import numpy as np
import scipy.linalg

from .control_map import fast_map, state_error


def saturation_bound(A: np.ndarray, B: np.ndarray, u_max: float, delay: float = 0.0) -> np.ndarray:
    """The largest catchable offset along each state coordinate (module docstring).

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, 1)
    u_max : float
        [N m].
    delay : float
        Input delay [s]: the mode grows unopposed by ``e^(lambda delay)`` before the input acts,
        so each slab shrinks by that factor.

    Returns
    -------
    ndarray, shape (n,)
        Per coordinate (others zero): ``min over unstable modes of |w^T B| u_max / (lambda |w_j|)``;
        ``inf`` where no unstable mode constrains it.
    """
    lam, W = np.linalg.eig(A.T)
    bound = np.full(A.shape[0], np.inf)
    for i in np.flatnonzero(lam.real > 1e-9):
        w = W[:, i].real if abs(lam[i].imag) < 1e-12 else None
        if w is None:  # a complex unstable pair: its modulus obeys no such slab (not the case of these arms)
            continue
        reach = abs(w @ B[:, 0]) * u_max / lam[i].real * np.exp(-lam[i].real * delay)
        with np.errstate(divide="ignore"):
            bound = np.minimum(bound, np.where(np.abs(w) > 1e-12, reach / np.abs(w), np.inf))
    return bound


@dataclasses.dataclass(frozen=True)
class PlantCase:
    """One plant of the set a region is checked on: its model and the input delay [control steps]."""

    model: Any
    delay: int = 0


@dataclasses.dataclass(frozen=True)
class ArmMap:
    """The arm's own discrete map about a goal, for :func:`hold_shares` instead of its linearization: ``model`` stepped
    by :func:`controllers.control_map.fast_map` (``dt`` [s], ``substeps``) from ``x_goal + x``; a run with an angle
    more than ``drop`` [rad] off the goal is over (where :class:`controllers.PlannedSwingUp` plans again)."""

    model: Any
    x_goal: np.ndarray
    dt: float
    substeps: int
    drop: float = np.inf

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """``x' - x_goal`` (angles wrapped) from ``x - x_goal`` under the input ``u`` (shape ``x.shape[:-1] + (1,)``)."""
        return state_error(fast_map(self.model, self.x_goal + x, u, self.dt, self.substeps), self.x_goal)


def closed_loop_final(cases: list[PlantCase], x0: np.ndarray, x_goal: np.ndarray, K: np.ndarray, u_max: float,
                      dt: float, substeps: int, steps: int, box: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """The error ``x_N - x_goal`` after ``steps`` of ``u = clip(-K (x - x_goal))`` from each start, on each plant.

    Parameters
    ----------
    x0 : ndarray, shape (S, n)
    box : ndarray, shape (n,), optional
        Half-widths of a box about ``x_goal`` (angles wrapped): a run that leaves it at any step is
        marked as diverged (a controller that hands back at the box's edge never sees it return,
        and a run that goes once around and comes back upright is no catch).

    Returns
    -------
    ndarray, shape (len(cases), S, n)
        Non-finite rows where a run diverged.
    """
    out = []
    for case in cases:
        x = np.array(x0, float)
        queue = [np.zeros((len(x), 1))] * case.delay
        with np.errstate(all="ignore"):
            for _ in range(steps):
                u = np.clip(-(state_error(x, x_goal) @ K.T), -u_max, u_max)
                queue.append(u)
                x = fast_map(case.model, x, queue.pop(0), dt, substeps)
                x = np.where(np.abs(x) < 1e6, x, np.nan)
                if box is not None:
                    x = np.where(np.all(np.abs(state_error(x, x_goal)) <= box, axis=-1, keepdims=True), x, np.nan)
        out.append(state_error(x, x_goal))
    return np.array(out)


def estimate_region(cases: list[PlantCase], x_goal: np.ndarray, K: np.ndarray, S: np.ndarray, u_max: float, dt: float,
                    substeps: int, half_widths: np.ndarray, samples: int = 1000, rounds: int = 12, horizon: float = 5.0,
                    tol: float = 0.1, seed: int = 0) -> tuple[float, dict]:  # fmt: skip
    """The catch level ``c*`` of ``u = clip(-K x)`` on every plant of ``cases`` (module docstring).

    Sampling as LQR-trees shrink a funnel: a first round draws ``samples`` states uniformly in the
    box ``|x - x_goal| <= half_widths``; each later round draws them uniformly in the part of the box
    below the current level (``x^T S x < c``, by rejection). Each state runs in closed loop on every
    plant; one that is not within ``tol`` (max norm) of ``x_goal`` after ``horizon`` seconds on some
    plant is a failure, and the level drops to the cost-to-go ``x^T S x`` of the cheapest failure.
    The rounds stop when one finds no failure below the level (or after ``rounds``). The box should
    reach beyond the saturation bound (:func:`saturation_bound`), so that failures bound the level
    and not the box.

    Returns
    -------
    level : float
    details : dict
        ``rounds`` run, ``samples`` in all, ``converged`` (the last round found no failure below the
        level), ``bounded_by_box`` (no failure at all: the level is the box's costliest sample).
    """
    rng = np.random.default_rng(seed)
    half_widths = np.asarray(half_widths, float)
    level, total, converged, failed_any = np.inf, 0, False, False
    for r in range(rounds):
        dx = np.empty((0, len(x_goal)))
        for _ in range(200):  # rejection: uniform in the box below the level
            draw = rng.uniform(-1.0, 1.0, (4 * samples, len(x_goal))) * half_widths
            dx = np.concatenate([dx, draw[np.einsum("bi,ij,bj->b", draw, S, draw) < level]])[:samples]
            if len(dx) == samples:
                break
        total += len(dx)
        err = closed_loop_final(cases, x_goal + dx, x_goal, K, u_max, dt, substeps, int(round(horizon / dt)), half_widths)
        ok = np.all(np.all(np.abs(err) <= tol, axis=-1), axis=0)  # NaN compares False: a diverged run is not caught
        cost = np.einsum("bi,ij,bj->b", dx, S, dx)
        if r == 0 and ok.all():
            return float(cost.max()), {"rounds": 1, "samples": total, "converged": True, "bounded_by_box": True}
        if ok.all():
            converged = True
            break
        failed_any = True
        level = float(cost[~ok].min())
    return level, {"rounds": r + 1, "samples": total, "converged": converged, "bounded_by_box": not failed_any}


def axis_catch(case: PlantCase, x_goal: np.ndarray, K: np.ndarray, u_max: float, dt: float, substeps: int, axis: int,
               high: float, points: int = 64, horizon: float = 5.0, tol: float = 0.1) -> float:  # fmt: skip
    """The largest offset along one state coordinate (others zero, both signs) from which ``u = clip(-K x)``
    brings ``case``'s plant within ``tol`` of ``x_goal`` in ``horizon`` seconds, on a grid of ``points``
    offsets in ``(0, high]`` (every smaller grid offset caught too); 0 if the first is not caught."""
    d = np.linspace(high / points, high, points)
    x0 = np.repeat(x_goal[None], 2 * points, axis=0)
    x0[:points, axis] += d
    x0[points:, axis] -= d
    err = closed_loop_final([case], x0, x_goal, K, u_max, dt, substeps, int(round(horizon / dt)))[0]
    ok = np.all(np.abs(err) <= tol, axis=-1)
    ok = ok[:points] & ok[points:]
    return float(d[np.argmin(ok)] - high / points) if not ok.all() else float(high)


def discretize(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A_d, B_d)`` of ``dx/dt = A x + B u`` with ``u`` held over ``dt`` [s] (the matrix exponential of the
    augmented system)."""
    n, m = B.shape
    M = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * dt)
    return M[:n, :n], M[:n, n:]


def lqg_stationary(A_d: np.ndarray, B_d: np.ndarray, K: np.ndarray, L: np.ndarray, P_post: np.ndarray, S_innov: np.ndarray) -> np.ndarray:
    """Stationary covariance of the true state under ``u_k = -K x^_k|k`` with the filter gain ``L``:
    ``Cov(x^) + P+``, ``Cov(x^)`` solving ``X = (A_d - B_d K) X (A_d - B_d K)^T + L S L^T`` (``S`` the innovations')."""
    F = A_d - B_d @ K
    return scipy.linalg.solve_discrete_lyapunov(F, L @ S_innov @ L.T) + P_post


def noise_floor(A: np.ndarray, B: np.ndarray, dt: float, sigma: float, rho: float = 1e-12, eps: float = 1e-12) -> np.ndarray:
    """**What observation noise allows**: the smallest stationary standard deviation of each state coordinate about
    upright that any causal controller achieves on the linearization, every state entry observed at each control
    step with white Gaussian noise of std ``sigma``, no process noise, the input unbounded.

    For coordinate ``j`` it is the LQG optimum of ``E[x_j^2] + rho E[u^2]`` as ``rho -> 0``: for a linear plant with
    Gaussian noise the LQG controller (Kalman filter on the current observation, LQR on its estimate) minimizes
    that cost over all causal controllers, linear or not, so no controller holds ``x_j`` tighter; saturation and
    the arm's nonlinearity can only add to it. ``eps`` regularizes the Riccati equations (a process noise and a
    weight on the other coordinates of that size). The value at ``rho`` approaches the floor from above; on the
    swing-up scenes it moves by about 1 % from ``rho = 1e-9`` to ``1e-12`` (scipy warns of the ill-conditioned
    Riccati solve there, silenced: the results are checked against simulation in the tests).

    Parameters
    ----------
    A, B : ndarray, shapes (n, n), (n, 1)
        The continuous linearization about upright.
    dt : float
        Control step [s] (input held).
    sigma : float
        Observation noise std per entry [rad, rad/s].

    Returns
    -------
    ndarray, shape (n,)
        The floor per coordinate [rad, rad/s].
    """
    with quiet_riccati():  # ill-conditioned at small rho (docstring above)
        A_d, B_d = discretize(A, B, dt)
        n = A.shape[0]
        L, P_post, S_innov = steady_kalman(A_d, sigma, eps)
        floor = np.empty(n)
        for j in range(n):
            Q = eps * np.eye(n)
            Q[j, j] = 1.0
            K = dlqr(A_d, B_d, Q, rho)
            floor[j] = np.sqrt(lqg_stationary(A_d, B_d, K, L, P_post, S_innov)[j, j])
    return floor


@contextlib.contextmanager
def quiet_riccati() -> Iterator[None]:
    """Silence scipy's warning of an ill-conditioned Riccati solve (the LQG optima at small input weights; their
    results are checked against simulation in the tests)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        yield


def steady_kalman(A_d: np.ndarray, sigma: float, eps: float = 1e-12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The steady-state Kalman filter of ``x_{k+1} = A_d x_k + B_d u_k`` observed as ``y_k = x_k + n_k`` (every entry,
    white noise of std ``sigma``; a process noise of covariance ``eps I`` regularizes the Riccati equation):
    ``(L, P+, S)``, the gain ``x^+ = x^- + L (y - x^-)``, the posterior covariance and the innovations'."""
    n = A_d.shape[0]
    R_n = sigma**2 * np.eye(n)
    P_prior = scipy.linalg.solve_discrete_are(A_d.T, np.eye(n), eps * np.eye(n), R_n)
    S_innov = P_prior + R_n
    L = P_prior @ np.linalg.inv(S_innov)
    return L, P_prior - L @ P_prior, S_innov


def dlqr(A_d: np.ndarray, B_d: np.ndarray, Q: np.ndarray, rho: float) -> np.ndarray:
    """The discrete LQR gain ``K`` (``u = -K x``) of ``sum x^T Q x + rho u^2``, shape (1, n)."""
    P = scipy.linalg.solve_discrete_are(A_d, B_d, Q, np.array([[rho]]))
    return np.linalg.solve(rho + B_d.T @ P @ B_d, B_d.T @ P @ A_d)


#: the LQG controllers :func:`lqg_hold_share` tries, ``(rho, w_1, w_v)``: the input weight [(N m)^-2], the first
#: angle's weight against the second's 1 (for the acrobot, weighting the passive shoulder 1e2-1e4 times the elbow
#: holds the most windows), and the rates' weight; 80 controllers, the first 12 (``w_1 = 1``, ``w_v <= 0.1``) the
#: grid of earlier runs
LQG_GRID = tuple((rho, w_1, w_v) for w_1 in (1.0, 0.01, 100.0, 1e4) for w_v in (1e-12, 1e-3, 1e-1, 1.0, 10.0)
                 for rho in (1e-9, 1e-6, 1e-4, 1e-2))  # fmt: skip


def lqg_hold_share(A: np.ndarray, B: np.ndarray, dt: float, sigma: float, tol: float, hold_steps: int, windows: int = 2000,
                   settle_steps: int = 300, seed: int = 0, grid: tuple = LQG_GRID) -> float:  # fmt: skip
    """**What observation noise leaves of a hold**: the largest share, over the LQG controllers of ``grid``
    (:data:`LQG_GRID`), of windows of ``hold_steps`` control steps in which both angles stay within ``tol`` of
    upright, on the linearization observed as in :func:`noise_floor` (every state entry with white Gaussian noise of
    std ``sigma``, no process noise, the input unbounded).

    Each controller (the Kalman filter of :func:`noise_floor` and the discrete LQR of ``x^T diag(w_1, 1, w_v, w_v) x
    + rho u^2``) runs ``windows`` independent episodes from upright with an exact estimate, ``settle_steps`` steps to
    reach its stationary spread, then the window; every controller sees the same noise (drawn from ``seed``), all
    of them in one batch. An estimate of what a controller that knows the plant achieves, not a bound (minimum
    variance is not maximum probability of staying inside a box, and the best of many controllers on the same
    windows is optimistic); the share at the tolerance of the swing-up scenes' success rule sets a model-free
    controller's strict success against it.

    Returns
    -------
    float
        The share in ``[0, 1]``.
    """
    with quiet_riccati():  # ill-conditioned at small rho (noise_floor)
        A_d, B_d = discretize(A, B, dt)
        n = A.shape[0]
        L = steady_kalman(A_d, sigma)[0]
        K = np.stack([dlqr(A_d, B_d, np.diag([w_1, 1.0] + [w_v] * (n - 2)), rho)[0] for rho, w_1, w_v in grid])
    return float(hold_shares(A_d, B_d, L, K, sigma, tol, hold_steps, windows, settle_steps, seed).max())


def edge_switched(x: np.ndarray, K: np.ndarray, K_e: np.ndarray, edge: Any, lead: Any, joint: int) -> np.ndarray:
    """The hold's input law with its edge gain: ``u = -K_e x`` where the angle ``joint`` is heading out, ``|x_j + lead
    v_j| > edge`` (the angle ``lead`` seconds ahead at its present rate beyond ``edge``), else ``u = -K x``.

    An LQR weighs the state's spread, not the chance of leaving a box: near the box's edge a second gain that
    stops the angle (at the other angle's expense, which has room) keeps more windows inside
    (:func:`hold_shares`, docs/physics.md §7).

    Parameters
    ----------
    x : ndarray, shape (..., 2 m)
        The state about upright ``(angles [rad], rates [rad/s])``.
    K, K_e : ndarray, shapes broadcasting with ``x``, (..., 2 m)
        The gains inside and at the edge [N m per unit of the state].
    edge : float or ndarray
        [rad]; ``inf``: never the edge gain.
    lead : float or ndarray
        [s].
    joint : int
        The angle watched (``0 <= joint < m``).

    Returns
    -------
    ndarray, shape (...)
        The input [N m], unsaturated.
    """
    m = x.shape[-1] // 2
    out = np.abs(x[..., joint] + lead * x[..., m + joint]) > edge
    return np.where(out, -np.sum(x * K_e, axis=-1), -np.sum(x * K, axis=-1))


def recovering(x: np.ndarray, before: np.ndarray, band: Any, back: Any) -> np.ndarray:
    """The hold's band rule with hysteresis: whether each member recovers (with its recovery gain) at state ``x``,
    having recovered (``before``) or held at the previous step: a holding member starts to recover where an angle is
    more than ``band`` off upright, a recovering one holds again where both are within ``back``.

    Parameters
    ----------
    x : ndarray, shape (..., 2 m)
        The (estimated) state about upright [rad, rad/s].
    before : ndarray of bool, shape (...)
    band, back : float or ndarray broadcasting with ``before``
        [rad], ``back <= band``.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    off = np.abs(x[..., : x.shape[-1] // 2]).max(axis=-1)
    return np.where(before, off > back, off > band)


def hold_input(x: np.ndarray, recover: np.ndarray, K: np.ndarray, K_e: np.ndarray, K_r: np.ndarray, edge: Any, lead: Any,
               joint: int, coef: np.ndarray | None = None, zd: ZeroDynamicsHold | None = None) -> np.ndarray:  # fmt: skip
    """The hold's input law, unsaturated: where ``coef`` (:func:`zero_dynamics`' coefficients, shape broadcasting
    with ``(..., 7)``) is finite, :func:`zero_dynamics_input` with ``zd``'s settings (its rescue reach where a member
    recovers, ``recover``: :func:`rescuing`); elsewhere ``u = -K_r x`` where a member recovers (:func:`recovering`),
    else :func:`edge_switched` between ``K`` and ``K_e``; shapes as there, ``recover`` of shape ``(...)``."""
    out = np.where(recover, -np.sum(x * K_r, axis=-1), edge_switched(x, K, K_e, edge, lead, joint))
    if coef is not None:
        finite = np.isfinite(coef).all(axis=-1)
        reach = np.where(recover, zd.rescue_reach, zd.reach)
        with np.errstate(all="ignore"):  # (NaN rows: not used)
            out = np.where(finite, zero_dynamics_input(x, coef, zd.rate, reach, zd.omega, joint), out)
    return out


def hold_shares(A_d: np.ndarray, B_d: np.ndarray, L: np.ndarray, K: np.ndarray, sigma: float, tol: float, hold_steps: int,
                windows: int = 2000, settle_steps: int = 300, seed: int = 0, u_max: float = np.inf, K_e: np.ndarray | None = None,
                edge: Any = np.inf, lead: Any = 0.0, joint: int = 1, K_r: np.ndarray | None = None, band: Any = np.inf,
                back: Any = np.inf, arm: ArmMap | None = None, coef: np.ndarray | None = None, zd: ZeroDynamicsHold | None = None) -> np.ndarray:  # fmt: skip
    """The share of windows of ``hold_steps`` control steps in which both angles stay within ``tol`` of upright, for
    each gain of ``K`` with the filter gain ``L``, on the discrete linearization ``x' = A_d x + B_d u`` observed as in
    :func:`noise_floor` (every state entry with white Gaussian noise of std ``sigma``).

    Each controller (``x^+ = x^- + L (y - x^-)``, ``u = clip(-K x^+, -u_max, u_max)``, or with ``K_e`` the edge rule
    :func:`edge_switched` on ``x^+``; with ``K_r``, where an estimated angle leaves ``band`` it recovers with
    ``u = clip(-K_r x^+, ...)`` until both are within ``back`` again: :func:`recovering`) runs ``windows`` independent
    episodes from upright with an exact estimate (with ``arm``, on the arm's own map instead, the filter predicting
    with it as an extended Kalman filter of the exact model does, its gain still ``L``; a run past ``arm.drop`` holds
    nothing more),
    ``settle_steps`` steps to reach its stationary spread, then the window; every controller sees the same noise
    (drawn from ``seed``), all of them in one batch.

    Parameters
    ----------
    A_d, B_d : ndarray, shapes (n, n), (n, 1)
    L : ndarray, shape (n, n)
    K : ndarray, shape (G, n)
        ``G`` gains [N m per unit of the state].
    K_e : ndarray, shape (G, n), optional
        The edge gains of :func:`edge_switched` (default: none, ``u = -K x^+``).
    edge, lead : float or ndarray of shape (G,)
        :func:`edge_switched`'s threshold [rad] and lead [s], per controller.
    joint : int
        The angle it watches.
    K_r : ndarray, shape (G, n), optional
        The recovery gains (default: none, no band).
    band, back : float or ndarray of shape (G,)
        [rad], ``back <= band``.
    arm : ArmMap, optional
        The nonlinear plant (default: the linearization ``A_d, B_d``).
    coef : ndarray, shape (G, 7), optional
        Per controller, :func:`zero_dynamics`' coefficients: where finite, the hold is :func:`zero_dynamics_input`
        with ``zd``'s settings and its rescue rule (:func:`rescuing`) instead of the gains and the band
        (:func:`hold_input`).
    zd : ZeroDynamicsHold, optional
        Needed with ``coef``.

    Returns
    -------
    ndarray, shape (G,)
        The shares, in ``[0, 1]``.
    """
    n = A_d.shape[0]
    G = len(K)
    K = np.asarray(K, float)[:, None, :]  # (G, 1, n)
    K_e = K if K_e is None else np.asarray(K_e, float)[:, None, :]
    K_r = K if K_r is None else np.asarray(K_r, float)[:, None, :]
    coef = None if coef is None else np.asarray(coef, float)[:, None, :]
    edge, lead, band, back = (np.broadcast_to(np.asarray(a, float), (G,))[:, None] for a in (edge, lead, band, back))
    rng = np.random.default_rng(seed)
    x, xh = np.zeros((G, windows, n)), np.zeros((G, windows, n))
    held, recover, over = np.ones((G, windows), bool), np.zeros((G, windows), bool), np.zeros((G, windows), bool)
    flat = lambda a: a.reshape(G * windows, n)  # noqa: E731  (2-D products: one BLAS call each)
    for k in range(settle_steps + hold_steps):
        xh = xh + (flat(x + rng.normal(0.0, sigma, (windows, n)) - xh) @ L.T).reshape(G, windows, n)  # the filter's update
        banded = recovering(xh, recover, band, back)
        recover = banded if coef is None else np.where(np.isfinite(coef).all(axis=-1), rescuing(xh, coef, recover, zd, back), banded)
        u = np.clip(hold_input(xh, recover, K, K_e, K_r, edge, lead, joint, coef, zd), -u_max, u_max)[..., None]
        # the plant's step and the filter's prediction
        if arm is None:
            x, xh = (flat(x) @ A_d.T).reshape(G, windows, n) + u * B_d.T, (flat(xh) @ A_d.T).reshape(G, windows, n) + u * B_d.T
        else:
            with np.errstate(all="ignore"):
                x, xh = arm.step(x, u), arm.step(xh, u)
            over |= ~(np.abs(x[..., : n // 2]) <= arm.drop).all(axis=-1)
            x, xh = (np.where(over[..., None], 0.0, a) for a in (x, xh))  # (over: no longer stepped)
        if k >= settle_steps:
            held &= np.all(np.abs(x[..., : n // 2]) <= tol, axis=-1) & ~over
    return held.mean(axis=1)


def zero_dynamics(A: np.ndarray, B: np.ndarray, joint: int) -> np.ndarray:
    """The unactuated combination of a two-link arm's linearization about upright and its zero dynamics.

    With ``q'' = M q + beta u`` (the rate rows of ``A``, ``B``), ``c = (beta_1, -beta_0)`` is blind to the input:
    ``p = c . q`` obeys ``p'' = c M q``, which in ``p`` and the driven angle ``q_j`` reads ``p'' = a p - g q_j``. Where
    ``a > 0`` (the arm with its driven joint locked falls: the acrobot's zero dynamics), ``z = p' + lam p``, ``lam =
    sqrt(a)``, is its unstable mode, ``z' = lam z - g q_j``: the driven angle is the input that keeps it, and so the
    arm, upright (docs/physics.md §7).

    Parameters
    ----------
    A, B : ndarray, shapes (..., 4, 4), (..., 4, 1)
        Continuous linearizations about upright, state ``(q, v)`` [rad, rad/s].
    joint : int
        The driven joint (0 or 1).

    Returns
    -------
    ndarray, shape (..., 7)
        ``(c_0, c_1, lam, g, M_j0, M_j1, beta_j)``: ``c`` [rad/s^2 per N m, as ``beta``], ``lam`` [1/s], ``g``
        [1/s^2 times the units of ``c``], the driven joint's row of ``M`` [1/s^2] and its input gain [rad/s^2 per
        N m]; ``lam`` NaN where ``a <= 0`` (no unstable zero dynamics) or the driven joint does not respond to the
        input.
    """
    M, beta = A[..., 2:, :2], B[..., 2:, 0]
    c = np.stack([beta[..., 1], -beta[..., 0]], axis=-1)
    r = np.einsum("...i,...ij->...j", c, M)
    i = 1 - joint
    with np.errstate(divide="ignore", invalid="ignore"):
        a = r[..., i] / c[..., i]
        g = a * c[..., joint] - r[..., joint]
        lam = np.where(a > 0, np.sqrt(np.abs(a)), np.nan)
    lam = np.where(np.abs(beta[..., joint]) > 0, lam, np.nan)
    return np.concatenate([c, lam[..., None], g[..., None], M[..., joint, :], beta[..., joint, None]], axis=-1)


@dataclasses.dataclass(frozen=True)
class ZeroDynamicsHold:
    """The settings of the hold on the zero dynamics (:func:`zero_dynamics_input`, :func:`rescuing`).

    rate : float
        The unstable mode's closed-loop decay rate [1/s] where the driven angle's request is linear.
    reach : float
        The most the driven angle is asked off upright while holding [rad].
    omega : float
        The driven angle's loop [rad/s] (critically damped).
    rescue_reach : float
        The reach while rescuing [rad]: beyond the box, where the mode has escaped what the box allows.
    trigger, release : float
        A holding member rescues where ``|z|`` exceeds ``trigger`` times the mode's capture within ``reach``,
        ``g reach / lam``, and holds again where it is below ``release`` times it with both angles within the way
        back.

    Each field is a float, or an array broadcasting with the members (``(G, 1)`` in :func:`hold_shares`: ``G``
    settings scored in one batch).
    """

    rate: float = 35.0
    reach: float = 0.0975
    omega: float = 45.0
    rescue_reach: float = 0.2
    trigger: float = 1.35
    release: float = 0.7


def zero_dynamics_mode(x: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """The unstable mode ``z = c . v + lam c . q`` of :func:`zero_dynamics` at the states ``x`` (shape (..., 4)) [units
    of ``c`` times rad/s], shape (...)."""
    return np.sum(coef[..., :2] * x[..., 2:], axis=-1) + coef[..., 2] * np.sum(coef[..., :2] * x[..., :2], axis=-1)


def rescuing(x: np.ndarray, coef: np.ndarray, before: np.ndarray, zd: ZeroDynamicsHold, back: Any) -> np.ndarray:
    """The zero-dynamics hold's rescue rule with hysteresis: whether each member rescues (the law with
    ``zd.rescue_reach``) at state ``x``, having rescued (``before``) or held at the previous step. Within ``reach``
    the driven angle pulls the mode back only while ``|z| < g reach / lam`` (``z' = lam z - g q_j``): past
    ``zd.trigger`` times that a holding member rescues (the box is lost for a while, the arm is not), and holds again
    where ``|z|`` is below ``zd.release`` times it and both angles are within ``back`` [rad]. Shapes as
    :func:`recovering`, ``coef`` broadcasting with ``(..., 7)``."""
    z = np.abs(zero_dynamics_mode(x, coef))
    with np.errstate(invalid="ignore", divide="ignore"):  # (rows without coefficients: not used)
        capture = np.abs(coef[..., 3]) * zd.reach / coef[..., 2]
    inside = np.abs(x[..., : x.shape[-1] // 2]).max(axis=-1) <= back
    return np.where(before, ~((z < zd.release * capture) & inside), z > zd.trigger * capture)


def zero_dynamics_input(x: np.ndarray, coef: np.ndarray, rate: Any, reach: Any, omega: Any, joint: int) -> np.ndarray:
    """The hold's input law on the zero dynamics (:func:`zero_dynamics`), unsaturated.

    The driven angle is asked to be ``q_j* = reach tanh(k z / reach)``, ``k = (lam + rate) / g`` (the unstable mode
    ``z`` decays at ``rate`` where the request is linear, and the request never leaves ``reach``: near the box's edge
    the driven angle stops and the mode is pushed back as hard as the box allows), with ``q_j*' = k z' sech^2(k z /
    reach)``, ``z' = lam z - g q_j``; the driven angle follows it as a critically damped second-order loop of natural
    frequency ``omega``, its acceleration asked of the linearization: ``u = (a_j - M_j . q) / beta_j``, ``a_j = -omega^2
    (q_j - q_j*) - 2 omega (v_j - q_j*')``.

    Parameters
    ----------
    x : ndarray, shape (..., 4)
        The state about upright ``(q, v)`` [rad, rad/s].
    coef : ndarray, shape broadcasting with ``(..., 7)``
        :func:`zero_dynamics`' coefficients.
    rate : float or ndarray
        The unstable mode's closed-loop decay rate [1/s] (> 0).
    reach : float or ndarray
        The most the driven angle is asked off upright [rad].
    omega : float or ndarray
        The driven angle's loop [rad/s].
    joint : int
        The driven joint.

    Returns
    -------
    ndarray, shape (...)
        The input [N m], unsaturated.
    """
    lam, g, M_j, beta_j = coef[..., 2], coef[..., 3], coef[..., 4:6], coef[..., 6]
    q, v = x[..., :2], x[..., 2:]
    z = zero_dynamics_mode(x, coef)
    k = (lam + rate) / g
    s = k * z / reach
    target = reach * np.tanh(s)
    target_rate = k * (lam * z - g * q[..., joint]) / np.cosh(np.clip(s, -50.0, 50.0)) ** 2
    a_j = -(omega**2) * (q[..., joint] - target) - 2.0 * omega * (v[..., joint] - target_rate)
    return (a_j - np.sum(M_j * q, axis=-1)) / beta_j
