"""Planar2R against Gymnasium's Acrobot-v1: the same physics, two independent implementations.

Acrobot-v1 (``book`` dynamics, its default) is a 2R arm with unit masses and lengths, centres
at half length, unit inertia about each centre, g = 9.8, and only the elbow driven. Its angle
``theta1`` is measured from the downward vertical, ours from +x: ``th1 = theta1 - pi/2``;
``th2`` is relative in both. With the elbow torque alone (``u = (0, a)``) our accelerations
must equal those of Acrobot-v1's equations (``AcrobotEnv._dsdt``) to rounding; so must those of
``Planar2R(driven=(1,))``, the model of ``mbs_envs/Acrobot-v0``, with the elbow torque as its one input.
"""

from __future__ import annotations

import numpy as np
from gymnasium.envs.classic_control.acrobot import AcrobotEnv

from mbs_envs.models import Planar2R

ACROBOT_PARAMS = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 1.0, "r1": 0.5, "r2": 0.5, "I1": 1.0, "I2": 1.0, "g": 9.8}


def test_planar2r_with_acrobot_parameters_has_acrobot_v1_accelerations():
    env = AcrobotEnv()
    assert (env.LINK_MASS_1, env.LINK_MASS_2, env.LINK_LENGTH_1, env.LINK_LENGTH_2) == (1.0, 1.0, 1.0, 1.0)
    assert (env.LINK_COM_POS_1, env.LINK_COM_POS_2, env.LINK_MOI, env.book_or_nips) == (0.5, 0.5, 1.0, "book")
    model = Planar2R(**ACROBOT_PARAMS, driven=(1,))  # Acrobot-v0's model: only the elbow driven
    rng = np.random.default_rng(0)
    theta = rng.uniform(-np.pi, np.pi, (500, 2))
    dtheta = rng.uniform(-4 * np.pi, 4 * np.pi, (500, 2))  # Acrobot-v1's velocity bounds: 4 pi, 9 pi
    dtheta[:, 1] *= 9 / 4
    a = rng.uniform(-1, 1, 500)  # Acrobot-v1's torques are -1, 0, 1
    q = np.stack([theta[:, 0] - np.pi / 2, theta[:, 1]], axis=-1)
    ours = model.forward_dynamics(q, dtheta, a[:, None])
    theirs = np.array([env._dsdt(np.r_[theta[k], dtheta[k], a[k]])[2:4] for k in range(500)])
    scale = np.max(np.abs(theirs), axis=-1, keepdims=True)
    assert np.max(np.abs(ours - theirs) / scale) < 1e-12
