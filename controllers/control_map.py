"""The discrete control map the swing-up environments integrate, for controllers that simulate ahead.

``x_{k+1} = F(x_k, u_k)``: ``x = (q, v)``, ``u`` held for one control step ``dt``, advanced by
``substeps`` steps of the project's classical RK4 stepper
(:func:`mbs_envs.dynamics.integrators.get`) with the model's ``forward_dynamics``, batched over
leading axes. It is the env's own step (Acrobot-v1's default: ``dt = 0.01``, 2 substeps) to
round-off: ``tests/controllers/test_region.py`` checks it against ``env.step``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mbs_envs.dynamics import integrators
from mbs_envs.envs.tracking import wrap_angle

_RK4 = integrators.get("rk4")


def rk4_map(model: Any, x: np.ndarray, u: np.ndarray, dt: float, substeps: int) -> np.ndarray:
    """``F(x, u)``: one control step of ``substeps`` RK4 steps with ``u`` held (module docstring).

    Parameters
    ----------
    model : Planar2R (or any model with ``forward_dynamics(q, v, u)``)
    x : ndarray, shape (..., 2 nv)
        ``(q, v)`` [rad, rad/s].
    u : ndarray, shape (..., nu)
        Inputs [N m], broadcast against ``x``.
    dt : float
        Control step [s].
    substeps : int

    Returns
    -------
    ndarray, shape of ``x``
    """
    n = x.shape[-1] // 2
    u = np.broadcast_to(u, x.shape[:-1] + (np.shape(u)[-1],))
    q, v = x[..., :n], x[..., n:]
    h = dt / substeps
    for _ in range(substeps):
        q, v = _RK4.step(lambda t, q, v: model.forward_dynamics(q, v, u), 0.0, q, v, h)
    return np.concatenate([q, v], axis=-1)


def fast_map(model: Any, x: np.ndarray, u: np.ndarray, dt: float, substeps: int) -> np.ndarray:
    """:func:`rk4_map`, compiled for the 2R arm with one motor (:func:`controllers.trajectory.map_rows`, equal to
    round-off); any other model (or input) takes :func:`rk4_map`. Same arguments and result; the model's parameters
    may be per member, broadcast against ``x``'s leading axes."""
    from mbs_envs.models.planar2r import Planar2R

    from . import trajectory as traj

    if not (isinstance(model, Planar2R) and len(model.driven) == 1 and x.shape[-1] == 4 and np.shape(u)[-1:] == (1,)):
        return rk4_map(model, x, u, dt, substeps)
    lead = np.broadcast_shapes(x.shape[:-1], np.shape(u)[:-1])
    theta = np.asarray(model.kernel_params(), float)
    n = int(np.prod(lead))
    theta = np.broadcast_to(theta, lead + theta.shape[-1:]).reshape(n, -1).T if theta.ndim > 1 else theta[:, None]
    X = np.ascontiguousarray(np.broadcast_to(x, lead + (4,)).reshape(n, 4), float)
    U = np.ascontiguousarray(np.broadcast_to(u, lead + (1,)).reshape(n), float)
    out = np.empty((n, 4))
    traj.map_rows(X, U, int(model.driven[0]), np.ascontiguousarray(theta), float(dt), int(substeps), out)
    return out.reshape(lead + (4,))


def state_error(x: np.ndarray, x_ref: np.ndarray) -> np.ndarray:
    """``x - x_ref`` with the angles (the first half) wrapped to ``[-pi, pi)``, shape of ``x``."""
    n = x.shape[-1] // 2
    d = x - x_ref
    return np.concatenate([wrap_angle(d[..., :n]), d[..., n:]], axis=-1)
