"""SerialChain-v0: any N, drives sized by the holding torque, sane under random actions, CT via RNEA."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import PD, ComputedTorque
from mbs_envs.envs import SerialChainEnv
from mbs_envs.models import SerialChain

ENV_ID = "mbs_envs/SerialChain-v0"


@pytest.mark.parametrize("n", [1, 3, 40])
def test_spaces_follow_n_links(n):
    env = gym.make(ENV_ID, n_links=n)
    assert env.action_space.shape == (n,)
    assert env.observation_space.shape == (6 * n,)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)


def test_default_drives_hold_the_horizontal_chain_and_have_armature():
    env = gym.make(ENV_ID, n_links=6).unwrapped
    bare = SerialChain(n_links=6)
    G = np.abs(bare.gravity(np.zeros(6)))
    np.testing.assert_allclose(env.u_max, G, rtol=1e-14)
    # base drive carries the whole rope at half its length: 1 kg * g * 0.5 m
    assert env.u_max[0] == pytest.approx(9.81 * 0.5, rel=1e-12)
    np.testing.assert_allclose(env.model.params.armature, G / SerialChainEnv.rotor_acceleration, rtol=1e-14)
    # user overrides win
    env2 = gym.make(ENV_ID, n_links=6, params={"armature": 0.0}, torque_limit=2.0).unwrapped
    assert np.all(env2.model.params.armature == 0) and np.all(env2.u_max == 2.0)


@pytest.mark.parametrize(
    "params, match", [({"n_links": 3}, "n_links"), ({"m": -1.0}, "'m'"), ({"armature": np.nan}, "armature")]
)
def test_bad_construction_raises(params, match):
    with pytest.raises(ValueError, match=match):
        gym.make(ENV_ID, n_links=4, params=params)


def test_n_links_must_be_a_positive_integer():
    with pytest.raises(ValueError, match="n_links"):
        gym.make(ENV_ID, n_links=0)


@pytest.mark.parametrize("n", [5, 50])
def test_random_actions_stay_finite_and_do_not_diverge(n):
    """Full random torques for a whole episode at the default single RK4 step."""
    env = gym.make(ENV_ID, n_links=n)
    env.reset(seed=3)
    env.action_space.seed(3)
    for _ in range(500):
        obs, reward, term, trunc, info = env.step(env.action_space.sample())
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
        assert not info["diverged"] and not term
    # measured for this seed: final max |v| 5.1 rad/s (N = 5), 11.6 (N = 50); over the episode 12.6 and 17.6
    assert np.max(np.abs(env.unwrapped.v)) < 200


def test_the_default_step_is_accurate_against_a_tight_adaptive_reference():
    """Random actions, 50 control steps, N = 20: RK4 (one step per 10 ms) vs DOP853 at 1e-11."""
    final = {}
    for name, kw in {"ref": dict(integrator="dop853", rtol=1e-11, atol=1e-11), "default": {}}.items():
        env = gym.make(ENV_ID, n_links=20, **kw)
        env.reset(seed=0)
        rng = np.random.default_rng(1)
        for _ in range(50):
            env.step(rng.uniform(-1, 1, 20))
        final[name] = env.unwrapped.q
    # measured 1.4e-7 rad
    assert np.max(np.abs(final["default"] - final["ref"])) < 1e-6


def test_computed_torque_uses_rnea_and_beats_pd():
    env = gym.make(ENV_ID, n_links=10)
    obs, _ = env.reset(seed=0)
    ct = ComputedTorque(env, kp=100.0, kd=20.0)  # PD and computed torque at the same bandwidth (10 rad/s)
    ob = env.unwrapped.decode_observation(obs)
    a_cmd = ob.a_ref + 100.0 * (ob.q_ref - ob.q) + 20.0 * (ob.v_ref - ob.v)
    model = env.unwrapped.model
    np.testing.assert_allclose(ct.input(ob), model.rnea(ob.q, ob.v, a_cmd) + model.friction(ob.v), atol=1e-12)
    rms = {}
    for C in (PD, ComputedTorque):
        c = C(env, *(env.unwrapped.pd_gains if C is PD else (100.0, 20.0)))
        errs = []
        for seed in range(2):
            obs, _ = env.reset(seed=seed)
            for k in range(300):
                obs, _, term, trunc, info = env.step(c.predict(obs, deterministic=True)[0])
                assert not term
                if k >= 100:
                    errs.append(info["tracking_error"])
        rms[C.__name__] = np.sqrt(np.mean(np.square(errs)))
    # measured: PD 1.7e-2, computed torque 3.0e-5 rad (N = 10, 1 s <= t < 3 s, seeds 0 and 1)
    assert rms["ComputedTorque"] * 100 < rms["PD"], rms


@pytest.mark.parametrize("n", [0, 501, "10", 2.5, True, 100_001, None])
def test_n_links_outside_the_task_range_is_refused_naming_the_bound(n):
    with pytest.raises(ValueError, match=r"n_links must be an integer in \[1, 500\]"):
        gym.make("mbs_envs/SerialChain-v0", n_links=n)


def test_model_n_links_bound_is_named():
    from mbs_envs.models import SerialChain

    with pytest.raises(ValueError, match=r"n_links' must be an integer in \[1, 100000\]"):
        SerialChain(n_links=100_001)
    assert SerialChain(n_links=3.0).n_links == 3
