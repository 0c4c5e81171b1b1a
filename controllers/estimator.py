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

from mbs_envs import validation as check

from mbs_envs.envs.tracking import wrap_angle

from .base import BuiltFor
from .control_map import rk4_map, state_error

#: the central differences' step for ``F_x`` [rad, rad/s]
EPS = 1e-6


def map_jacobian(
    model: Any, x: np.ndarray, u: np.ndarray, dt: float, substeps: int, eps: float = EPS
) -> tuple[np.ndarray, np.ndarray]:
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


def rates_from_angles(q: np.ndarray, q_1: np.ndarray, q_2: np.ndarray, history: np.ndarray, v_seen: np.ndarray,
                      dt: float) -> np.ndarray:  # fmt: skip
    """Joint rates from the last three angle observations: the second-order backward difference

        v_k = (3 q_k - 4 q_{k-1} + q_{k-2}) / (2 dt) = (3 (q_k - q_{k-1}) - (q_{k-1} - q_{k-2})) / (2 dt)

    (exact for angles quadratic in time: no lag at constant acceleration; error ``dt^2 q''' / 3``), with wrapped
    differences; the first-order ``(q_k - q_{k-1}) / dt`` where only two angles are known yet, and the observed
    rates where only one is.

    Parameters
    ----------
    q, q_1, q_2 : ndarray, shape (B, n)
        The angles observed now, one and two control steps before [rad].
    history : ndarray, shape (B,)
        How many observations each member has had before this one in its episode (0, 1, >= 2).
    v_seen : ndarray, shape (B, n)
        The rates observed now [rad/s] (kept where ``history == 0``).
    dt : float
        The control step [s].

    Returns
    -------
    ndarray, shape (B, n)
        The rates [rad/s].
    """
    d1, d2 = wrap_angle(q - q_1), wrap_angle(q_1 - q_2)
    second = (3.0 * d1 - d2) / (2.0 * dt)
    h = np.asarray(history)[:, None]
    return np.where(h >= 2, second, np.where(h == 1, d1 / dt, v_seen))


class RatesFromAngles:
    """A policy (controller or agent, SB3's ``predict``) fed its swing-up observations with the joint rates replaced
    by :func:`rates_from_angles` of the observed angles: what an arm's encoders give where its rate sensors are noisy
    (the DFKI benchmark's velocity-noise axis perturbs the observed rates only). Where the angles are noisy too the
    difference amplifies their noise by ``sqrt(26) / (2 dt)``, about ``2.5 / dt`` (the swing-up scenes' observation
    noise: keep the observed rates or the controllers' own filter there).

    Memory (SB3's ``state``): ``(q_1, q_2, history, inner)``: the last two observed angles (B, n), the observations
    each member has had in its episode (B,), and the wrapped policy's own state; reset where ``episode_start``.

    Parameters
    ----------
    policy : object with ``predict(obs, state, episode_start, deterministic)``
    env : a swing-up env (``mbs_envs/Acrobot-v*``, ``Pendubot-v*`` and their protocol ids), for its control step.
    """

    def __init__(self, policy: Any, env: Any):
        from mbs_envs.envs.swingup import SwingUpEnv

        base = getattr(env, "unwrapped", env)
        if not isinstance(base, SwingUpEnv):
            raise ValueError(f"env: RatesFromAngles reads a swing-up env's observations, got {type(base).__name__}")
        self.policy, self.dt = policy, float(base.dt)
        self.built_for = BuiltFor(base)
        self.observation_space, self.action_space = env.observation_space, env.action_space

    def predict(
        self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[np.ndarray, Any]:
        from mbs_envs.envs.swingup import decode_swingup

        self.built_for.check(type(self).__name__)
        obs = np.asarray(observation)
        if obs.ndim not in (1, 2):
            raise ValueError(f"observation must have shape (k,) or (n, k), got shape {obs.shape}")
        single = obs.ndim == 1
        batch = np.array(obs.reshape(-1, obs.shape[-1]), dtype=obs.dtype if obs.dtype.kind == "f" else np.float32)
        seen = decode_swingup(batch)  # ValueError for a wrong shape; the angles by atan2
        q, B = seen.q, len(batch)
        start = (
            np.ones(B, bool)
            if episode_start is None
            else check.shaped(episode_start, "episode_start", (B,), bools=True, broadcast=True) != 0
        )
        if state is None:
            q_1, q_2, history, inner = q, q, np.zeros(B), None
        else:
            if not (isinstance(state, tuple) and len(state) == 4):
                raise ValueError(f"state must be the 4-tuple this wrapper returned, got {type(state).__name__}")
            q_1, q_2, history, inner = state
            q_1, q_2 = check.shaped(q_1, "state's q_1", q.shape), check.shaped(q_2, "state's q_2", q.shape)
            history = np.where(start, 0.0, check.shaped(history, "state's history", (B,)))
        batch[:, -q.shape[1] :] = rates_from_angles(q, q_1, q_2, history, seen.v, self.dt)
        action, inner = self.policy.predict(
            batch[0] if single else batch, state=inner, episode_start=episode_start, deterministic=deterministic
        )
        return action, (q, q_1, history + 1.0, inner)
