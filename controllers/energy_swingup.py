"""Swing-up and balance of a derived mechanism with one input (``mbs_envs.envs.derived_swingup``): energy pumping
through collocated partial feedback linearization, then LQR about upright.

Let ``a`` be the driven coordinate and ``p`` the passive ones. With ``M q'' + h = B u`` the passive rows give
``q_p'' = -M_pp^-1 (M_pa y + h_p)`` for a commanded ``q_a'' = y``, and the driven row the input that produces it
(Spong 1994; :func:`controllers.swingup.collocated_pfl`), ``u = M_aa y + M_ap q_p'' + h_a``. The outer loop pumps the energy of the passive part,

    E_p = 1/2 v_p^T M_pp v_p + V(q),

toward ``E_up = V(q_up)`` while a PD brings the driven coordinate back to its upright value:

    y = -k_q e_a - k_v v_a + sat_{a_max}(k_E (E_p - E_up) (M_ap v_p)),

the pumping term saturated at ``a_max`` (Astrom and Furuta's bound on the pump, ``n g`` in their paper: with a large
``k_E`` the pump is bang-bang, near the fastest energy gain the bound allows, while the PD keeps its share of the
input to bring the cart back; ``a_max = inf`` is the linear law).

For a driven base that carries the rest (a cart: ``M`` and ``V`` free of ``x``, and the passive rows' velocity terms
then free of ``v_a``) without friction, ``dE_p/dt = -(M_ap v_p) y``, so the (unsaturated) pumping term alone gives
``dE_p/dt = -k_E (E_p - E_up) (M_ap v_p)^2``, and saturated still ``dE_p/dt <= 0`` for ``E_p > E_up`` (and
``>= 0`` below): ``E_p`` goes to ``E_up`` from either side (Astrom and Furuta 2000's law,
written on the derived model). On other mechanisms it is a heuristic.

Near upright an LQR balances, ``u = -K x`` with ``x = (e, v)`` (``e = q - q_up``, angles wrapped) and ``K`` from
``control.lqr`` on the model's linearization about upright (central differences of its ``forward_dynamics``),
``Q = diag(10 I, I)``, ``R = lqr_r``; the switch is :class:`controllers.swingup.CatchingSwingUp`'s (the cost-to-go
``x^T S x`` below ``catch`` to take over, above ``release * catch`` to hand back), the mode kept in SB3's ``state``.
"""

from __future__ import annotations

from typing import Any

import control
import numpy as np

from mbs_envs import validation as check
from mbs_envs.envs.derived_swingup import DerivedSwingUpEnv

from .base import linearize
from .swingup import CatchingSwingUp, collocated_pfl
from .tuned import tuned_gains


def upright_error(q: np.ndarray, q_up: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``e = q - q_up`` with the angles wrapped to ``[-pi, pi)``, shape ``(..., n)``."""
    e = q - q_up
    return np.where(angle, (e + np.pi) % (2 * np.pi) - np.pi, e)


class EnergySwingUpLQR(CatchingSwingUp):
    """Energy-based swing-up through collocated partial feedback linearization, then LQR (module docstring).

    Parameters
    ----------
    env : gymnasium.Env
        A derived swing-up env (:class:`~mbs_envs.envs.derived_swingup.DerivedSwingUpEnv`) with one input.
    k_q, k_v : float, optional
        PD of the driven coordinate during swing-up [1/s^2, 1/s]; default the tuned ones.
    k_E : float, optional
        Pumping gain [1/(J kg s) for a cart]; default the tuned one.
    catch : float, optional
        The LQR takes over below this cost-to-go; default the tuned one.
    release : float
        Swing-up resumes above ``release * catch`` (> 1).
    lqr_r : float, optional
        The LQR's input weight [(N or N m)^-2]; default the tuned one (1 if none).
    a_max : float, optional
        Bound on the pumping term [m/s^2 or rad/s^2]; default the tuned one (none if absent: the linear law).
    """

    fits = (DerivedSwingUpEnv,)
    #: the entry of controllers/tuned.json
    tuned_name = "energy swing-up + LQR"

    def __init__(self, env: Any, k_q: Any = None, k_v: Any = None, k_E: Any = None, catch: Any = None, release: float = 4.0,
                 lqr_r: Any = None, a_max: Any = None):  # fmt: skip
        super().__init__(env)
        base = env.unwrapped
        base = getattr(base, "env", base)
        if self.model.nu != 1:
            raise ValueError(f"EnergySwingUpLQR drives one coordinate; this model has {self.model.nu} inputs")
        tuned = tuned_gains(env, self.tuned_name)
        self.k_q = check.nonnegative(tuned["k_q"] if k_q is None else k_q, "k_q")
        self.k_v = check.nonnegative(tuned["k_v"] if k_v is None else k_v, "k_v")
        self.k_E = check.nonnegative(tuned["k_E"] if k_E is None else k_E, "k_E")
        self.catch = check.positive(tuned["catch"] if catch is None else catch, "catch")
        self.release = check.real(release, "release", 1.0, np.inf, low_open=True)
        self.lqr_r = check.positive(tuned.get("lqr_r", 1.0) if lqr_r is None else lqr_r, "lqr_r")
        bound = tuned.get("a_max") if a_max is None else a_max
        self.a_max = np.inf if bound is None else check.positive(bound, "a_max")
        self.q_up, self.angle = np.array(base.upright, float), np.array(base.angle, bool)
        self.driven = int(base.actuated[0])
        self.E_up = float(self.model.potential_energy(self.q_up))
        n = self.model.nq
        self.Q = np.diag(np.r_[np.full(n, 10.0), np.ones(n)])
        A, B = linearize(lambda x, u: np.concatenate([x[..., n:], self.model.forward_dynamics(x[..., :n], x[..., n:], u)], axis=-1),
                         np.r_[self.q_up, np.zeros(n)], np.zeros(1))  # fmt: skip
        K, S, _ = control.lqr(A, B, self.Q, np.full((1, 1), self.lqr_r))
        self.K, self.S = np.asarray(K), np.asarray(S)

    def swing_up(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The swing-up input ``u`` [N or N m], shape ``(...)``."""
        a = self.driven
        p = np.arange(q.shape[-1]) != a
        M, h = self.model.mass_matrix(q), self.model.bias(q, v)
        v_p = v[..., p]
        E_p = 0.5 * np.einsum("...i,...ij,...j->...", v_p, M[..., p][..., p, :], v_p) + self.model.potential_energy(q)
        e_a = upright_error(q, self.q_up, self.angle)[..., a]
        pump = self.k_E * (E_p - self.E_up) * np.einsum("...i,...i->...", M[..., a, p], v_p)
        y = -self.k_q * e_a - self.k_v * v[..., a] + np.clip(pump, -self.a_max, self.a_max)
        return collocated_pfl(self.model, q, v, y, a, M, h)

    def upright_state(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``x = (e, v)``, ``e`` of :func:`upright_error`, shape ``(..., 2 n)``."""
        return np.concatenate([upright_error(q, self.q_up, self.angle), v], axis=-1)
