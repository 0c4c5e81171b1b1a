"""The joint-space tracking task shared by the fully actuated scenes.

The observation carries the state and the reference at the current time, so a
model-based controller acts from the observation alone:

    obs = [cos q, sin q, v, e, v_ref, a_ref],   e = wrap(q_ref - q[tracked]) in [-pi, pi)

(``q, v`` of length ``n = nq``, the reference blocks of length ``m`` = the
number of tracked coordinates: all of them for serial scenes, the crank for the
four-bar; ``q`` is recovered as ``atan2(sin, cos)`` and ``q_ref = q[tracked] + e``,
exact modulo 2 pi, which is all a revolute model needs). The reward is

    r = -(w_e |e|^2 + w_de |v_ref - v[tracked]|^2 + w_u |action|^2)

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
    """A decoded tracking observation.

    ``q, v`` have shape ``(..., n)`` (the whole state); ``q_ref, v_ref, a_ref``
    shape ``(..., m)``, the reference of the coordinates ``tracked``.
    """

    q: np.ndarray
    v: np.ndarray
    q_ref: np.ndarray
    v_ref: np.ndarray
    a_ref: np.ndarray
    tracked: tuple[int, ...]


def encode_tracking(q, v, q_ref, v_ref, a_ref, tracked: tuple[int, ...]) -> np.ndarray:
    """Observation ``[cos q, sin q, v, wrap(q_ref - q[tracked]), v_ref, a_ref]`` (float32)."""
    e = wrap_angle(q_ref - np.asarray(q)[..., list(tracked)])
    return np.concatenate([np.cos(q), np.sin(q), v, e, v_ref, a_ref], axis=-1).astype(np.float32)


def decode_tracking(obs: np.ndarray, n: int, tracked: tuple[int, ...] | None = None) -> TrackingObservation:
    """Invert :func:`encode_tracking` (batched over leading dimensions).

    Parameters
    ----------
    obs : ndarray, shape (..., 3 n + 3 m)
    n : int
        Number of coordinates.
    tracked : tuple of int, optional
        Tracked coordinates (default all ``n``).

    Returns
    -------
    TrackingObservation
    """
    tracked = tuple(range(n)) if tracked is None else tuple(tracked)
    m = len(tracked)
    obs = np.asarray(obs, dtype=float)
    if obs.shape[-1] != 3 * (n + m):
        raise ValueError(f"observation must have shape (..., {3 * (n + m)}), got {obs.shape}")
    c, s, v = (obs[..., k * n : (k + 1) * n] for k in range(3))
    e, v_ref, a_ref = (obs[..., 3 * n + k * m : 3 * n + (k + 1) * m] for k in range(3))
    q = np.arctan2(s, c)
    return TrackingObservation(q=q, v=v, q_ref=q[..., list(tracked)] + e, v_ref=v_ref, a_ref=a_ref, tracked=tracked)


class JointTrackingEnv(MBSEnv):
    """Track a random smooth reference (:class:`SumOfSines`) of the ``tracked`` coordinates.

    Subclasses set the reference distribution (class attributes below) and
    the drawing. Serial scenes track every joint (``tracked`` = all, fully
    actuated); a constrained scene tracks its independent coordinates and
    overrides :meth:`_state_from_tracked` to complete a consistent state.

    Parameters
    ----------
    model, u_max, **kwargs
        See :class:`MBSEnv`.
    reward_weights : (float, float, float)
        ``(w_e, w_de, w_u)`` of the reward.
    start_noise : float
        Start state ``q0 = q_ref(0) + U(-s, s)``, ``v0 = v_ref(0) + U(-s, s)`` [rad, rad/s].
    """

    #: reference centre range per tracked coordinate [rad], amplitude [rad],
    #: frequencies [rad/s], mean rate range [rad/s] (None: no drift)
    center_low: ClassVar[np.ndarray]
    center_high: ClassVar[np.ndarray]
    max_amplitude: ClassVar[np.ndarray]
    omega_range: ClassVar[tuple[float, float]] = (0.5, 3.0)
    rate_range: ClassVar[tuple[float, float] | None] = None
    n_components: ClassVar[int] = 3
    #: default (kp, kd) of a PD controller on this task [N m/rad, N m s/rad]
    pd_gains: tuple[float, float] = (100.0, 20.0)

    def __init__(self, model, u_max, *, reward_weights=(1.0, 0.1, 1e-3), start_noise=0.1, **kwargs):
        super().__init__(model, u_max, **kwargs)
        self.tracked = tuple(getattr(model, "independent", range(model.nq)))
        if len(self.tracked) != model.nu:
            raise ValueError("JointTrackingEnv needs one input per tracked coordinate")
        w = np.asarray(reward_weights, float)
        if w.shape != (3,) or not np.all(np.isfinite(w) & (w >= 0)):
            raise ValueError(f"reward_weights must be 3 finite values >= 0, got {reward_weights!r}")
        if not (np.isfinite(start_noise) and start_noise >= 0):
            raise ValueError(f"start_noise must be finite and >= 0, got {start_noise!r}")
        self.reward_weights = w
        self.start_noise = float(start_noise)
        n, m = model.nq, len(self.tracked)
        # |v| <= divergence_limit is guaranteed (a diverged step keeps the last
        # finite state); the reference's rates are bounded by |s| + sum A w and sum A w^2.
        w_max = self.omega_range[1]
        s_max = 0.0 if self.rate_range is None else np.max(np.abs(self.rate_range))
        high = np.concatenate(
            [
                np.ones(2 * n),
                np.full(n, self.divergence_limit),
                np.full(m, np.pi),
                np.broadcast_to(s_max + self.max_amplitude * w_max, (m,)),
                np.broadcast_to(self.max_amplitude * w_max**2, (m,)),
            ]
        ).astype(np.float32)
        self.observation_space = gym.spaces.Box(-high, high, dtype=np.float32)
    @property
    def reference(self) -> SumOfSines | None:
        """The episode's reference (None before the first reset)."""
        return self._task

    def reference_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q_ref, v_ref, a_ref)`` at the current time."""
        return self.now()

    # -- the task, batched (see MBSEnv) ------------------------------------------

    def _reset_task(self, options: dict) -> SumOfSines:
        return sample_sum_of_sines(
            self.np_random,
            self.center_low,
            self.center_high,
            self.max_amplitude,
            self.omega_range,
            self.n_components,
            self.rate_range,
        )

    def _initial_state(self, task: SumOfSines) -> tuple[np.ndarray, np.ndarray]:
        q_ref, v_ref, _ = task(0.0)
        s, m = self.start_noise, len(self.tracked)
        q_t = q_ref + self.np_random.uniform(-s, s, m)
        v_t = v_ref + self.np_random.uniform(-s, s, m)
        return self._state_from_tracked(q_t, v_t)

    def _state_from_tracked(self, q_t: np.ndarray, v_t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Whole state from the tracked coordinates (identity when all are tracked)."""
        return q_t, v_t

    def task_now(self, t: np.ndarray, task: SumOfSines) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q_ref, v_ref, a_ref)`` at ``t``, each shape ``(..., m)``."""
        return task(t)

    def observe(self, q, v, now, task) -> np.ndarray:
        return encode_tracking(q, v, *now, self.tracked)

    def decode_observation(self, obs: np.ndarray) -> TrackingObservation:
        """The state and reference in an observation (batched); see :func:`decode_tracking`."""
        return decode_tracking(obs, self.model.nq, self.tracked)

    def errors(self, q: np.ndarray, v: np.ndarray, now) -> tuple[np.ndarray, np.ndarray]:
        """``(wrap(q_ref - q), v_ref - v)`` on the tracked coordinates, shape ``(..., m)``."""
        q_ref, v_ref, _ = now
        idx = list(self.tracked)
        return wrap_angle(q_ref - q[..., idx]), v_ref - v[..., idx]

    def reward(self, q, v, now, task, u, action) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        e, de = self.errors(q, v, now)
        w_e, w_de, w_u = (float(w) for w in self.reward_weights)
        terms = {
            "reward_tracking": -w_e * np.sum(e * e, axis=-1),
            "reward_velocity": -w_de * np.sum(de * de, axis=-1),
            "reward_effort": -w_u * np.sum(action * action, axis=-1),
        }
        return terms["reward_tracking"] + terms["reward_velocity"] + terms["reward_effort"], terms

    def task_info(self, q, v, now, task, u) -> dict[str, Any]:
        e, _ = self.errors(q, v, now)
        return {"tracking_error": e, "q_ref": now[0]}
