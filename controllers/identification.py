"""Online identification of the 2R arm's inertial parameters from its energy balance.

The planar 2R arm's dynamics depend on its masses, lengths and inertias only through five
*base parameters* (docs/physics.md §3; Gautier & Khalil's minimal set)::

    th1 = I1 + m1 r1^2 + m2 l1^2      [kg m^2]      th4 = (m1 r1 + m2 l1) g   [N m]
    th2 = m2 l1 r2                    [kg m^2]      th5 = m2 r2 g             [N m]
    th3 = I2 + m2 r2^2                [kg m^2]

(``M11 = th1 + th3 + 2 th2 c2``, ``M12 = th3 + th2 c2``, ``M22 = th3``, ``G1 = th4 c1 + th5 c12``,
``G2 = th5 c12``), and the mechanical energy is linear in them::

    E(q, v) = phi(q, v)^T th,   phi = (v1^2 / 2, c2 (v1^2 + v1 v2), (v1 + v2)^2 / 2, s1, s12).

**Energy balance.** Without friction, ``dE/dt = u v_a`` for the driven joint ``a``; with the input
held constant over a control step (as the env applies it) this integrates exactly::

    (phi(x_{k+W}) - phi(x_k))^T th = sum_{j=k}^{k+W-1} u_j (q_a,{j+1} - q_a,j),

one linear equation per window of ``W`` control steps, with no accelerations to differentiate
(the *energy* or *power* model of Gautier & Khalil 1988). The windows' equations accumulate in the
normal equations ``(A0 + sum d d^T) th = b0 + sum d rhs`` (``d`` the regressor difference), with a
weak prior ``A0 = w diag(th0)^-2``, ``b0 = w / th0`` toward the nominal ``th0``. Observation noise enters
the regressor (errors in variables); windows longer than a step average it down (``W = 10`` at
``dt = 0.01`` s: parameters within about 2 % with noise 0.01 on the observation, 0.1 % without, after
4 s of swing-up). Friction, if the model has any, is taken as known (its work is not modelled here;
the swing-up scenes have none).

**Back to a model.** The controllers use the estimate as a :class:`Planar2R` with per-member
parameters: :func:`params_from_base` picks one physically consistent set of masses, lengths and
inertias (non-negative, as the model's checks require) with exactly these base parameters; any such
set has the same dynamics.

**Work the balance does not model.** An external torque (a push on a link, the DFKI benchmark's perturbation
pulses) adds work that no parameter set explains; its windows bias every parameter at once (measured on the DFKI
pendubot under its pulses: the worst base parameter of each failed episode at 0.3-0.7 of its true value after 10 s). With a gate ``rho``
(:func:`explained`), a window whose residual under the estimate so far exceeds ``rho`` times its gross energy
exchange is left out: a plant within ``rho`` of the estimate in every base parameter never misses by more.
The gate trades the speed of identifying a plant far from the prior (its first windows miss by more) for immunity
to such pushes, so it is a controller setting (off by default).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mbs_envs.models import Planar2R

#: number of base parameters of the 2R arm
N_BASE = 5


def base_parameters(p: Any) -> np.ndarray:
    """The base parameters ``th`` (module docstring) of :class:`Planar2RParams` ``p``.

    Returns
    -------
    ndarray, shape (..., 5)
        Broadcast over per-member parameter arrays.
    """
    th = (p.I1 + p.m1 * p.r1**2 + p.m2 * p.l1**2, p.m2 * p.l1 * p.r2, p.I2 + p.m2 * p.r2**2,
          (p.m1 * p.r1 + p.m2 * p.l1) * p.g, p.m2 * p.r2 * p.g)  # fmt: skip
    return np.stack(np.broadcast_arrays(*th), axis=-1)


def energy_regressor(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``phi(q, v)`` with ``E = phi^T th`` (module docstring).

    Parameters
    ----------
    q, v : ndarray, shape (..., 2)
        Joint angles [rad] (``q = 0``: link 1 horizontal) and rates [rad/s].

    Returns
    -------
    ndarray, shape (..., 5)
        [rad^2/s^2, rad^2/s^2, rad^2/s^2, 1, 1].
    """
    v1, v2 = v[..., 0], v[..., 1]
    return np.stack([0.5 * v1**2, np.cos(q[..., 1]) * (v1**2 + v1 * v2), 0.5 * (v1 + v2) ** 2,
                     np.sin(q[..., 0]), np.sin(q[..., 0] + q[..., 1])], axis=-1)  # fmt: skip


