"""Swing-up and balance of the 2R arm with one motor: energy pumping through partial
feedback linearization, switching to LQR about upright (Acrobot, Pendubot: v0 and v1).

Let ``a`` be the driven joint and ``p`` the passive one. With ``M q'' + h = B u``
(``h = C v + G + F``; docs/physics.md §3) the passive row gives
``q_p'' = -(M_pa y + h_p) / M_pp`` for a commanded ``q_a'' = y``, and the driven row
the input that produces it (*collocated partial feedback linearization*, Spong 1994):

    u = M_aa y + M_ap q_p'' + h_a.

The outer loop pumps energy toward the upright energy ``E_up = V(q_up)`` while a PD
keeps the driven joint near its upright value, with ``E~ = E - E_up``:

- acrobot (elbow driven; Spong 1995):   ``y = -k_q wrap(th2) - k_v dth2 + k_E E~ dth1``
- pendubot (shoulder driven):          ``y = -k_q wrap(th1 - pi/2) - k_v dth1 - k_E E~ dth1``

(for the pendubot ``dE/dt = dth1 u`` with the friction-free arm, so ``-E~ dth1`` feeds
energy in while ``E < E_up``; for the acrobot the elbow's motion pumps through the
coupling, and ``+E~ dth1`` is the sign of Spong's law).

**The kick.** For the acrobot the hanging rest is an equilibrium of this closed loop: every
term of ``y`` vanishes there, and so does ``h_a`` (no motion, gravity's moment zero at hanging).
An arm started exactly at rest (the DFKI benchmark's protocol, ``preset="dfki_c1"``) would never
move. Where the arm is within :data:`REST_TOL` of the hanging rest (every angle and rate), the
PD aims the driven joint at an offset of :data:`KICK` rad from its upright value instead
(``y = -k_q (wrap(th_a - th_a,up) - KICK) - k_v dth_a``): one control step's push, after which
the pumping grows the motion. The scenes' own starts (uniform within 0.1 of hanging in each of the
four entries) come that close with probability 1e-8, so the law is unchanged there. Near upright an LQR balances:
``u = -K x`` with ``x = (wrap(q - q_up), v)`` and ``K`` from ``control.lqr`` on the
model's linearization about upright (central finite differences of the same
``forward_dynamics`` the simulation uses), ``Q = diag(10, 10, 1, 1)``, ``R = lqr_r``
[(N m)^-2] (default 1; tuned with the catch level: a larger ``R`` gives smaller gains, which
saturate the motor later, so the LQR holds from farther out).

**Switching rule** (with hysteresis): the LQR takes over when ``x^T S x < catch``
(``S`` the Riccati solution, so ``x^T S x`` is the LQR's cost-to-go from ``x``) and hands
back to swing-up only when ``x^T S x > release * catch``. The mode is the controller's
memory, kept in SB3's ``state`` (reset where ``episode_start``), so ``evaluate_policy``
and the batched rollouts carry it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mbs_envs import validation as check
from mbs_envs.envs.swingup import Q_DOWN, Q_UP, SwingUpEnv
from mbs_envs.envs.tracking import wrap_angle
from mbs_envs.envs.upright import upright_linearization, upright_lqr  # noqa: F401  (re-exported)

from .base import Controller, solve_rows
from .tuned import tuned_gains

#: a state within this of the hanging rest (each angle [rad] and rate [rad/s]) is at rest there (the kick)
REST_TOL = 1e-3
#: the driven joint's setpoint offset [rad] the swing-up's PD aims at from the hanging rest (module docstring)
KICK = 0.1


def collocated_pfl(
    model: Any, q: np.ndarray, v: np.ndarray, y: np.ndarray, a: int, M: Any = None, h: Any = None
) -> np.ndarray:
    """The driven coordinate's input that gives it the acceleration ``y`` (module docstring): the passive rows give
    ``q_p'' = -M_pp^-1 (M_pa y + h_p)``, the driven row ``u = M_aa y + M_ap q_p'' + h_a``.

    Parameters
    ----------
    model : a model with ``mass_matrix`` and ``bias`` (the arm; any one-input derived model)
    q, v : ndarray, shape (..., n)
    y : ndarray, shape (...)
        Commanded acceleration of coordinate ``a`` [rad/s^2 or m/s^2].
    a : int
        The driven coordinate.
    M, h : ndarray, shapes (..., n, n) and (..., n), optional
        ``M(q)`` and ``h(q, v)`` where the caller has them already (default: from ``model``).

    Returns
    -------
    ndarray, shape (...)
        ``u`` [N m or N].
    """
    M = model.mass_matrix(q) if M is None else M
    h = model.bias(q, v) if h is None else h
    p = np.arange(np.shape(q)[-1]) != a
    M_pa, h_p = M[..., p, a], h[..., p]
    if p.sum() == 1:  # one passive coordinate (the arm): a division
        a_p = -(M_pa * y[..., None] + h_p) / M[..., p, :][..., p][..., 0]
    else:
        a_p = -solve_rows(M[..., p, :][..., p], (M_pa * y[..., None] + h_p)[..., None])[..., 0]
    return M[..., a, a] * y + np.einsum("...i,...i->...", M[..., a, p], a_p) + h[..., a]


def at_rest(q: np.ndarray, v: np.ndarray, tol: float = REST_TOL) -> np.ndarray:
    """Whether the arm is at rest hanging: every angle within ``tol`` [rad] of :data:`~mbs_envs.envs.swingup.Q_DOWN`
    (wrapped) and every rate within ``tol`` [rad/s] of zero; ``q, v`` shape ``(..., 2)``, result ``(...)``."""
    return (np.abs(wrap_angle(q - Q_DOWN)).max(axis=-1) < tol) & (np.abs(v).max(axis=-1) < tol)


def switch(
    x: np.ndarray, S: np.ndarray, balancing: Any, episode_start: Any, catch: float, release: float
) -> np.ndarray:
    """The switching rule with hysteresis (module docstring): whether the LQR holds each member now.

    Parameters
    ----------
    x : ndarray, shape (..., 2 n)
        The error state ``(e, v)`` about upright.
    S : ndarray, shape (..., 2 n, 2 n)
        The Riccati solution (per member if batched).
    balancing : array_like of bool, shape (...), or None
        The mode so far (None: nobody balancing yet); reset where ``episode_start``.
    catch, release : float
        Take over where ``x^T S x < catch``, hand back where ``x^T S x > release * catch``.

    Returns
    -------
    ndarray of bool, shape (...)
    """
    cost = np.einsum("...i,...ij,...j->...", x, S, x)
    lead = cost.shape
    balancing = np.zeros(lead, bool) if balancing is None else check.shaped(balancing, "state", lead, bools=True) != 0
    if episode_start is not None:
        balancing = np.where(check.shaped(episode_start, "episode_start", lead, bools=True, broadcast=True) != 0, False,
                             balancing)  # fmt: skip
    return np.where(balancing, cost <= release * catch, cost < catch)


class CatchingSwingUp(Controller):
    """A swing-up law with an LQR that catches near upright: the switching rule (:func:`switch`), its mode kept in SB3's
    ``state``. Subclasses give ``swing_up(q, v)``, ``upright_state(q, v)`` (the LQR's error state ``x``) and set
    ``K``, ``S``, ``catch``, ``release``."""

    K: np.ndarray
    S: np.ndarray
    catch: float
    release: float

    def swing_up(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The swing-up input ``u``, shape ``(...)``."""
        raise NotImplementedError

    def upright_state(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The LQR's error state ``x = (e, v)`` about upright, shape ``(..., 2 n)``."""
        raise NotImplementedError

    def balance(self, q: np.ndarray, v: np.ndarray, balancing: Any, episode_start: Any, catch: float | None = None,
                release: float | None = None, K: Any = None, S: Any = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """The switching rule (:func:`switch`) and the LQR's input.

        Parameters
        ----------
        q, v : ndarray, shape (..., n)
        balancing : array_like of bool, shape (...), or None
            The mode so far (None: nobody balancing yet); reset where ``episode_start``.
        catch, release : float, optional
            The level and hysteresis; default the controller's own.
        K, S : ndarray, shapes (..., 1, 2 n) and (..., 2 n, 2 n), optional
            The LQR's gain and Riccati solution; default the controller's own (per member if batched).

        Returns
        -------
        balancing : ndarray of bool, shape (...)
            Whether the LQR holds each member now.
        u_lqr : ndarray, shape (...)
            ``-K x`` [N m or N], ``x`` of :meth:`upright_state`.
        """
        catch = self.catch if catch is None else catch
        release = self.release if release is None else release
        K = self.K if K is None else K
        S = self.S if S is None else S
        x = self.upright_state(q, v)
        return switch(x, S, balancing, episode_start, catch, release), -np.einsum("...ij,...j->...i", K, x)[..., 0]

    def control(self, obs: Any, state: Any, episode_start: Any) -> tuple[np.ndarray, Any]:
        balancing, u_lqr = self.balance(obs.q, obs.v, state, episode_start)
        u = np.where(balancing, u_lqr, self.swing_up(obs.q, obs.v))
        return u[..., None], balancing

    def input(self, obs: Any) -> np.ndarray:
        """Inputs without memory (swing-up unless already inside the catch region)."""
        return self.control(obs, None, None)[0]


class SwingUpLQR(CatchingSwingUp):
    """Energy-based swing-up through partial feedback linearization, then LQR (module docstring).

    Parameters
    ----------
    env : gymnasium.Env
        an Acrobot or Pendubot env, any version (wrapped or not).
    k_q, k_v : float, optional
        PD of the driven joint during swing-up [1/s^2, 1/s]; default the tuned ones.
    k_E : float, optional
        Energy-pumping gain [1/(J s)]; default the tuned one.
    catch : float, optional
        LQR takes over below this cost-to-go ``x^T S x``; default the tuned one.
    release : float
        Swing-up resumes above ``release * catch`` (hysteresis, > 1).
    lqr_r : float, optional
        The LQR's input weight ``R`` [(N m)^-2]; default the tuned one (1 if none).
    """

    fits = (SwingUpEnv,)
    #: the entry of controllers/tuned.json
    tuned_name = "swing-up + LQR"
    Q = np.diag([10.0, 10.0, 1.0, 1.0])

    def __init__(self, env: Any, k_q: Any = None, k_v: Any = None, k_E: Any = None, catch: Any = None, release: float = 4.0,
                 lqr_r: Any = None):  # fmt: skip
        super().__init__(env)
        tuned = tuned_gains(env, self.tuned_name)
        self.k_q = check.nonnegative(tuned["k_q"] if k_q is None else k_q, "k_q")
        self.k_v = check.nonnegative(tuned["k_v"] if k_v is None else k_v, "k_v")
        self.k_E = check.nonnegative(tuned["k_E"] if k_E is None else k_E, "k_E")
        self.catch = check.positive(tuned["catch"] if catch is None else catch, "catch")
        self.release = check.real(release, "release", 1.0, np.inf, low_open=True)
        self.lqr_r = check.positive(tuned.get("lqr_r", 1.0) if lqr_r is None else lqr_r, "lqr_r")
        self.R = np.full((1, 1), self.lqr_r)
        self.driven = int(self.model.driven[0])
        self.E_up = float(self.model.potential_energy(Q_UP))
        self.K, self.S = upright_lqr(self.model, self.Q, self.R)

    def swing_up(self, q: np.ndarray, v: np.ndarray, model: Any = None) -> np.ndarray:
        """The swing-up input ``u`` [N m], shape ``(...)``, computed on ``model`` (default the
        controller's own; one with per-member parameters gives each member its own)."""
        model = self.model if model is None else model
        a = self.driven
        E_up = self.E_up if model is self.model else model.potential_energy(np.broadcast_to(Q_UP, q.shape))
        E_err = model.energy(q, v) - E_up
        pump = self.k_E * E_err * v[..., 0] * (1.0 if a == 1 else -1.0)
        kick = np.where(at_rest(q, v), KICK, 0.0)
        y = -self.k_q * (wrap_angle(q[..., a] - Q_UP[a]) - kick) - self.k_v * v[..., a] + pump
        return collocated_pfl(model, q, v, y, a)

    def upright_state(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``x = (wrap(q - q_up), v)``, shape ``(..., 4)``."""
        return np.concatenate([wrap_angle(q - Q_UP), v], axis=-1)
