"""What observation noise leaves of a hold, by simulation: the share of 2-s windows in which given gains with a
given filter keep both angles within a tolerance (:func:`hold_shares`), on the noisy linearization or the arm's own
map (:class:`ArmMap`). An estimate, not a bound.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .control_map import fast_map, state_error
from .hold_laws import ZeroDynamicsHold, hold_input, recovering, rescuing


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
        xh = xh + (flat(x + rng.normal(0.0, sigma, (windows, n)) - xh) @ L.T).reshape(
            G, windows, n
        )  # the filter's update
        banded = recovering(xh, recover, band, back)
        recover = (
            banded
            if coef is None
            else np.where(np.isfinite(coef).all(axis=-1), rescuing(xh, coef, recover, zd, back), banded)
        )
        u = np.clip(hold_input(xh, recover, K, K_e, K_r, edge, lead, joint, coef, zd), -u_max, u_max)[..., None]
        # the plant's step and the filter's prediction
        if arm is None:
            x, xh = (
                (flat(x) @ A_d.T).reshape(G, windows, n) + u * B_d.T,
                (flat(xh) @ A_d.T).reshape(G, windows, n) + u * B_d.T,
            )
        else:
            with np.errstate(all="ignore"):
                x, xh = arm.step(x, u), arm.step(xh, u)
            over |= ~(np.abs(x[..., : n // 2]) <= arm.drop).all(axis=-1)
            x, xh = (np.where(over[..., None], 0.0, a) for a in (x, xh))  # (over: no longer stepped)
        if k >= settle_steps:
            held &= np.all(np.abs(x[..., : n // 2]) <= tol, axis=-1) & ~over
    return held.mean(axis=1)
