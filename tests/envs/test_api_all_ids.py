"""Every registered id through the API tier: checkers, determinism, pickling, subprocess vector envs, bad actions."""

from __future__ import annotations

import copy
import os
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs

IDS = sorted(mbs_envs.ENV_IDS)


def actions(env, n, seed=1, scale=1.5):
    shape = (n,) + env.action_space.shape
    return np.random.default_rng(seed).uniform(-scale, scale, shape).astype(np.float32)


def rollout(env, acts, seed):
    obs, _ = env.reset(seed=seed)
    rows = []
    for a in acts:
        obs, r, term, trunc, info = env.step(a)
        rows.append(np.r_[obs.astype(np.float64), r])
        if term or trunc:
            obs, _ = env.reset()
    return np.array(rows)


@pytest.mark.parametrize("env_id", IDS)
def test_checkers_without_warnings(env_id):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    envs = [
        gym.make(env_id).unwrapped for _ in range(2)
    ]  # made outside: making a superseded version (v0) warns by design
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(envs[0], skip_render_check=True)
        sb3_check_env(envs[1], warn=True)


@pytest.mark.parametrize("env_id", IDS)
def test_same_seed_and_actions_give_bit_identical_trajectories(env_id):
    env = gym.make(env_id)
    acts = actions(env, 150)
    a = rollout(env, acts, seed=7)
    np.testing.assert_array_equal(a, rollout(gym.make(env_id), acts, seed=7))
    assert not np.array_equal(a, rollout(gym.make(env_id), acts, seed=8))


@pytest.mark.parametrize("clone", [pickle.loads, copy.deepcopy], ids=["pickle", "deepcopy"])
@pytest.mark.parametrize("env_id", IDS)
def test_cloning_mid_episode_continues_identically(env_id, clone):
    env = gym.make(env_id)
    env.reset(seed=3)
    for a in actions(env, 40):
        env.step(a)
    twin = clone(pickle.dumps(env) if clone is pickle.loads else env)
    for a in actions(env, 60, seed=2):
        o1, r1, t1, *_ = env.step(a)
        o2, r2, t2, *_ = twin.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2 and t1 == t2
    np.testing.assert_array_equal(env.reset()[0], twin.reset()[0])  # the RNG travelled too


@pytest.mark.parametrize("env_id", IDS)
def test_subprocess_vector_env_matches_single_envs(env_id):
    env = gym.make(env_id)
    acts = actions(env, 40)
    # "module:id" imports mbs_envs (and so registers the ids) in the spawned workers
    venv = gym.vector.AsyncVectorEnv([lambda: gym.make("mbs_envs:" + env_id) for _ in range(2)], context="spawn")
    try:
        venv.reset(seed=[11, 12])
        rows = []
        for a in acts:
            o, r, term, trunc, _ = venv.step(np.stack([a, a]))
            rows.append(np.c_[o, r])
            assert not (term.any() or trunc.any())  # keeps the comparison free of autoresets
    finally:
        venv.close()
    rows = np.array(rows)
    for i, seed in enumerate([11, 12]):
        np.testing.assert_array_equal(rows[:, i], rollout(gym.make(env_id), acts, seed=seed))


@pytest.mark.parametrize("env_id", IDS)
def test_bad_actions_raise_and_lose_nothing(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    nu = env.action_space.shape[0]
    q, v, t = env.unwrapped.q, env.unwrapped.v, env.unwrapped.t
    for bad, match in (
        ([np.nan] * nu, "finite"),
        ([np.inf] + [0.0] * (nu - 1), "finite"),
        ([0.0] * (nu + 1), "shape"),
        ("left", "action must be real numbers"),
    ):
        with pytest.raises(ValueError, match=match):
            env.step(bad)
    np.testing.assert_array_equal(env.unwrapped.q, q)
    np.testing.assert_array_equal(env.unwrapped.v, v)
    assert env.unwrapped.t == t
    env.step(np.zeros(nu, np.float32))  # still usable


@pytest.mark.parametrize("env_id", IDS)
def test_out_of_range_actions_saturate(env_id):
    e1, e2 = gym.make(env_id), gym.make(env_id)
    e1.reset(seed=0)
    e2.reset(seed=0)
    nu = e1.action_space.shape[0]
    big = np.array([5.0, -3.0][:nu] + [7.0] * max(0, nu - 2))
    o1, *_, i1 = e1.step(big)
    o2, *_, i2 = e2.step(np.clip(big, -1, 1))
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(i1["u"], e1.unwrapped.u_max * np.clip(big, -1, 1))


@pytest.mark.parametrize("env_id", IDS)
def test_rgb_array_render(env_id):
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    pytest.importorskip("pygame")
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(env.action_space.shape, np.float32))
    frame = env.render()
    assert frame.shape == (500, 500, 3) and frame.dtype == np.uint8
    assert frame.min() < 100  # something was drawn on the white background
    env.close()
