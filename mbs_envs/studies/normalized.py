"""A policy that sees observations normalized as it saw them in training.

The counterpart, at evaluation, of training behind SB3's ``VecNormalize``
(:attr:`mbs_envs.studies.training.TrainConfig.normalize`): the agent learned on
``clip((obs - mean) / sqrt(var + eps), -c, c)`` with the running mean and variance of
the training observations, so it is run on the unchanged environment through the same
map with the statistics frozen at the end of training (saved beside the agent as
``normalization.npz``: plain arrays, no pickle). Reward normalization only scales the
learning signal and needs nothing at evaluation.
"""

from __future__ import annotations

import dataclasses
import pathlib
from typing import Any

import numpy as np

#: the file a normalized agent's statistics are saved to, beside ``agent.zip``
FILE = "normalization.npz"


@dataclasses.dataclass(frozen=True)
class ObsNormalization:
    """``clip((obs - mean) / sqrt(var + eps), -clip, clip)``, as SB3's ``VecNormalize.normalize_obs``.

    Attributes
    ----------
    mean, var : ndarray, shape (obs_dim,)
    clip : float
    eps : float
    """

    mean: np.ndarray
    var: np.ndarray
    clip: float
    eps: float

    @classmethod
    def of(cls, vec_normalize: Any) -> "ObsNormalization":
        """The current statistics of a ``VecNormalize`` (copied: later training leaves them alone)."""
        rms = vec_normalize.obs_rms
        return cls(
            np.array(rms.mean, float),
            np.array(rms.var, float),
            float(vec_normalize.clip_obs),
            float(vec_normalize.epsilon),
        )

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """The normalized observation, float32, the shape of ``obs``."""
        z = (np.asarray(obs, float) - self.mean) / np.sqrt(self.var + self.eps)
        return np.clip(z, -self.clip, self.clip).astype(np.float32)

    def save(self, folder: pathlib.Path) -> None:
        np.savez(pathlib.Path(folder) / FILE, mean=self.mean, var=self.var, clip=self.clip, eps=self.eps)

    @classmethod
    def load(cls, folder: pathlib.Path) -> "ObsNormalization":
        with np.load(pathlib.Path(folder) / FILE) as z:
            return cls(z["mean"], z["var"], float(z["clip"]), float(z["eps"]))


class NormalizedPolicy:
    """``policy`` acting on normalized observations (module docstring); ``predict`` as SB3's.

    Parameters
    ----------
    policy : object with ``predict(obs, state, episode_start, deterministic)``
    normalize : callable ``obs -> normalized obs``
        An :class:`ObsNormalization`, or a live ``VecNormalize.normalize_obs`` while training.
    """

    def __init__(self, policy: Any, normalize: Any):
        self.policy = policy
        self.normalize = normalize

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self.policy.predict(
            self.normalize(observation), state=state, episode_start=episode_start, deterministic=deterministic
        )
