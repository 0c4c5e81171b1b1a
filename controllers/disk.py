"""Balance controllers for RollingDisk-v0: LQR (python-control) and a PD steering law.

Both act on the error of the reduced state ``x = (heading, lean, dheading,
dlean, dspin)`` (see :meth:`mbs_envs.models.RollingDisk.reduced_dynamics`)
from steady upright straight rolling at the commanded spin ``W_ref``:

    z = (heading - heading_ref, lean, dheading - dheading_ref, dlean, dspin - W_ref).
"""

from __future__ import annotations

from typing import Any

import control
import numpy as np

from .base import Controller


def linearize(f: Any, x0: np.ndarray, u0: np.ndarray, eps: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians ``A = df/dx``, ``B = df/du`` at ``(x0, u0)`` by central finite differences.

    Central differences have truncation error ``O(eps^2)`` and round-off
    ``O(1e-16 / eps)``: about 1e-10 relative at ``eps = 1e-6`` for these smooth maps.

    Parameters
    ----------
    f : callable ``f(x, u) -> dx/dt``, batched over leading dimensions
    x0 : ndarray, shape (n,)
    u0 : ndarray, shape (m,)

    Returns
    -------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    """
    n, m = len(x0), len(u0)
    dX = np.concatenate([np.eye(n), -np.eye(n)]) * eps
    dU = np.concatenate([np.eye(m), -np.eye(m)]) * eps
    fx = f(x0 + dX, np.broadcast_to(u0, (2 * n, m)))  # one batched call for all columns
    fu = f(np.broadcast_to(x0, (2 * m, n)), u0 + dU)
    A = (fx[:n] - fx[n:]).T / (2 * eps)
    B = (fu[:m] - fu[m:]).T / (2 * eps)
    return A, B


def balance_error(obs: Any) -> np.ndarray:
    """``z`` of the module docstring from a decoded observation, shape ``(..., 5)``."""
    return np.stack(
        [-obs.heading_error, obs.lean, obs.dheading - obs.dheading_ref, obs.dlean, obs.dspin - obs.spin_ref],
        axis=-1,
    )


class LQR(Controller):
    """Linear-quadratic regulator about steady upright rolling, gain-scheduled on ``W_ref``.

    For each commanded spin the model's reduced dynamics are linearized at
    ``x = (0, 0, 0, 0, W_ref)``, ``u = (b_roll W_ref, 0)`` (the drive that
    balances rolling resistance) by central finite differences (the Jacobians
    are numerical, from the same ``forward_dynamics`` the simulation uses), and
    ``control.lqr(A, B, Q, R)`` gives ``K``; ``u = u_op - K z``. Gains are cached
    per ``W_ref`` (constant within an episode).

    Parameters
    ----------
    env : gymnasium.Env
        A RollingDisk-v0 environment (wrapped or not).
    Q : array_like (5,) or (5, 5)
        State weights on ``z`` (default ``diag(1, 10, 1, 1, 0.1)``).
    R : array_like (2,) or (2, 2)
        Input weights (default ``diag(10, 10)`` [1/(N m)^2]).
    """

    def __init__(self, env: Any, Q: Any = (1.0, 10.0, 1.0, 1.0, 0.1), R: Any = (10.0, 10.0)):
        super().__init__(env)
        self.Q = np.diag(Q) if np.ndim(Q) == 1 else np.asarray(Q, float)
        self.R = np.diag(R) if np.ndim(R) == 1 else np.asarray(R, float)
        if self.Q.shape != (5, 5) or self.R.shape != (2, 2):
            raise ValueError(f"Q must be 5 x 5 and R 2 x 2, got {self.Q.shape} and {self.R.shape}")
        self._gains: dict[float, np.ndarray] = {}

    def operating_input(self, W: float) -> np.ndarray:
        """Inputs holding steady straight rolling at spin ``W``: the drive against rolling resistance."""
        return np.array([self.model.params.b_roll * W, 0.0])

    def system(self, W: float) -> tuple[np.ndarray, np.ndarray]:
        """``(A, B)`` of the reduced dynamics linearized about upright rolling at spin ``W``."""
        return linearize(self.model.reduced_dynamics, np.array([0.0, 0.0, 0.0, 0.0, W]), self.operating_input(W))

    def gain(self, W: float) -> np.ndarray:
        """LQR gain ``K`` (2 x 5) for spin ``W`` (cached)."""
        key = float(W)
        if key not in self._gains:
            A, B = self.system(key)
            K, _, _ = control.lqr(A, B, self.Q, self.R)
            self._gains[key] = np.asarray(K)
        return self._gains[key]

    def input(self, obs: Any) -> np.ndarray:
        z = balance_error(obs)
        W = np.asarray(obs.spin_ref, float)
        flat_W, flat_z = W.reshape(-1), z.reshape(-1, 5)
        u = np.stack([self.operating_input(w) - self.gain(w) @ zi for w, zi in zip(flat_W, flat_z)])
        return u.reshape(z.shape[:-1] + (2,))


class SteeringPD(Controller):
    """A simple PD steering law on lean and heading, plus a proportional speed hold.

    ``steer = -k_dlean dlean - k_lean lean + k_h heading_error + k_r (dheading_ref - dheading)``,
    ``drive = k_w (W_ref - dspin)``.

    Steering on the lean rate adds to the gyroscopic coupling
    ``A heading'' = -C W lean' + steer`` exactly as extra spin would, which
    raises the stiffness of the lean against gravity (see
    :func:`mbs_envs.models.rolling_disk.critical_spin`). The heading terms are
    off by default: the heading response is non-minimum-phase (to turn left the
    disk must first lean left, which a direct steering torque to the left
    opposes), so a heading PD on the steering torque destabilizes the lean
    (measured: 0 of 10 episodes upright with ``k_h = 0.05, k_r = 0.02``). With
    them off this is a balance law; LQR handles heading and balance together.
    Gains in N m per rad (or rad/s).
    """

    def __init__(
        self,
        env: Any,
        k_dlean: float = 0.3,
        k_lean: float = 0.05,
        k_h: float = 0.0,
        k_r: float = 0.0,
        k_w: float = 0.05,
    ):
        super().__init__(env)
        self.k = dict(k_dlean=k_dlean, k_lean=k_lean, k_h=k_h, k_r=k_r, k_w=k_w)
        for name, value in self.k.items():
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")

    def input(self, obs: Any) -> np.ndarray:
        k = self.k
        steer = (
            -k["k_dlean"] * obs.dlean
            - k["k_lean"] * obs.lean
            + k["k_h"] * obs.heading_error
            + k["k_r"] * (obs.dheading_ref - obs.dheading)
        )
        drive = k["k_w"] * (obs.spin_ref - obs.dspin)
        return np.stack([drive, steer], axis=-1)


class NoControl(Controller):
    """Zero input (the passive disk)."""

    def input(self, obs: Any) -> np.ndarray:
        return np.zeros(np.shape(obs.lean) + (self.model.nu,))
