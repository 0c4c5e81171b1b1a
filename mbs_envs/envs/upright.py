"""The 2R arm's linearization and LQR about upright: what the swing-up controllers balance with and what the v2
swing-up task pays for reaching (the region its LQR catches).

About ``x_up = (q_up, v = 0)`` with ``u = 0`` the arm obeys ``dx/dt = A x + B u`` to first order, ``x = (dq, dv)``;
the LQR with weights ``Q``, ``R`` gives ``u = -K x`` and the cost-to-go ``x^T S x`` (``S`` the Riccati solution).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dynamics.linearize import linearize
from .swingup import Q_UP


def upright_linearization(model: Any, lead: tuple[int, ...] = ()) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of ``dx/dt = A x + B u`` about ``(q_up, v = 0, u = 0)``, ``x = (dq, dv)``: central
    finite differences of the model's ``forward_dynamics``; shapes ``lead + (4, 4)`` and ``lead + (4, nu)``
    (``lead = (B,)`` for a model with per-member parameters of shape ``(B,)``)."""

    def f(x, u):
        return np.concatenate([x[..., 2:], model.forward_dynamics(x[..., :2], x[..., 2:], u)], axis=-1)

    return linearize(f, np.broadcast_to(np.concatenate([Q_UP, np.zeros(2)]), lead + (4,)), np.zeros(lead + (model.nu,)))


def upright_lqr(model: Any, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(K, S)`` of ``control.lqr`` on the model linearized about ``(q_up, v = 0, u = 0)``; ``K`` shape ``(nu, 4)``,
    ``S`` ``(4, 4)``."""
    import control  # python-control: imported here, so that making an env without this region does not load it

    A, B = upright_linearization(model)
    K, S, _ = control.lqr(A, B, Q, R)
    return np.asarray(K), np.asarray(S)
