"""FourBar-v0 through the API: checkers, determinism, consistency of start states, stabilization, divergence."""

from __future__ import annotations


import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import PD, ComputedTorque, PDGravity

ENV_ID = "mbs_envs/FourBar-v0"


def test_episode_states_stay_consistent_and_info_is_complete():
    env = gym.make(ENV_ID)
    obs, info = env.reset(seed=3)
    model = env.unwrapped.model
    assert obs.shape == (12,) and info["constraint_residual"] <= 1e-12
    for _ in range(50):
        obs, r, term, trunc, info = env.step(env.action_space.sample())
    assert not term
    assert info["constraint_residual"] <= 1e-10
    q, v = env.unwrapped.q, env.unwrapped.v
    np.testing.assert_allclose(model.constraint_jacobian(q) @ v, 0, atol=1e-9)
    np.testing.assert_allclose(info["multipliers"], model.multipliers(q, v, info["u"]))
    assert info["energy"] == pytest.approx(float(model.energy(q, v)))
    assert info["tracking_error"].shape == (1,)


def test_reset_state_is_projected_or_refused():
    env = gym.make(ENV_ID)
    model = env.unwrapped.model
    q_ok, _ = model.consistent_state(0.5)
    env.reset(seed=0, options={"q": q_ok + [0.0, 0.02, -0.03], "v": [1.0, 0.0, 0.0]})
    assert np.max(np.abs(model.constraint_residual(env.unwrapped.q))) <= 1e-12
    np.testing.assert_allclose(model.constraint_jacobian(env.unwrapped.q) @ env.unwrapped.v, 0, atol=1e-12)
    # links stretched in a line, the rocker folded back: a stationary point of |phi| with phi != 0
    with pytest.raises(ValueError, match="cannot be made consistent"):
        env.reset(seed=0, options={"q": [0.0, 0.0, np.pi]})


def test_stabilization_choices_order_the_drift():
    residual = {}
    for kind in ("projection", "baumgarte", "none"):
        env = gym.make(ENV_ID, stabilization=kind)
        env.reset(seed=0)
        for _ in range(100):
            *_, info = env.step(np.array([0.2], np.float32))
        residual[kind] = info["constraint_residual"]
        assert not info["diverged"]
    assert residual["projection"] <= 1e-10 < residual["baumgarte"] < residual["none"], residual


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"stabilization": "magic"}, "stabilization"),
        ({"params": {"l0": 5.0}}, "l0"),
        ({"branch": 0}, "branch"),
        ({"residual_limit": -1.0}, "residual_limit"),
    ],
)
def test_bad_construction_raises(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(ENV_ID, **kwargs)


def test_serial_env_refuses_a_stabilization():
    with pytest.raises(ValueError, match="no constraints"):
        gym.make("mbs_envs/Planar2R-v0", stabilization="projection")


def test_residual_blow_up_is_reported_as_divergence():
    """No stabilization and explicit Euler at a coarse step: the loop drifts open; the env says so."""
    env = gym.make(ENV_ID, stabilization="none", integrator="euler", dt=0.05)
    obs, _ = env.reset(seed=0)
    for _ in range(500):
        obs, r, term, trunc, info = env.step(np.array([1.0], np.float32))
        assert np.all(np.isfinite(obs))
        if term:
            break
    assert term and info["diverged"]


def test_computed_torque_beats_pd_on_the_crank():
    env = gym.make(ENV_ID)
    settle = int(1.0 / env.unwrapped.dt)
    rms = {}
    for C in (PD, PDGravity, ComputedTorque):
        errs = []
        for seed in range(3):
            obs, _ = env.reset(seed=seed)
            e = []
            while True:
                obs, _, term, trunc, info = env.step(C(env).predict(obs)[0])
                e.append(info["tracking_error"])
                if term or trunc:
                    break
            errs.append(np.sqrt(np.mean(np.square(e[settle:]))))
        rms[C.__name__] = np.mean(errs)
    assert rms["ComputedTorque"] * 10 < rms["PD"], rms
    assert rms["ComputedTorque"] < rms["PDGravity"] < rms["PD"], rms


def test_pd_default_gains_match_the_mean_crank_inertia():
    env = gym.make(ENV_ID)
    J = env.unwrapped.mean_crank_inertia
    assert 0.03 < J < 0.2
    assert env.unwrapped.joint_inertia == J
    np.testing.assert_allclose(env.unwrapped.pd_gains, (100 * J, 20 * J))  # the pre-tuning gains
    # the defaults: the tuned bandwidth, scaled by the same inertia for PD (computed torque needs none)
    from mbs_envs.controllers.tuned import tuned_gains

    g = tuned_gains(env, "PD")
    pd = PD(env)
    np.testing.assert_allclose([pd.kp[0], pd.kd[0]], [J * g["omega"] ** 2, 2 * J * g["zeta"] * g["omega"]], rtol=1e-15)
    g = tuned_gains(env, "computed torque")
    np.testing.assert_allclose(ComputedTorque(env).kp, g["omega"] ** 2, rtol=1e-15)
