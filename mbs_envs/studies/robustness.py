"""Robustness sweeps: one batched run per axis, each member one value of the axis.

A sweep perturbs the closed loop along six axes, as the DFKI benchmark's robustness v2 does
(:mod:`mbs_envs.studies.dfki` gives its ranges; ``scripts/robustness.py`` gives ranges for every
scene). Every axis is one :class:`Perturbation` batch on a vector env whose members hold the axis's
values, so a whole axis is one rollout:

- **model**: each member its own plant parameters (the vector env's ``member_params``);
- **measurement noise**: Gaussian noise of std ``sigma`` on the observation entries ``noise_index``
  (e.g. the velocities), drawn afresh at every control step;
- **torque noise**: Gaussian noise of std ``sigma`` [N m] added to the commanded torque, then the
  actuator limit;
- **torque response**: a first-order actuator, ``u_k = u_{k-1} + r (u_cmd,k - u_{k-1})`` with
  responsiveness ``r`` (1: ideal; below: a lag; above: overshoot), from ``u_{-1} = 0``;
- **time delay**: the controller sees the observation of ``d`` control steps earlier (the first
  observation until then);
- **perturbations**: torque pulses ``tau(t)`` on every joint, applied at each step as the impulse
  ``tau(t_k) dt`` (:meth:`~mbs_envs.envs.vector.MBSVectorEnv.apply_impulse`: first-order operator
  splitting; the pulses are 25 steps wide or more at the protocol's rate).

The rollout records every member's final state and whether it ended early; the caller's success
rule judges them. Actions go through the env as the agent's normalized actions (``u / u_max``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


@dataclasses.dataclass(frozen=True)
class Perturbation:
    """Per-member settings of one batched rollout (every array has one entry per member; None: unperturbed).

    Attributes
    ----------
    noise_sigma : ndarray (n,), optional
        Std of the measurement noise on the observation entries ``noise_index``.
    noise_index : tuple of int
        Observation entries the noise reaches (empty: all).
    torque_sigma : ndarray (n,), optional
        Std of the torque noise [N m].
    response : ndarray (n,), optional
        Actuator responsiveness ``r`` (module docstring).
    delay : ndarray of int (n,), optional
        Observation delay in control steps.
    pulses : ndarray (n, steps, nv), optional
        Disturbance torque of every joint at every control step [N m].
    """

    noise_sigma: np.ndarray | None = None
    noise_index: tuple[int, ...] = ()
    torque_sigma: np.ndarray | None = None
    response: np.ndarray | None = None
    delay: np.ndarray | None = None
    pulses: np.ndarray | None = None


def gaussian_pulses(t: np.ndarray, mu: np.ndarray, sigma: np.ndarray, amplitude: np.ndarray) -> np.ndarray:
    """Sums of Gaussian pulses ``A exp(-(t - mu)^2 / (2 sigma^2))`` per joint.

    Parameters
    ----------
    t : ndarray (steps,)
        Times [s].
    mu, sigma, amplitude : ndarray (n, nv, k)
        Centre [s], width [s] and height [N m] of ``k`` pulses per joint and member.

    Returns
    -------
    ndarray (n, steps, nv)
    """
    z = (t[None, :, None, None] - mu[:, None]) / sigma[:, None]
    return (amplitude[:, None] * np.exp(-0.5 * z**2)).sum(-1)


def run(venv: Any, policy: Any, seeds: list[int], p: Perturbation, noise_seed: int = 0, deterministic: bool = True) -> dict[str, np.ndarray]:
    """One perturbed episode per member of ``venv`` (``autoreset_mode="Disabled"``, a ``max_episode_steps``).

    Returns
    -------
    dict
        ``q`` (n, nq) and ``v`` (n, nv): each member's state when its episode ended; ``terminated`` (n,):
        it ended early (diverged); ``steps`` (n,): the control steps it ran.
    """
    base = venv.unwrapped
    n, steps = len(seeds), base.max_episode_steps
    if base.num_envs != n or steps is None:
        raise ValueError(f"venv needs {n} members and a max_episode_steps, has {base.num_envs} and {steps}")
    u_max = np.asarray(base.env.u_max, float)
    rng = np.random.default_rng(noise_seed)
    obs, _ = base.reset(seed=list(seeds))
    delay = np.zeros(n, int) if p.delay is None else np.asarray(p.delay, int)
    history = np.empty((int(delay.max()) + 1,) + obs.shape, obs.dtype)  # a ring of the last observations
    members = np.arange(n)
    applied = np.zeros((n, base.model.nu))
    q_end, v_end = base.q, base.v
    ran = np.full(n, steps)
    done = np.zeros(n, bool)
    terminated_any = np.zeros(n, bool)
    state, start = None, np.ones(n, bool)
    dt = float(base.env.dt)
    for k in range(steps):
        history[k % len(history)] = obs
        seen = history[np.maximum(k - delay, 0) % len(history), members] if delay.any() else obs
        if p.noise_sigma is not None:
            idx = list(p.noise_index) or slice(None)
            noisy = seen.copy()
            noisy[:, idx] = seen[:, idx] + (np.asarray(p.noise_sigma)[:, None] * rng.standard_normal((n, noisy[:, idx].shape[1])))
            seen = noisy.astype(obs.dtype)
        action, state = policy.predict(seen, state=state, episode_start=start, deterministic=deterministic)
        start = np.zeros(n, bool)
        u = np.clip(np.asarray(action, float).reshape(n, -1), -1.0, 1.0) * u_max
        if p.torque_sigma is not None:
            u = u + np.asarray(p.torque_sigma)[:, None] * rng.standard_normal(u.shape)
        if p.response is not None:
            u = applied + np.asarray(p.response)[:, None] * (u - applied)
        applied = np.clip(u, -u_max, u_max)
        if p.pulses is not None:
            base.apply_impulse(np.where(done[:, None], 0.0, p.pulses[:, k] * dt))
        obs, _, terminated, truncated, _ = base.step((applied / u_max).astype(np.float32))
        newly = ~done & (terminated | truncated)
        q_now, v_now = base.q, base.v
        q_end[newly], v_end[newly] = q_now[newly], v_now[newly]
        ran[newly] = k + 1
        terminated_any |= newly & terminated
        done |= newly
        if done.all():
            break
    return {"q": q_end, "v": v_end, "terminated": terminated_any, "steps": ran}
