"""SpatialChain-v0 (issue 35): drives sized by an upper bound of the gravity torque, the rest posture an
equilibrium, computed torque through the spatial RNEA, sane under random actions, the 100-link chain drawn."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import PD, ComputedTorque
from mbs_envs.envs.serial_chain import SerialChainEnv
from mbs_envs.envs.spatial_chain import SpatialChainEnv, hanging_posture, reach_gravity_torque
from mbs_envs.models import SerialChain
from mbs_envs.models.spatial_chain import SpatialChain

ENV_ID = "mbs_envs/SpatialChain-v0"


@pytest.mark.parametrize("n", [1, 2, 7])
def test_spaces_follow_n_links_and_the_vector_env_is_the_single_one(n):
    env = gym.make(ENV_ID, n_links=n)
    assert env.action_space.shape == (n,) and env.observation_space.shape == (6 * n,)
    obs, _ = env.reset(seed=4)
    assert env.observation_space.contains(obs)
    venv = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", n_links=n)
    vobs, _ = venv.reset(seed=[4, 5, 6])
    np.testing.assert_array_equal(vobs[0], obs)
    a = np.random.default_rng(0).uniform(-1, 1, (3, n)).astype(np.float32)
    for _ in range(20):
        vobs, vr, *_ = venv.step(a)
        obs, r, *_ = env.step(a[0])
    np.testing.assert_array_equal(vobs[0], obs)
    assert vr[0] == r


def test_drives_bound_every_gravity_torque_and_equal_the_planar_holding_torque():
    """``reach_gravity_torque`` >= |G(q)| at random postures of a random chain; for the planar
    arrangement (axes along z, gravity along -y) it is the planar chain's horizontal holding torque."""
    rng = np.random.default_rng(2)
    n = 6
    chain = SpatialChain(n_links=n, m=rng.uniform(0.1, 1, n), axis=rng.normal(size=(n, 3)), offset=rng.normal(size=(n, 3)) * 0.3,
                         com=rng.normal(size=(n, 3)) * 0.1)  # fmt: skip
    bound = reach_gravity_torque(chain)
    G = np.abs(chain.gravity(rng.uniform(-np.pi, np.pi, (2000, n))))
    assert np.all(G <= bound * (1 + 1e-12))
    m, l = rng.uniform(0.1, 1, n), rng.uniform(0.1, 0.5, n)  # noqa: E741
    planar = SerialChain(n_links=n, m=m, l=l)
    axis = np.tile([0.0, 0.0, 1.0], (n, 1))
    offset = np.zeros((n, 3))
    offset[1:, 0] = l[:-1]
    spatial = SpatialChain(n_links=n, m=m, l=l, axis=axis, offset=offset, g_vec=(0.0, -9.81, 0.0))
    np.testing.assert_allclose(
        reach_gravity_torque(spatial), SerialChainEnv.horizontal_gravity_torque(planar), rtol=1e-13
    )
    env = gym.make(ENV_ID, n_links=n).unwrapped
    bare = SpatialChain(n_links=n)
    np.testing.assert_allclose(env.u_max, reach_gravity_torque(bare), rtol=1e-14)
    np.testing.assert_allclose(
        env.model.params.armature, reach_gravity_torque(bare) / SpatialChainEnv.rotor_acceleration, rtol=1e-14
    )
    assert env.u_max[0] == pytest.approx(
        9.81 * 0.5, rel=1e-12
    )  # the base carries the 1 kg, 1 m chain at half its length


@pytest.mark.parametrize("n", [1, 2, 10])
def test_the_rest_posture_is_the_potential_minimum(n):
    chain = SpatialChain(n_links=n)
    q = hanging_posture(chain)
    assert np.max(np.abs(chain.gravity(q))) < 1e-12
    V = chain.potential_energy(q)
    others = np.random.default_rng(n).uniform(-np.pi, np.pi, (500, n))
    assert np.all(chain.potential_energy(others) >= V - 1e-12)
    if n > 1:  # the default: a horizontal first link, the rest straight down
        p = chain.joint_positions(q)
        np.testing.assert_allclose(p[2:, :2], np.broadcast_to(p[1, :2], p[2:, :2].shape), atol=1e-12)


