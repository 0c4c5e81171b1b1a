"""A policy that decides every ``K`` control steps and holds its action in between.

The counterpart, at evaluation, of training with ``action_repeat = K``
(:class:`mbs_envs.envs.sb3.SB3VecEnv`): the agent saw the plant every ``K dt`` and
its action was applied for ``K`` steps, so it is run the same way on the unchanged
environment. Member ``i`` asks the wrapped policy at its steps ``0, K, 2K, ...``
(counted from its ``episode_start``) and repeats that action at the others. The
count and the held actions travel in ``predict``'s ``state``, as a recurrent
policy's would, so the wrapper holds nothing between calls and any rollout loop
that passes ``state`` back (``mbs_envs.studies.evaluation``, SB3's
``evaluate_policy``) runs it.
"""

from __future__ import annotations

from typing import Any

import numpy as np


class HeldPolicy:
    """``policy`` deciding every ``action_repeat`` calls (module docstring).

    Parameters
    ----------
    policy : object with ``predict(obs, state, episode_start, deterministic)``
    action_repeat : int
        ``K >= 1``; ``K = 1`` is ``policy`` itself.
    """

    def __init__(self, policy: Any, action_repeat: int):
        from ..envs.sb3 import check_action_repeat

        self.policy = policy
        self.action_repeat = check_action_repeat(action_repeat)

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        """The held action of each member, and the state to pass back (``(inner state, count, held)``).

        ``observation`` of shape ``(B, d)`` (or ``(d,)``: one member); ``episode_start``
        of shape ``(B,)`` (None: a new episode only at the first call, ``state=None``).
        """
        obs = np.asarray(observation)
        single = obs.ndim == 1
        n = 1 if single else obs.shape[0]
        inner, count, held = state if state is not None else (None, np.zeros(n, int), None)
        if episode_start is not None:
            count = np.where(np.asarray(episode_start, bool).reshape(n), 0, count)
        decide = count % self.action_repeat == 0
        if held is None or decide.any():
            fresh, inner = self.policy.predict(
                observation, state=inner, episode_start=episode_start, deterministic=deterministic
            )
            rows = np.asarray(fresh).reshape(n, -1)
            held = rows.copy() if held is None else np.where(decide[:, None], rows, held)
        action = held[0].copy() if single else held.copy()
        return action, (inner, count + 1, held)
