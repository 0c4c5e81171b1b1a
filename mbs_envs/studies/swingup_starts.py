"""Training starts along a model-based swing-up: a reverse curriculum for the pure RL agents of the swing-up scenes.

A pure RL agent on a swing-up scene must find, by exploration alone, a swing-up that ends where the upright can be
held, and only then does the critic see what holding it is worth. Starting a share of the training episodes from
states a model-based swing-up passes through (the env's ``start_states``) shows the critic the values along a
swing-up that succeeds before the policy has found one; the policy itself has no model in it, and validation and
evaluation start hanging as the task does.

The states are those of the scene's best model-based swing-up from hanging at rest, up to its hand-over:

- on the DFKI protocol's plant, the score-designed swing-up's plan (:func:`mbs_envs.studies.dfki_swingup.plan_starts`);
- on our own arms (``Acrobot-*``, ``Pendubot-*``), an episode of ``identified iLQR + TVLQR``
  (:class:`mbs_envs.controllers.PlannedSwingUp`) from hanging at rest, its states up to the first within the success
  tolerance (:func:`controller_states`).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from ..envs import registry
from ..envs.swingup import Q_DOWN
from ..envs.tracking import wrap_angle
from .evaluation import default_gains_entry, make_controller

#: the model-based swing-up whose states seed the curriculum on our own arms (the best of the comparison's)
CONTROLLER = "identified iLQR + TVLQR"


def controller_states(env: gym.Env, controller: Any) -> np.ndarray:
    """The states of one episode of ``controller`` on ``env`` from hanging at rest, up to the first within the
    success tolerance.

    Parameters
    ----------
    env : gymnasium.Env
        A swing-up env of the Planar2R arm (its state ``q, v`` read after each step).
    controller
        A ``predict(obs, state, episode_start, deterministic)`` policy.

    Returns
    -------
    ndarray, shape (T, 4)
        ``[th1, th2, dth1, dth2]`` at each control step (the angles wrapped to ``[-pi, pi)``), the first at rest
        hanging ``(-pi/2, 0)``, the last the state before the step that reached the tolerance (all the episode's
        states if it never did).
    """
    arm = env.unwrapped
    obs, _ = env.reset(options={"q": np.array(Q_DOWN, float), "v": np.zeros(2)})
    X, state, start = [], None, np.ones((1,), dtype=bool)
    while True:
        X.append(np.concatenate([wrap_angle(arm.q), arm.v]))
        action, state = controller.predict(obs, state=state, episode_start=start, deterministic=True)
        start = np.zeros((1,), dtype=bool)
        obs, _, terminated, truncated, info = env.step(action)
        if info["upright"] or terminated or truncated:
            return np.array(X)


def swingup_starts(env_id: str, share: float, stride: int = 10, env_kwargs: dict | None = None) -> dict[str, Any]:
    """The ``start_states`` setting of a training env (JSON's form): a share of the episodes that would start hanging
    start from a state of the scene's best model-based swing-up (module docstring).

    Parameters
    ----------
    env_id : str
        A swing-up id of the Planar2R arm: our own (``mbs_envs/Acrobot-v2``, ...) or one on the DFKI protocol's plant.
    share : float
        In [0, 1].
    stride : int
        Every ``stride``-th state (control steps ``dt`` apart) is a row.
    env_kwargs : dict, optional
        The env's arguments (the plant and torque limit the controller swings up; our own arms only: the protocol's
        plan is its shipped design).

    Returns
    -------
    dict
        ``{"share": share, "rows": [[th1, th2, dth1, dth2], ...]}``.

    Raises
    ------
    ValueError
        A share outside [0, 1], a stride not an integer >= 1, or an id that is no swing-up of the arm; each before any
        rollout.
    """
    from .. import validation as check
    from .dfki_selection import protocol_id
    from .dfki_swingup import plan_starts

    if isinstance(stride, bool) or not isinstance(stride, int) or stride < 1:
        raise ValueError(f"stride must be an integer >= 1, got {stride!r}")
    share = check.real(share, "share", 0.0, 1.0)
    try:
        protocol_id(env_id)
    except ValueError:
        pass
    else:
        return plan_starts(env_id, share, stride)
    swingups = {s.id: s.controllers[CONTROLLER] for s in registry.SCENES if CONTROLLER in s.controllers}
    spec = swingups.get(env_id) if isinstance(env_id, str) else None
    if spec is None:
        raise ValueError(
            f"env_id: {env_id!r} is no swing-up of the arm; known: {list(swingups)} and the DFKI protocol's ids"
        )
    env = gym.make(env_id, **(env_kwargs or {}))
    X = controller_states(env, make_controller(spec, env, default_gains_entry(spec, env)))[::stride]
    return {"share": share, "rows": [[round(float(x), 12) for x in row] for row in X]}
