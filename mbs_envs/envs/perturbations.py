"""The perturbations of a closed loop, as arithmetic on batches: the actuator's response and torque noise
(:func:`actuated`), an observation delay (:func:`delayed`), measurement noise (:func:`with_noise`) and torque pulses
(:func:`gaussian_pulses`, :func:`random_pulses`); and the DFKI benchmark's robustness-v2 ranges of them.

One module for the robustness sweeps (:mod:`mbs_envs.studies.robustness`, :mod:`mbs_envs.studies.dfki`) and the
training under perturbations (:class:`mbs_envs.envs.perturbed.PerturbedVectorEnv`): a perturbation means the same
arithmetic wherever it is applied.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Any

import numpy as np

# -- the DFKI benchmark's robustness-v2 ranges ------------------------------------------------------------------

#: ranges: velocity-noise std [rad/s], torque-noise std [N m], responsiveness, delay [s]
RANGES = MappingProxyType({"velocity noise": (0.0, 0.5), "torque noise": (0.0, 1.1), "torque response": (0.1, 2.0),
                           "time delay": (0.0, 0.04)})  # fmt: skip
#: the observation entries the velocity noise reaches: the joint rates of the swing-up envs' (cos, sin, cos, sin, v1, v2)
RATE_INDEX = (4, 5)
#: perturbations: episodes, pulses per joint, least spacing [s], width and height ranges [s], [N m]
PULSES = MappingProxyType(
    {"episodes": 50, "per_joint": 3, "min_spacing": 1.0, "sigma": (0.05, 0.1), "amplitude": (0.5, 5.0)}
)


# -- the arithmetic -------------------------------------------------------------------------------------------


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


def random_pulses(rng: np.random.Generator, episodes: int, t: np.ndarray, coordinates: int, per_coordinate: int, gap: float,
                  sigma: tuple[float, float], amplitude: tuple[Any, Any]) -> np.ndarray:  # fmt: skip
    """The DFKI benchmark's random disturbance (``get_random_gauss_perturbation_array``), for any number of coordinates.

    Per episode ``c k`` Gaussian torque pulses, ``k = per_coordinate`` on each of ``c = coordinates``: their
    centres ``gap`` apart at least (cumulative sums of ``gap + U(0, room)``, ``room = (T - (c k + 1) gap) / (c k)``),
    in shuffled order; widths ``U(sigma)``; heights of random sign with ``|A| ~ U(amplitude)``.

    Parameters
    ----------
    rng : numpy Generator
    episodes : int
    t : ndarray (steps,)
        Control times [s], evenly spaced from 0.
    coordinates, per_coordinate : int
    gap : float
        Least spacing of the centres [s].
    sigma : (float, float)
        Width range [s].
    amplitude : (array_like, array_like)
        Height range [N m or N], scalars or one per coordinate, shape (c,).

    Returns
    -------
    ndarray (episodes, steps, c)
    """
    T = float(t[-1] + (t[1] - t[0]))
    n = coordinates * per_coordinate
    room = (T - (n + 1) * gap) / n
    if room < 0:
        raise ValueError(f"gap: {n} pulses {gap} s apart do not fit in {T} s")
    mu = np.cumsum(gap + rng.uniform(0, room, (episodes, n)), axis=1)
    mu = rng.permuted(mu, axis=1).reshape(episodes, coordinates, per_coordinate)
    width = rng.uniform(sigma[0], sigma[1], (episodes, coordinates, per_coordinate))
    lo, hi = (np.broadcast_to(np.asarray(a, float), (coordinates,))[:, None] for a in amplitude)
    amp = rng.uniform(-(hi - lo), hi - lo, (episodes, coordinates, per_coordinate))
    amp += lo * np.sign(amp)
    return gaussian_pulses(t, mu, width, amp)


def actuated(
    u: np.ndarray,
    applied: np.ndarray,
    u_max: np.ndarray,
    noise: np.ndarray | None = None,
    response: np.ndarray | None = None,
) -> np.ndarray:
    """The torque the plant gets for the command ``u``: the torque noise added, then the first-order actuator
    ``applied + r (u - applied)`` (responsiveness ``r = response``), then the actuator limit.

    Parameters
    ----------
    u : ndarray (n, nu)
        Commanded torques [N m].
    applied : ndarray (n, nu)
        The torques applied at the step before [N m] (zeros at an episode's start).
    u_max : ndarray (nu,)
        Actuator limit [N m].
    noise : ndarray (n, nu), optional
        Additive torque noise [N m] (None: none).
    response : ndarray (n,), optional
        Responsiveness per member (None: ideal, ``r = 1``).

    Returns
    -------
    ndarray (n, nu)
    """
    if noise is not None:
        u = u + noise
    if response is not None:
        u = applied + response[:, None] * (u - applied)
    return np.clip(u, -u_max, u_max)


def delayed(history: np.ndarray, k: Any, delay: np.ndarray) -> np.ndarray:
    """What each member sees at its control step ``k`` with its delay: the observation of step ``k - delay`` from the
    ring ``history`` (the observation of step ``j`` in row ``j % len(history)``), the episode's first one until then.

    Parameters
    ----------
    history : ndarray (L, n, obs_dim)
        The ring, ``L > max(delay)``.
    k : int or ndarray of int (n,)
        Each member's step in its episode.
    delay : ndarray of int (n,)
        Delay [control steps].

    Returns
    -------
    ndarray (n, obs_dim)
    """
    return history[np.maximum(k - delay, 0) % len(history), np.arange(history.shape[1])]


def with_noise(seen: np.ndarray, index: Any, noise: np.ndarray) -> np.ndarray:
    """``seen`` (n, obs_dim) with ``noise`` (n, len(index)) added to the entries ``index`` (a list, or a slice for
    all), in ``seen``'s dtype (a new array)."""
    noisy = seen.copy()
    noisy[:, index] = seen[:, index] + noise  # cast into seen's dtype by the assignment
    return noisy
