"""What observation noise allows about upright: the smallest stationary spread any controller achieves
(:func:`noise_floor`, the LQG optimum as the input weight vanishes), and the share of windows the best of a grid of
LQG controllers holds (:func:`lqg_hold_share`); the discrete-time pieces they share (:func:`discretize`,
:func:`steady_kalman`, :func:`dlqr`).
"""

from __future__ import annotations

import contextlib
import warnings
from typing import Iterator

import numpy as np
import scipy.linalg

from .hold_evaluation import hold_shares


def discretize(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A_d, B_d)`` of ``dx/dt = A x + B u`` with ``u`` held over ``dt`` [s] (the matrix exponential of the
    augmented system)."""
    n, m = B.shape
    M = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * dt)
    return M[:n, :n], M[:n, n:]


def lqg_stationary(
    A_d: np.ndarray, B_d: np.ndarray, K: np.ndarray, L: np.ndarray, P_post: np.ndarray, S_innov: np.ndarray
) -> np.ndarray:
    """Stationary covariance of the true state under ``u_k = -K x^_k|k`` with the filter gain ``L``:
    ``Cov(x^) + P+``, ``Cov(x^)`` solving ``X = (A_d - B_d K) X (A_d - B_d K)^T + L S L^T`` (``S`` the innovations')."""
    F = A_d - B_d @ K
    return scipy.linalg.solve_discrete_lyapunov(F, L @ S_innov @ L.T) + P_post


def noise_floor(
    A: np.ndarray, B: np.ndarray, dt: float, sigma: float, rho: float = 1e-12, eps: float = 1e-12
) -> np.ndarray:
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
