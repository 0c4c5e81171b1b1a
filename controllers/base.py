"""The controller protocol: SB3's ``PolicyPredictor``."""

from __future__ import annotations

import abc
from typing import Any

import gymnasium as gym
import numpy as np

from mbs_envs import validation as check


def gain(value: Any, n: int, name: str) -> np.ndarray:
    """A non-negative finite gain, scalar or per coordinate, as shape ``(n,)``.

    Raises
    ------
    ValueError
        Naming the gain, if it is negative, non-finite or of the wrong length.
    """
    return check.vector(value, name, n, 0.0)


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


class Controller(abc.ABC):
    """A model-based policy: observation -> normalized action.

    Implements ``predict(observation, state=None, episode_start=None,
    deterministic=True) -> (action, state)`` (SB3's ``PolicyPredictor``),
    batched: an observation of shape ``(n_envs, obs_dim)`` gives actions of
    shape ``(n_envs, nu)``. Subclasses compute actuator inputs ``u`` [N m] in
    :meth:`input`; the conversion to the env's ``[-1, 1]`` scale (with
    saturation) happens here once.

    Parameters
    ----------
    env : gymnasium.Env
        The environment (wrapped or not) the controller will act on; its
        ``unwrapped`` must expose ``model``, ``u_max`` and ``decode_observation``.
    """

    #: the environment classes this controller can act on (its observation decoding and model use)
    fits: tuple[type, ...] = ()

    def __init__(self, env: Any):
        base = env.unwrapped if isinstance(env, (gym.Env, gym.vector.VectorEnv)) else None
        base = getattr(base, "env", base) if isinstance(base, gym.vector.VectorEnv) else base
        if base is None or not isinstance(base, self.fits):
            kinds = ", ".join(c.__name__ for c in self.fits)
            raise ValueError(f"{type(self).__name__} acts on {kinds} environments, got {type(getattr(env, 'unwrapped', env)).__name__}")
        self.model = base.model
        self.u_max = np.asarray(base.u_max, float)
        self.decode_observation = base.decode_observation
        space = base.observation_space
        self._obs_low, self._obs_high = np.asarray(space.low, float), np.asarray(space.high, float)

    @abc.abstractmethod
    def input(self, obs: Any) -> np.ndarray:
        """Actuator inputs ``u`` [N m], shape ``(..., nu)``, from a decoded observation."""

    def control(self, obs: Any, state: Any, episode_start: Any) -> tuple[np.ndarray, Any]:
        """Inputs ``u`` and the controller's next internal state.

        Stateless controllers (the default) pass ``state`` through; controllers
        with memory (integral action) override this and keep it in SB3's
        ``state``, reset where ``episode_start`` is true, so ``evaluate_policy``
        and batched rollouts carry it as they carry a recurrent policy's.
        """
        return self.input(obs), state

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action for an observation (or a batch), and the controller's state (see :meth:`control`).

        The observation must be real numbers and finite (``ValueError`` naming the members that are
        not: a NaN observation has no action). Where a finite observation far beyond the env's observation
        space overflows the computation (the disk LQR's feedforward at 1e30), the input is computed again from
        the observation clipped into the space (the env never observes beyond it): every finite observation
        gives a finite action, and every other one the same action as before."""
        obs = check.reals(observation, "observation")
        finite = np.isfinite(obs)
        if not finite.all():
            where = "" if obs.ndim < 2 else f" (members {np.flatnonzero(~finite.reshape(-1, obs.shape[-1]).all(axis=-1)).tolist()})"
            raise ValueError(f"observation must be finite{where}")
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is caught below, from the result
            u, new_state = self.control(self.decode_observation(obs), state, episode_start)
        if not np.all(np.isfinite(u)) and obs.shape[-1:] == self._obs_low.shape:  # overflow from a finite observation
            u, new_state = self.control(self.decode_observation(np.clip(obs, self._obs_low, self._obs_high)), state, episode_start)
        state = new_state
        action = np.clip(u / self.u_max, -1.0, 1.0).astype(np.float32)
        return action, state

    def __repr__(self) -> str:
        return f"{type(self).__name__}(model={self.model!r})"
