"""Residual RL: a model-based controller plus a learned, bounded correction.

The action applied to the plant is

    a = clip(a_base(obs) + beta * clip(a_rl(obs), -1, 1), -1, 1)

where ``a_base`` is a model-based controller's normalized action (computed
torque on the tracking scenes, LQR on the disk), ``a_rl`` the output of an SB3
policy in ``[-1, 1]`` and ``beta`` (``bound``) the largest correction, as a
fraction of the actuator limit. With ``a_rl = 0`` the policy is the base
controller exactly; the correction can never move the action by more than
``beta``.

- :class:`ResidualPolicy` is the evaluated policy (SB3's ``predict`` protocol,
  batched, carrying the base controller's internal state).
- :func:`residual_vec_env` wraps a training ``VecEnv`` so that an SB3 agent's
  actions are the corrections (requires the ``rl`` extra).
"""

from __future__ import annotations

from typing import Any

import numpy as np


def check_bound(bound: Any) -> float:
    """The correction bound as a float in ``(0, 2]``; ``ValueError`` otherwise."""
    try:
        beta = float(bound)
    except (TypeError, ValueError):
        raise ValueError(f"residual bound must be a number in (0, 2], got {bound!r}") from None
    if not (np.isfinite(beta) and 0 < beta <= 2):
        raise ValueError(f"residual bound must be a number in (0, 2], got {bound!r}")
    return beta


def combine(a_base: np.ndarray, a_rl: np.ndarray, bound: float) -> np.ndarray:
    """``clip(a_base + bound * clip(a_rl, -1, 1), -1, 1)`` as float32 (module docstring)."""
    a = np.asarray(a_base, float) + bound * np.clip(np.asarray(a_rl, float), -1.0, 1.0)
    return np.clip(a, -1.0, 1.0).astype(np.float32)


class ResidualPolicy:
    """``predict`` of a base controller plus a bounded learned correction.

    Parameters
    ----------
    base : object with ``predict``
        The model-based controller (its ``state`` is carried through).
    correction : object with ``predict``
        The learned policy (an SB3 model); its actions are read as ``a_rl``.
    bound : float
        ``beta`` of the module docstring, in ``(0, 2]``.
    """

    def __init__(self, base: Any, correction: Any, bound: float):
        self.base = base
        self.correction = correction
        self.bound = check_bound(bound)

    def predict(
        self, observation: np.ndarray, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ):
        a_base, state = self.base.predict(observation, state=state, episode_start=episode_start, deterministic=True)
        a_rl, _ = self.correction.predict(observation, deterministic=deterministic)
        return combine(a_base, a_rl, self.bound), state


def residual_vec_env(venv: Any, base: Any, bound: float) -> Any:
    """An SB3 ``VecEnv`` whose actions are corrections to ``base``'s actions (module docstring).

    The base controller sees each member's current observation and keeps its
    state per member, restarted where an episode ends (SB3 resets members
    within the step, so the observation after a done is the new episode's first).
    """
    from stable_baselines3.common.vec_env import VecEnvWrapper

    beta = check_bound(bound)

    class ResidualVecEnv(VecEnvWrapper):
        def __init__(self) -> None:
            super().__init__(venv)
            self._obs: np.ndarray | None = None
            self._state: Any = None
            self._start = np.ones(venv.num_envs, dtype=bool)

        def reset(self) -> np.ndarray:
            self._obs = self.venv.reset()
            self._state = None
            self._start = np.ones(self.num_envs, dtype=bool)
            return self._obs

        def step_async(self, actions: np.ndarray) -> None:
            a_base, self._state = base.predict(
                self._obs, state=self._state, episode_start=self._start, deterministic=True
            )
            self.venv.step_async(combine(a_base, actions, beta))

        def step_wait(self):
            obs, reward, dones, infos = self.venv.step_wait()
            self._obs = obs
            self._start = np.asarray(dones, dtype=bool).copy()
            return obs, reward, dones, infos

    return ResidualVecEnv()
