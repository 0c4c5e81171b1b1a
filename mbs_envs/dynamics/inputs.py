"""Inputs with structure an integrator can use: a joint-space PD law.

:class:`JointPD` is an ordinary input ``u(t, q, v)`` for every integrator (it
is callable), and it tells :class:`mbs_envs.dynamics.integrators.JointImplicitEuler`
its gains, so that the stiffness ``K_p`` and damping ``K_d`` enter that step
implicitly (``h^2 K_p`` and ``h K_d`` on the diagonal of the mass matrix).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class JointPD:
    """``u = u_ff + K_p (q_ref - B^T q) - K_d B^T v``: joint PD on the driven joints, held targets.

    Attributes
    ----------
    kp : ndarray, shape (nu,)
        Stiffness [N m/rad], >= 0 (a scalar is broadcast when called).
    kd : ndarray, shape (nu,)
        Damping [N m s/rad], >= 0.
    q_ref : ndarray, shape (nu,)
        Target angles of the driven joints [rad].
    u_ff : ndarray, shape (nu,)
        Feed-forward input [N m] (default 0).

    ``B`` is the model's actuation matrix (a selection of joints: columns of
    the identity), ``q`` and ``v`` the joint coordinates (``nq = nv``).
    """

    kp: Any
    kd: Any
    q_ref: Any
    u_ff: Any = 0.0

    def __post_init__(self) -> None:
        for name in ("kp", "kd"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.ndim > 1 or not np.all(np.isfinite(value)) or np.any(value < 0):
                raise ValueError(
                    f"JointPD: {name} must be finite and >= 0 (scalar or one per driven joint), got {getattr(self, name)!r}"
                )
            object.__setattr__(self, name, value)
        for name in ("q_ref", "u_ff"):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.ndim > 1 or not np.all(np.isfinite(value)):
                raise ValueError(
                    f"JointPD: {name} must be finite (scalar or one per driven joint), got {getattr(self, name)!r}"
                )
            object.__setattr__(self, name, value)

    def __call__(self, t: float, q: np.ndarray, v: np.ndarray, B: np.ndarray | None = None) -> np.ndarray:
        """The input ``u`` [N m], shape ``(..., nu)``; ``B`` defaults to the identity."""
        q_act = q if B is None else q @ B
        v_act = v if B is None else v @ B
        return self.u_ff + self.kp * (self.q_ref - q_act) - self.kd * v_act

    def diagonals(self, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``diag(B K_p B^T), diag(B K_d B^T)``, shape ``(nv,)`` each.

        Raises
        ------
        ValueError
            If ``B`` is not a selection of joints (columns of the identity): then
            ``B K B^T`` is not diagonal and the O(N) implicit step does not apply.
        """
        B = np.asarray(B, float)
        selection = np.all((B == 0) | (B == 1)) and np.all(B.sum(axis=0) == 1) and np.all(B.sum(axis=1) <= 1)
        if not selection:
            raise ValueError(
                "JointPD: the model's actuation must select joints (columns of the identity) for an implicit joint PD"
            )
        nu = B.shape[1]
        kp = np.broadcast_to(self.kp, (nu,))
        kd = np.broadcast_to(self.kd, (nu,))
        return B @ kp, B @ kd
