"""A state estimator for noisy observations: the extended Kalman filter on the control map.

The plant is observed as ``y_k = x_k + n_k`` (the decoded state, angles and rates), ``n_k`` white
with covariance ``R_n = sigma^2 I`` (the swing-up scenes' noise condition adds Gaussian noise of std
0.01 to each observation entry; decoded through ``atan2``, each angle gets std 0.01 too). Between
observations the state moves by the discrete map the env integrates,
``x_{k+1} = F(x_k, u_k) + w_k`` (:func:`controllers.control_map.rk4_map`: ``u`` held over the control
step), with ``w_k`` white of covariance ``Q_w`` standing for what the model does not know. One filter
step (Jazwinski 1970; Simon, *Optimal State Estimation*, 2006, §13.2):

    predict:  x- = F(x+, u),              P- = F_x P+ F_x^T + Q_w      (F_x by central differences)
    update:   L = P- (P- + R_n)^-1,       x+ = x- + L (y - x-),   P+ = (I - L) P-

with ``y - x-`` taken with wrapped angles. On a linear plant with constant covariances the gain
converges to the steady-state Kalman gain (the discrete algebraic Riccati equation's), which the
tests check.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mbs_envs.envs.tracking import wrap_angle

from .control_map import rk4_map, state_error

#: the central differences' step for ``F_x`` [rad, rad/s]
EPS = 1e-6


def map_jacobian(model: Any, x: np.ndarray, u: np.ndarray, dt: float, substeps: int, eps: float = EPS) -> tuple[np.ndarray, np.ndarray]:
    """``F(x, u)`` and ``F_x = dF/dx`` by central differences, in one batched call of the map.

    Parameters
    ----------
    model : Planar2R (per-member parameters of shape ``(B,)`` allowed)
    x : ndarray, shape (B, n)
    u : ndarray, shape (B, m)

    Returns
    -------
    F : ndarray, shape (B, n)
    F_x : ndarray, shape (B, n, n)
    """
    n = x.shape[-1]
    d = np.concatenate([np.zeros((1, n)), np.eye(n) * eps, -np.eye(n) * eps])[:, None, :]  # (2n + 1, 1, n)
    y = rk4_map(model, x[None] + d, u[None], dt, substeps)  # (2n + 1, B, n)
    return y[0], np.moveaxis((y[1 : n + 1] - y[n + 1 :]) / (2 * eps), 0, -1)


def ekf_step(model: Any, x: np.ndarray, P: np.ndarray, u: np.ndarray, y: np.ndarray, dt: float, substeps: int,
             Q_w: np.ndarray, R_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """One predict + update of the filter (module docstring), batched over members.

    Parameters
    ----------
    x, P : ndarray, shapes (B, n) and (B, n, n)
        The last estimate and its covariance.
    u : ndarray, shape (B, m)
        The input applied since [N m].
    y : ndarray, shape (B, n)
        The new observation of the state.
    Q_w : ndarray, shape (n, n) or (B, n, n)
        Process-noise covariance per step.
    R_n : ndarray, shape (n, n)
        Observation-noise covariance.

    Returns
    -------
    x, P : the new estimate (angles wrapped) and covariance.
    """
    x_pred, F_x = map_jacobian(model, x, u, dt, substeps)
    P_pred = F_x @ P @ np.swapaxes(F_x, -1, -2) + Q_w
    L = np.swapaxes(np.linalg.solve(P_pred + R_n, P_pred), -1, -2)  # P- (P- + R)^-1, both symmetric
    x_new = x_pred + np.einsum("bij,bj->bi", L, state_error(y, x_pred))
    n = x.shape[1] // 2
    x_new[:, :n] = wrap_angle(x_new[:, :n])
    P_new = P_pred - L @ P_pred
    return x_new, 0.5 * (P_new + np.swapaxes(P_new, -1, -2))
