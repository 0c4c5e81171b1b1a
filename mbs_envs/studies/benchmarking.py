"""Timing helpers shared by the benchmark scripts (not used by tests: machines are noisy).

Every figure is a median over repeats, and scripts print ratios against a peer
timed in the same process and run.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..models import SerialChain


def median_time(f: Callable[[], Any], repeats: int = 7, min_time: float = 0.02) -> float:
    """Median seconds per call of ``f`` over ``repeats`` timed loops of at least ``min_time`` s."""
    f()  # warm-up (numba compilation, caches)
    n = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(n):
            f()
        if time.perf_counter() - t0 >= min_time:
            break
        n *= 2
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            f()
        times.append((time.perf_counter() - t0) / n)
    return float(np.median(times))


def time_steps(env: Any, actions: list, reset_every: int) -> float:
    """Mean wall time of one ``env.step`` over ``actions`` [s] (resets not timed).

    A single env is reset at episode ends and every ``reset_every`` steps; a
    vector env resets its members itself (autoreset).
    """
    single = not hasattr(env, "num_envs")
    env.reset(seed=0)
    total = 0.0
    for k, a in enumerate(actions):
        tic = time.perf_counter()
        _, _, term, trunc, _ = env.step(a)
        total += time.perf_counter() - tic
        if single and (term or trunc or (k + 1) % reset_every == 0):
            env.reset()
    return total / len(actions)


def _pinocchio_serial(joint: Callable[[Any, int], Any], offset: np.ndarray, m: np.ndarray, com: np.ndarray, inertia: np.ndarray,
                      g_vec: Any, armature: np.ndarray):  # fmt: skip
    """A serial chain as a Pinocchio model: joint ``i`` is ``joint(pin, i)``, placed at ``offset[i]`` in its
    parent's frame, carrying mass ``m[i]`` at ``com[i]`` with ``inertia[i]`` about it; or None without ``pin``.

    Returns
    -------
    (pinocchio module, model, data) or None
    """
    try:
        import pinocchio as pin
    except ImportError:
        return None
    model = pin.Model()
    parent = 0
    for i in range(len(m)):
        parent = model.addJoint(
            parent, joint(pin, i), pin.SE3(np.eye(3), np.asarray(offset[i], float)), f"joint{i + 1}"
        )
        model.appendBodyToJoint(
            parent, pin.Inertia(m[i], np.asarray(com[i], float), np.asarray(inertia[i], float)), pin.SE3.Identity()
        )
    model.gravity.linear[:] = g_vec
    model.armature[:] = armature
    return pin, model, model.createData()


def pinocchio_spatial_chain(chain: Any):
    """The same :class:`~mbs_envs.models.spatial_chain.SpatialChain` as a Pinocchio model
    (``JointModelRevoluteUnaligned`` about each axis, the same placements, inertias, gravity and
    armature), or None without ``pin`` (:func:`_pinocchio_serial`)."""
    p = chain.params
    return _pinocchio_serial(
        lambda pin, i: pin.JointModelRevoluteUnaligned(p.axis[i]), p.offset, p.m, p.com, p.inertia, p.g_vec, p.armature
    )


def pinocchio_chain(chain: SerialChain):
    """The same planar chain as a Pinocchio model (revolute-z joints), or None without ``pin`` (:func:`_pinocchio_serial`)."""
    p = chain.params
    n = chain.n_links
    offset = np.zeros((n, 3))
    offset[1:, 0] = p.l[:-1]
    com = np.zeros((n, 3))
    com[:, 0] = p.r
    return _pinocchio_serial(
        lambda pin, i: pin.JointModelRZ(),
        offset,
        p.m,
        com,
        [np.diag([I] * 3) for I in p.I],
        [0.0, -p.g, 0.0],
        p.armature,
    )
