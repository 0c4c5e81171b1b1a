"""Jacobians of a batched vector field by central finite differences (the linearizations of the controllers and
of the swing-up task's upright region)."""

from __future__ import annotations

from typing import Any

import numpy as np


def linearize(f: Any, x0: np.ndarray, u0: np.ndarray, eps: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians ``A = df/dx``, ``B = df/du`` at ``(x0, u0)`` by central finite differences.

    Central differences have truncation error ``O(eps^2)`` and round-off
    ``O(1e-16 / eps)``: about 1e-10 relative at ``eps = 1e-6`` for these smooth maps.

    Parameters
    ----------
    f : callable ``f(x, u) -> dx/dt``, batched over leading dimensions
    x0 : ndarray, shape (..., n)
    u0 : ndarray, shape (..., m)
        Leading dimensions (a batch of points, e.g. one per member of a model with per-member
        parameters) broadcast; ``f`` is called once with a leading axis of ``2 n`` (``2 m``) prepended.

    Returns
    -------
    A : ndarray, shape (..., n, n)
    B : ndarray, shape (..., n, m)
    """
    x0, u0 = np.asarray(x0, float), np.asarray(u0, float)
    n, m = x0.shape[-1], u0.shape[-1]
    lead = np.broadcast_shapes(x0.shape[:-1], u0.shape[:-1])
    pad = (1,) * len(lead)
    dX = (np.concatenate([np.eye(n), -np.eye(n)]) * eps).reshape((2 * n,) + pad + (n,))
    dU = (np.concatenate([np.eye(m), -np.eye(m)]) * eps).reshape((2 * m,) + pad + (m,))
    fx = f(np.broadcast_to(x0, lead + (n,)) + dX, np.broadcast_to(u0, (2 * n,) + lead + (m,)))  # one batched call
    fu = f(np.broadcast_to(x0, (2 * m,) + lead + (n,)), np.broadcast_to(u0, lead + (m,)) + dU)
    A = np.moveaxis(fx[:n] - fx[n:], 0, -1) / (2 * eps)
    B = np.moveaxis(fu[:m] - fu[m:], 0, -1) / (2 * eps)
    return A, B
