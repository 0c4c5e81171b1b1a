"""The joint-space tracking task shared by the fully actuated scenes.

The observation carries the state and the reference at the current time, so a
model-based controller acts from the observation alone:

    obs = [cos q, sin q, v, e, v_ref, a_ref],   e = wrap(q_ref - q) in [-pi, pi)

(each block of length ``n = nq``; ``q`` is recovered as ``atan2(sin, cos)`` and
``q_ref = q + e``, exact modulo 2 pi, which is all a revolute model needs).
The reward is

    r = -(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |action|^2)

with each term reported in ``info``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from ..references import SumOfSines, sample_sum_of_sines
from .base import MBSEnv


def wrap_angle(x: np.ndarray) -> np.ndarray:
    """Wrap angles to ``[-pi, pi)``."""
    return (np.asarray(x) + np.pi) % (2 * np.pi) - np.pi


@dataclasses.dataclass(frozen=True)
class TrackingObservation:
    """A decoded tracking observation; arrays of shape ``(..., n)``."""

    q: np.ndarray
    v: np.ndarray
    q_ref: np.ndarray
    v_ref: np.ndarray
    a_ref: np.ndarray


def encode_tracking(q, v, q_ref, v_ref, a_ref) -> np.ndarray:
    """Observation vector ``[cos q, sin q, v, wrap(q_ref - q), v_ref, a_ref]`` (float32)."""
    return np.concatenate(
        [np.cos(q), np.sin(q), v, wrap_angle(q_ref - q), v_ref, a_ref], axis=-1
    ).astype(np.float32)


def decode_tracking(obs: np.ndarray, n: int) -> TrackingObservation:
    """Invert :func:`encode_tracking` (batched over leading dimensions).

    Parameters
    ----------
    obs : ndarray, shape (..., 6 n)
    n : int

    Returns
    -------
    TrackingObservation
    """
    obs = np.asarray(obs, dtype=float)
    if obs.shape[-1] != 6 * n:
        raise ValueError(f"observation must have shape (..., {6 * n}), got {obs.shape}")
    c, s, v, e, v_ref, a_ref = (obs[..., k * n : (k + 1) * n] for k in range(6))
    q = np.arctan2(s, c)
    return TrackingObservation(q=q, v=v, q_ref=q + e, v_ref=v_ref, a_ref=a_ref)


class JointTrackingEnv(MBSEnv):
    """Track a random smooth joint reference (:class:`SumOfSines`) with every joint driven.

    Subclasses set the reference distribution (class attributes below) and
    the drawing; the model must be fully actuated (``nu == nv == nq``).

    Parameters
    ----------
    model, u_max, **kwargs
        See :class:`MBSEnv`.
    reward_weights : (float, float, float)
        ``(w_e, w_de, w_u)`` of the reward.
    start_noise : float
        Start state ``q0 = q_ref(0) + U(-s, s)``, ``v0 = v_ref(0) + U(-s, s)`` [rad, rad/s].
    """

    #: reference centre range per joint [rad], amplitude per joint [rad], frequencies [rad/s]
    center_low: ClassVar[np.ndarray]
    center_high: ClassVar[np.ndarray]
    max_amplitude: ClassVar[np.ndarray]
    omega_range: ClassVar[tuple[float, float]] = (0.5, 3.0)
    n_components: ClassVar[int] = 3

    def __init__(self, model, u_max, *, reward_weights=(1.0, 0.1, 1e-3), start_noise=0.1, **kwargs):
        super().__init__(model, u_max, **kwargs)
        if not (model.nq == model.nv == model.nu):
            raise ValueError("JointTrackingEnv needs a fully actuated model (nq == nv == nu)")
        w = np.asarray(reward_weights, float)
        if w.shape != (3,) or not np.all(np.isfinite(w) & (w >= 0)):
            raise ValueError(f"reward_weights must be 3 finite values >= 0, got {reward_weights!r}")
        if not (np.isfinite(start_noise) and start_noise >= 0):
            raise ValueError(f"start_noise must be finite and >= 0, got {start_noise!r}")
        self.reward_weights = w
        self.start_noise = float(start_noise)
        n = model.nq
        # |v| <= divergence_limit is guaranteed (a diverged step keeps the last
        # finite state); the reference's rates are bounded by sum A w and sum A w^2.
        w_max = self.omega_range[1]
        high = np.concatenate(
            [
                np.ones(2 * n),
                np.full(n, self.divergence_limit),
                np.full(n, np.pi),
                np.broadcast_to(self.max_amplitude * w_max, (n,)),
                np.broadcast_to(self.max_amplitude * w_max**2, (n,)),
            ]
        ).astype(np.float32)
        self.observation_space = gym.spaces.Box(-high, high, dtype=np.float32)
        self.reference: SumOfSines | None = None

    def _reset_task(self, options: dict) -> None:
        self.reference = sample_sum_of_sines(
            self.np_random,
            self.center_low,
            self.center_high,
            self.max_amplitude,
            self.omega_range,
            self.n_components,
        )

    def _initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        q_ref, v_ref, _ = self.reference(0.0)
        s, n = self.start_noise, self.model.nq
        return q_ref + self.np_random.uniform(-s, s, n), v_ref + self.np_random.uniform(-s, s, n)

    def _observation(self) -> np.ndarray:
        return encode_tracking(self._q, self._v, *self.reference(self._t))

    def decode_observation(self, obs: np.ndarray) -> TrackingObservation:
        """The state and reference in an observation (batched); see :func:`decode_tracking`."""
        return decode_tracking(obs, self.model.nq)

    def _errors(self) -> tuple[np.ndarray, np.ndarray]:
        q_ref, v_ref, _ = self.reference(self._t)
        return wrap_angle(q_ref - self._q), v_ref - self._v

    def _reward(self, u: np.ndarray, action: np.ndarray) -> tuple[float, dict[str, Any]]:
        e, de = self._errors()
        w_e, w_de, w_u = (float(w) for w in self.reward_weights)
        terms = {
            "reward_tracking": -w_e * float(e @ e),
            "reward_velocity": -w_de * float(de @ de),
            "reward_effort": -w_u * float(action @ action),
        }
        return sum(terms.values()), terms

    def _task_info(self) -> dict[str, Any]:
        e, _ = self._errors()
        return {"tracking_error": e, "q_ref": self.reference(self._t)[0]}