def gauge(th: np.ndarray, g: float) -> np.ndarray:
    """The free ratio ``alpha = m2 r2^2 / th3`` of :func:`params_from_base`, or NaN where ``th`` is
    not the base parameters of any physical arm.

    ``alpha`` in ``(lo, 1]`` gives ``I2 = (1 - alpha) th3 >= 0``, ``I1 >= 0`` (needs
    ``alpha >= th2^2 / (th1 th3)``) and ``m1 r1 >= 0`` (needs ``alpha >= th2 th5 / (th3 th4)``); the
    midpoint of ``(lo, 1)`` is taken. Physical arms have ``th3, th5 > 0`` and ``lo < 1``.
    """
    th1, th2, th3, th4, th5 = np.moveaxis(th, -1, 0)
    ok = (th1 > 0) & (th2 > 0) & (th3 > 0) & (th4 > 0) & (th5 > 0) & (g > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo = np.maximum(th2**2 / (th1 * th3), th2 * th5 / (th3 * th4))
    ok &= lo < 1.0
    return np.where(ok, 0.5 * (1.0 + lo), np.nan)


def params_from_base(th: np.ndarray, nominal: Any) -> dict[str, np.ndarray]:
    """Masses, lengths and inertias with base parameters ``th`` (one of many equivalent sets).

    With ``alpha`` from :func:`gauge`: ``r2 = alpha th3 g / th5``, ``m2 = th5 / (g r2)``,
    ``l1 = th2 / (m2 r2)``, ``I2 = th3 - m2 r2^2``; then ``mu1 = m1 r1 = th4 / g - m2 l1``, the rest
    ``rho = th1 - m2 l1^2`` split as ``I1 = rho / 2``, ``m1 r1^2 = rho / 2`` (``r1 = rho / (2 mu1)``,
    ``m1 = mu1 / r1``; ``r1 = 0``, ``m1`` nominal where ``mu1 = 0``). ``g``, ``l2`` and friction stay
    the nominal ones.

    Parameters
    ----------
    th : ndarray, shape (..., 5)
        Base parameters of physical arms (:func:`gauge` not NaN).
    nominal : Planar2RParams

    Returns
    -------
    dict
        ``m1, m2, l1, r1, r2, I1, I2``, each of shape ``th.shape[:-1]``.
    """
    g = nominal.g
    alpha = gauge(th, g)
    if np.isnan(alpha).any():
        raise ValueError("th: not the base parameters of a physical 2R arm")
    th1, th2, th3, th4, th5 = np.moveaxis(th, -1, 0)
    r2 = alpha * th3 * g / th5
    m2 = th5 / (g * r2)
    l1 = th2 / (m2 * r2)
    mu1 = np.maximum(th4 / g - m2 * l1, 0.0)
    rho = th1 - m2 * l1**2
    with np.errstate(divide="ignore", invalid="ignore"):
        r1 = np.where(mu1 > 0, rho / (2 * mu1), 0.0)
        m1 = np.where(mu1 > 0, mu1 / r1, nominal.m1)
    I1 = np.where(mu1 > 0, 0.5 * rho, rho)
    return {"m1": m1, "m2": m2, "l1": l1, "r1": r1, "r2": r2, "I1": I1, "I2": th3 - m2 * r2**2}


def identified_model(th: np.ndarray, nominal: Planar2R) -> Planar2R:
    """The nominal model with per-member parameters of base parameters ``th`` (shape ``(B, 5)``)."""
    model = Planar2R(nominal.params, driven=nominal.driven)
    model.params = nominal.params.batched(**params_from_base(th, nominal.params))
    return model


def prior(th0: np.ndarray, weight: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A0, b0)`` of the prior toward ``th0`` (shape ``(5,)``) with ``weight`` w [J^2] (module docstring)."""
    return weight * np.diag(th0**-2.0), weight / th0


def estimate(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``th`` solving the normal equations ``A th = b``; shapes ``(..., 5, 5)``, ``(..., 5)`` -> ``(..., 5)``."""
    return np.linalg.solve(A, b[..., None])[..., 0]


def explained(r: np.ndarray, work: np.ndarray, d: np.ndarray, th: np.ndarray, gate: Any) -> np.ndarray:
    """Whether a window's energy balance is explained by a parameter error: its prediction residual within ``gate``
    times the window's gross energy exchange,

        |r| <= gate (|W| + sum_i |d_i th_i|),   r = W - d^T th,

    with ``th`` the estimate before the window. A parameter error of at most ``gate`` relative in every base parameter
    misses by at most ``gate * sum_i |d_i th_i|``; a window that misses by more than that carried work the balance does
    not model (an external torque: a push, a collision) and is left out of the normal equations (module docstring).

    Parameters
    ----------
    r, work : ndarray, shape (n,)
        The residual and the input work ``W`` of each window [J].
    d : ndarray, shape (n, 5)
        The regressor differences of the windows.
    th : ndarray, shape (n, 5)
        The estimates the residuals were computed with.
    gate : float or ndarray of shape (n,)
        The relative bound (> 0); ``inf``: every window is taken.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    gate = np.broadcast_to(np.asarray(gate, float), np.shape(r))
    gross = np.abs(work) + np.abs(d * th).sum(axis=-1)
    return np.isinf(gate) | (np.abs(r) <= gate * gross)
