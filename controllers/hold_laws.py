"""The hold's input laws about upright under observation noise (docs/physics.md §7): the hold on the zero dynamics
(:func:`zero_dynamics`, :func:`zero_dynamics_input`, :func:`rescuing`) and the edge-switched LQRs
(:func:`edge_switched`, :func:`recovering`); :func:`hold_input` is the law of a holding member, either way.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


def edge_switched(x: np.ndarray, K: np.ndarray, K_e: np.ndarray, edge: Any, lead: Any, joint: int) -> np.ndarray:
    """The hold's input law with its edge gain: ``u = -K_e x`` where the angle ``joint`` is heading out, ``|x_j + lead
    v_j| > edge`` (the angle ``lead`` seconds ahead at its present rate beyond ``edge``), else ``u = -K x``.

    An LQR weighs the state's spread, not the chance of leaving a box: near the box's edge a second gain that
    stops the angle (at the other angle's expense, which has room) keeps more windows inside
    (:func:`hold_shares`, docs/physics.md §7).

    Parameters
    ----------
    x : ndarray, shape (..., 2 m)
        The state about upright ``(angles [rad], rates [rad/s])``.
    K, K_e : ndarray, shapes broadcasting with ``x``, (..., 2 m)
        The gains inside and at the edge [N m per unit of the state].
    edge : float or ndarray
        [rad]; ``inf``: never the edge gain.
    lead : float or ndarray
        [s].
    joint : int
        The angle watched (``0 <= joint < m``).

    Returns
    -------
    ndarray, shape (...)
        The input [N m], unsaturated.
    """
    m = x.shape[-1] // 2
    out = np.abs(x[..., joint] + lead * x[..., m + joint]) > edge
    return np.where(out, -np.sum(x * K_e, axis=-1), -np.sum(x * K, axis=-1))


def recovering(x: np.ndarray, before: np.ndarray, band: Any, back: Any) -> np.ndarray:
    """The hold's band rule with hysteresis: whether each member recovers (with its recovery gain) at state ``x``,
    having recovered (``before``) or held at the previous step: a holding member starts to recover where an angle is
    more than ``band`` off upright, a recovering one holds again where both are within ``back``.

    Parameters
    ----------
    x : ndarray, shape (..., 2 m)
        The (estimated) state about upright [rad, rad/s].
    before : ndarray of bool, shape (...)
    band, back : float or ndarray broadcasting with ``before``
        [rad], ``back <= band``.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    off = np.abs(x[..., : x.shape[-1] // 2]).max(axis=-1)
    return np.where(before, off > back, off > band)


def hold_input(x: np.ndarray, recover: np.ndarray, K: np.ndarray, K_e: np.ndarray, K_r: np.ndarray, edge: Any, lead: Any,
               joint: int, coef: np.ndarray | None = None, zd: ZeroDynamicsHold | None = None) -> np.ndarray:  # fmt: skip
    """The hold's input law, unsaturated: where ``coef`` (:func:`zero_dynamics`' coefficients, shape broadcasting
    with ``(..., 7)``) is finite, :func:`zero_dynamics_input` with ``zd``'s settings (its rescue reach where a member
    recovers, ``recover``: :func:`rescuing`); elsewhere ``u = -K_r x`` where a member recovers (:func:`recovering`),
    else :func:`edge_switched` between ``K`` and ``K_e``; shapes as there, ``recover`` of shape ``(...)``."""
    out = np.where(recover, -np.sum(x * K_r, axis=-1), edge_switched(x, K, K_e, edge, lead, joint))
    if coef is not None:
        finite = np.isfinite(coef).all(axis=-1)
        reach = np.where(recover, zd.rescue_reach, zd.reach)
        with np.errstate(all="ignore"):  # (NaN rows: not used)
            out = np.where(finite, zero_dynamics_input(x, coef, zd.rate, reach, zd.omega, joint), out)
    return out


def zero_dynamics(A: np.ndarray, B: np.ndarray, joint: int) -> np.ndarray:
    """The unactuated combination of a two-link arm's linearization about upright and its zero dynamics.

    With ``q'' = M q + beta u`` (the rate rows of ``A``, ``B``), ``c = (beta_1, -beta_0)`` is blind to the input:
    ``p = c . q`` obeys ``p'' = c M q``, which in ``p`` and the driven angle ``q_j`` reads ``p'' = a p - g q_j``. Where
    ``a > 0`` (the arm with its driven joint locked falls: the acrobot's zero dynamics), ``z = p' + lam p``, ``lam =
    sqrt(a)``, is its unstable mode, ``z' = lam z - g q_j``: the driven angle is the input that keeps it, and so the
    arm, upright (docs/physics.md §7).

    Parameters
    ----------
    A, B : ndarray, shapes (..., 4, 4), (..., 4, 1)
        Continuous linearizations about upright, state ``(q, v)`` [rad, rad/s].
    joint : int
        The driven joint (0 or 1).

    Returns
    -------
    ndarray, shape (..., 7)
        ``(c_0, c_1, lam, g, M_j0, M_j1, beta_j)``: ``c`` [rad/s^2 per N m, as ``beta``], ``lam`` [1/s], ``g``
        [1/s^2 times the units of ``c``], the driven joint's row of ``M`` [1/s^2] and its input gain [rad/s^2 per
        N m]; ``lam`` NaN where ``a <= 0`` (no unstable zero dynamics) or the driven joint does not respond to the
        input.
    """
    M, beta = A[..., 2:, :2], B[..., 2:, 0]
    c = np.stack([beta[..., 1], -beta[..., 0]], axis=-1)
    r = np.einsum("...i,...ij->...j", c, M)
    i = 1 - joint
    with np.errstate(divide="ignore", invalid="ignore"):
        a = r[..., i] / c[..., i]
        g = a * c[..., joint] - r[..., joint]
        lam = np.where(a > 0, np.sqrt(np.abs(a)), np.nan)
    lam = np.where(np.abs(beta[..., joint]) > 0, lam, np.nan)
    return np.concatenate([c, lam[..., None], g[..., None], M[..., joint, :], beta[..., joint, None]], axis=-1)


@dataclasses.dataclass(frozen=True)
class ZeroDynamicsHold:
    """The settings of the hold on the zero dynamics (:func:`zero_dynamics_input`, :func:`rescuing`).

    rate : float
        The unstable mode's closed-loop decay rate [1/s] where the driven angle's request is linear.
    reach : float
        The most the driven angle is asked off upright while holding [rad].
    omega : float
        The driven angle's loop [rad/s] (critically damped).
    rescue_reach : float
        The reach while rescuing [rad]: beyond the box, where the mode has escaped what the box allows.
    trigger, release : float
        A holding member rescues where ``|z|`` exceeds ``trigger`` times the mode's capture within ``reach``,
        ``g reach / lam``, and holds again where it is below ``release`` times it with both angles within the way
        back.

    Each field is a float, or an array broadcasting with the members (``(G, 1)`` in :func:`hold_shares`: ``G``
    settings scored in one batch).
    """

    rate: float = 35.0
    reach: float = 0.0975
    omega: float = 45.0
    rescue_reach: float = 0.2
    trigger: float = 1.35
    release: float = 0.7


def zero_dynamics_mode(x: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """The unstable mode ``z = c . v + lam c . q`` of :func:`zero_dynamics` at the states ``x`` (shape (..., 4)) [units
    of ``c`` times rad/s], shape (...)."""
    return np.sum(coef[..., :2] * x[..., 2:], axis=-1) + coef[..., 2] * np.sum(coef[..., :2] * x[..., :2], axis=-1)


def rescuing(x: np.ndarray, coef: np.ndarray, before: np.ndarray, zd: ZeroDynamicsHold, back: Any) -> np.ndarray:
    """The zero-dynamics hold's rescue rule with hysteresis: whether each member rescues (the law with
    ``zd.rescue_reach``) at state ``x``, having rescued (``before``) or held at the previous step. Within ``reach``
    the driven angle pulls the mode back only while ``|z| < g reach / lam`` (``z' = lam z - g q_j``): past
    ``zd.trigger`` times that a holding member rescues (the box is lost for a while, the arm is not), and holds again
    where ``|z|`` is below ``zd.release`` times it and both angles are within ``back`` [rad]. Shapes as
    :func:`recovering`, ``coef`` broadcasting with ``(..., 7)``."""
    z = np.abs(zero_dynamics_mode(x, coef))
    with np.errstate(invalid="ignore", divide="ignore"):  # (rows without coefficients: not used)
        capture = np.abs(coef[..., 3]) * zd.reach / coef[..., 2]
    inside = np.abs(x[..., : x.shape[-1] // 2]).max(axis=-1) <= back
    return np.where(before, ~((z < zd.release * capture) & inside), z > zd.trigger * capture)


def zero_dynamics_input(x: np.ndarray, coef: np.ndarray, rate: Any, reach: Any, omega: Any, joint: int) -> np.ndarray:
    """The hold's input law on the zero dynamics (:func:`zero_dynamics`), unsaturated.

    The driven angle is asked to be ``q_j* = reach tanh(k z / reach)``, ``k = (lam + rate) / g`` (the unstable mode
    ``z`` decays at ``rate`` where the request is linear, and the request never leaves ``reach``: near the box's edge
    the driven angle stops and the mode is pushed back as hard as the box allows), with ``q_j*' = k z' sech^2(k z /
    reach)``, ``z' = lam z - g q_j``; the driven angle follows it as a critically damped second-order loop of natural
    frequency ``omega``, its acceleration asked of the linearization: ``u = (a_j - M_j . q) / beta_j``, ``a_j = -omega^2
    (q_j - q_j*) - 2 omega (v_j - q_j*')``.

    Parameters
    ----------
    x : ndarray, shape (..., 4)
        The state about upright ``(q, v)`` [rad, rad/s].
    coef : ndarray, shape broadcasting with ``(..., 7)``
        :func:`zero_dynamics`' coefficients.
    rate : float or ndarray
        The unstable mode's closed-loop decay rate [1/s] (> 0).
    reach : float or ndarray
        The most the driven angle is asked off upright [rad].
    omega : float or ndarray
        The driven angle's loop [rad/s].
    joint : int
        The driven joint.

    Returns
    -------
    ndarray, shape (...)
        The input [N m], unsaturated.
    """
    lam, g, M_j, beta_j = coef[..., 2], coef[..., 3], coef[..., 4:6], coef[..., 6]
    q, v = x[..., :2], x[..., 2:]
    z = zero_dynamics_mode(x, coef)
    k = (lam + rate) / g
    s = k * z / reach
    target = reach * np.tanh(s)
    target_rate = k * (lam * z - g * q[..., joint]) / np.cosh(np.clip(s, -50.0, 50.0)) ** 2
    a_j = -(omega**2) * (q[..., joint] - target) - 2.0 * omega * (v[..., joint] - target_rate)
    return (a_j - np.sum(M_j * q, axis=-1)) / beta_j
