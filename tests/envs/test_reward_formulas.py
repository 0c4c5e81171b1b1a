"""The reward kernels (SIMD loops over members) against their formulas in plain numpy, beside them in the code."""

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.envs import swingup, tracking


@pytest.mark.parametrize("env_id", ["mbs_envs/Planar2R-v0", "mbs_envs/FourBar-v0", "mbs_envs/SerialChain-v0"])
def test_the_tracking_reward_kernel_is_its_formula(env_id):
    env = gym.make(env_id).unwrapped
    p = env.task_params
    rng = np.random.default_rng(0)
    B, m = 257, len(p.tracked)  # not a multiple of any vector width
    q, v = rng.uniform(-3, 3, (B, env.model.nq)), rng.uniform(-5, 5, (B, env.model.nv))
    q_ref, v_ref, a_ref = rng.uniform(-3, 3, (B, m)), rng.uniform(-5, 5, (B, m)), rng.uniform(-5, 5, (B, m))
    action = rng.uniform(-1, 1, (B, env.action_space.shape[0]))
    r, terms = tracking.reward(p, q, v, (q_ref, v_ref, a_ref), action)
    e, de = tracking.errors(p, q, v, (q_ref, v_ref, a_ref))
    r_ref, (r_e, r_de, r_u) = tracking.reward_formula(p.weights, e, de, action)
    np.testing.assert_allclose(r, r_ref, rtol=1e-13, atol=0)  # sums of a few squares: rounding of the order only
    np.testing.assert_allclose(terms["reward_tracking"], r_e, rtol=1e-13, atol=0)
    np.testing.assert_allclose(terms["reward_velocity"], r_de, rtol=1e-13, atol=0)
    np.testing.assert_allclose(terms["reward_effort"], r_u, rtol=1e-13, atol=0)


@pytest.mark.parametrize("env_id", ["mbs_envs/Acrobot-v0", "mbs_envs/Acrobot-v1", "mbs_envs/Pendubot-v1"])
def test_the_swingup_reward_kernel_is_its_formula(env_id):
    env = gym.make(env_id).unwrapped
    p = env.task_params
    rng = np.random.default_rng(1)
    B = 257
    q = rng.uniform(-10, 10, (B, 2))
    q[:40] = np.array([np.pi / 2, 0.0]) + rng.uniform(-0.15, 0.15, (40, 2))  # some members near upright
    v, action = rng.uniform(-5, 5, (B, 2)), rng.uniform(-1, 1, (B, 1))
    r, _ = swingup.reward(p, q, v, action)
    weights, _, _, tolerance = p.kernel_arguments()
    np.testing.assert_allclose(r, swingup.reward_formula(weights, tolerance, q, action), rtol=1e-12, atol=1e-15)
    assert 0 < np.sum(swingup.reward_formula(weights, tolerance, q, action) > 1.5) or weights[3] == 0