@pytest.mark.parametrize("axis", [None, [[0, 0, 1], [0.6, 0.8, 0], [0, 0.6, 0.8]]], ids=["default", "tilted"])
def test_the_rest_posture_is_bfgs_result_with_or_without_scipy(axis):
    """The default chain starts at its minimum (no scipy.optimize needed, the same bits BFGS returns); a chain
    with tilted axes does not, and BFGS moves it to a stationary point of lower potential energy."""
    from scipy.optimize import minimize

    chain = SpatialChain(n_links=3) if axis is None else SpatialChain(n_links=3, axis=axis)
    q0 = np.array([0.0, np.pi / 2, 0.0])
    ref = minimize(lambda q: float(chain.potential_energy(q)), q0, jac=lambda q: chain.gravity(q), method="BFGS",
                   options={"gtol": 1e-10, "maxiter": 600})  # fmt: skip
    q = hanging_posture(chain)
    assert np.array_equal(q, ref.x)
    assert (ref.nit == 0) == (axis is None)  # the fast path is taken exactly where BFGS takes no step
    assert np.max(np.abs(chain.gravity(q))) <= 1e-10
    assert chain.potential_energy(q) <= chain.potential_energy(q0)


@pytest.mark.parametrize("n", [10, 100])
def test_computed_torque_tracks_and_pd_stays_within_the_drives(n):
    env = gym.make(ENV_ID, n_links=n)
    for C, tol in ((ComputedTorque, 1e-3), (PD, 0.5)):
        ctrl = C(env)
        obs, _ = env.reset(seed=11)
        errors = []
        for k in range(300):
            a, _ = ctrl.predict(obs)
            obs, r, term, trunc, info = env.step(a)
            assert not term
            if k >= 100:
                errors.append(np.linalg.norm(info["tracking_error"]) / np.sqrt(n))
        assert np.sqrt(np.mean(np.square(errors))) < tol, C.__name__


@pytest.mark.parametrize("n", [5, 50])
def test_random_actions_stay_finite_and_do_not_diverge(n):
    env = gym.make(ENV_ID, n_links=n)
    env.reset(seed=3)
    env.action_space.seed(3)
    for _ in range(500):
        obs, reward, term, trunc, info = env.step(env.action_space.sample())
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
        assert not info["diverged"] and not term


def test_free_motion_of_the_env_conserves_energy():
    """No drive torque, no damping: the env's energy (``info["energy"]``, the compiled kernel) is constant to RK4's error."""
    env = gym.make(ENV_ID, n_links=8, dt=0.002)
    env.reset(seed=0)
    E = [env.step(np.zeros(8, np.float32))[4]["energy"] for _ in range(500)]
    assert np.ptp(E) < 1e-6 * max(1.0, abs(E[0]))


def test_bad_construction_raises_by_name():
    with pytest.raises(ValueError, match="n_links"):
        gym.make(ENV_ID, n_links=0)
    with pytest.raises(ValueError, match="n_links"):
        gym.make(ENV_ID, n_links=4, params={"n_links": 3})
    with pytest.raises(ValueError, match="axis"):
        gym.make(ENV_ID, n_links=2, params={"axis": [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]]})
    with pytest.raises(ValueError, match="n_links"):
        gym.make(ENV_ID, n_links=3, params=SpatialChain(n_links=2).params)


def test_the_100_link_chain_is_drawn():
    env = gym.make(ENV_ID, n_links=100, render_mode="rgb_array")
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (500, 500, 3)
    link = np.all(img == np.array([0, 90, 200], np.uint8), axis=-1)  # the links' colour
    rows = np.flatnonzero(link.any(axis=1))
    assert link.sum() > 300 and rows.max() - rows.min() > 150  # a chain, not a dot: it spans the picture
