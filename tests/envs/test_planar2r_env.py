"""Planar2R-v0 through the API: checkers, determinism, pickling, bad input, divergence, render."""

from __future__ import annotations

import os
import pickle

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401  (registers the ids)
from mbs_envs.envs import decode_tracking

ENV_ID = "mbs_envs/Planar2R-v0"


def rollout(env, actions, seed=0):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out.append(np.r_[obs.astype(np.float64), r])
    return np.array(out[1:])


def random_actions(n, seed=1, scale=1.5):
    return np.random.default_rng(seed).uniform(-scale, scale, (n, 2)).astype(np.float32)


def test_reset_to_exact_state_and_state_accessors():
    env = gym.make(ENV_ID)
    q0, v0 = np.array([0.4, -0.3]), np.array([1.0, 2.0])
    obs, info = env.reset(seed=0, options={"q": q0, "v": v0})
    np.testing.assert_array_equal(env.unwrapped.q, q0)
    np.testing.assert_array_equal(env.unwrapped.v, v0)
    dec = decode_tracking(obs, 2)
    np.testing.assert_allclose(dec.q, q0, atol=1e-6)
    np.testing.assert_allclose(dec.v, v0, atol=1e-6)
    assert info["energy"] == pytest.approx(env.unwrapped.model.energy(q0, v0))
    env.unwrapped.q[0] = 99.0  # a copy: the env is untouched
    assert env.unwrapped.q[0] == 0.4
    env.reset(options={"q": q0})
    np.testing.assert_array_equal(env.unwrapped.v, 0.0)


def test_observation_carries_the_reference():
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=5)
    ref = env.unwrapped.reference
    for _ in range(10):
        obs, *_ = env.step(np.zeros(2, np.float32))
    dec = decode_tracking(obs, 2)
    q_ref, v_ref, a_ref = ref(env.unwrapped.t)
    np.testing.assert_allclose(dec.v_ref, v_ref, rtol=1e-6)
    np.testing.assert_allclose(dec.a_ref, a_ref, rtol=1e-6)
    np.testing.assert_allclose(np.angle(np.exp(1j * (dec.q_ref - q_ref))), 0, atol=1e-6)


def test_make_kwargs_reach_the_model_and_integrator():
    env = gym.make(ENV_ID, params={"m1": 2.0}, dt=0.02, integrator="radau", rtol=1e-6, substeps=3, max_episode_steps=7)
    base = env.unwrapped
    assert base.model.params.m1 == 2.0 and base.dt == 0.02 and base.substeps == 3
    assert base.integrator.name == "radau" and base.integrator.rtol == 1e-6
    env.reset(seed=0)
    n = 0
    while True:
        n += 1
        *_, term, trunc, _ = env.step(np.zeros(2, np.float32))
        if term or trunc:
            break
    assert n == 7


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"params": {"m1": -1.0}}, "m1"),
        ({"params": {"arm": 1.0}}, "arm"),
        ({"dt": 0.0}, "dt"),
        ({"substeps": 0}, "substeps"),
        ({"integrator": "magic"}, "unknown integrator"),
        ({"integrator": "rk4", "rtol": 1e-6}, "takes no options"),
        ({"torque_limit": (10.0, -1.0)}, "torque_limit"),
        ({"reward_weights": (1.0, -1.0, 0.0)}, "reward_weights"),
    ],
)
def test_bad_construction_raises(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(ENV_ID, **kwargs)


def test_bad_render_mode_raises():
    from mbs_envs.envs import Planar2REnv

    with pytest.raises(ValueError, match="render_mode"):
        Planar2REnv(render_mode="ascii")


@pytest.mark.parametrize(
    "options, match",
    [
        ({"q": [0.0]}, "q"),
        ({"q": [np.nan, 0.0]}, "finite"),
        ({"v": [0.0, 0.0, 1.0]}, "v"),
        ({"x": 1}, "unknown reset option"),
    ],
)
def test_bad_reset_options_raise(options, match):
    env = gym.make(ENV_ID)
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0, options=options)


def test_divergence_ends_the_episode_with_a_finite_observation():
    """Explicit Euler at a huge step under full torque blows up; the env reports it."""
    env = gym.make(ENV_ID, integrator="euler", dt=0.5, divergence_limit=1e6)
    obs, _ = env.reset(seed=0)
    for _ in range(100):
        obs, r, term, trunc, info = env.step(np.array([1.0, -1.0]))
        assert np.all(np.isfinite(obs)) and np.isfinite(r)
        if term:
            break
    assert term and info["diverged"]
    assert np.all(np.isfinite(env.unwrapped.q)) and np.isfinite(info["energy"])


def test_no_divergence_flag_in_normal_runs():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    for a in random_actions(100):
        *_, term, _, info = env.step(a)
        assert not term and not info["diverged"]


def test_rgb_array_render():
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    pytest.importorskip("pygame")
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (500, 500, 3) and frame.dtype == np.uint8
    assert frame.min() < 100  # something was drawn on the white background
    env.step(np.zeros(2))
    pickle.loads(pickle.dumps(env)).render()  # renderer reopened after pickling
    env.close()


def test_human_render_with_dummy_video_driver():
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    pytest.importorskip("pygame")
    env = gym.make(ENV_ID, render_mode="human")
    env.reset(seed=0)
    env.step(np.zeros(2))
    assert env.render() is None
    env.close()
