"""Joint rates differenced from the observed angles (controllers.estimator.rates_from_angles, RatesFromAngles)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import SwingUpLQR
from mbs_envs.controllers.estimator import RatesFromAngles, rates_from_angles
from mbs_envs.envs.swingup import encode_swingup

DT = 0.002


def test_the_second_order_difference_is_exact_on_quadratics_across_the_wrap():
    """Angles quadratic in time, crossing +-pi between the samples: the rate at the last sample, to rounding."""
    rng = np.random.default_rng(0)
    B = 200
    q0, v0, a = rng.uniform(-np.pi, np.pi, (B, 2)), rng.uniform(-20, 20, (B, 2)), rng.uniform(-200, 200, (B, 2))
    t = np.array([-2 * DT, -DT, 0.0])
    raw = [q0 + v0 * s + 0.5 * a * s * s for s in t]  # unwrapped
    wrapped = [np.angle(np.exp(1j * x)) for x in raw]
    assert any(np.any(np.abs(w - r) > 1.0) for w, r in zip(wrapped, raw))  # some samples were wrapped
    got = rates_from_angles(wrapped[2], wrapped[1], wrapped[0], np.full(B, 2), np.full((B, 2), np.nan), DT)
    # the angles' rounding (|q| <= pi, eps 4.4e-16) over 2 dt, times 3 + 4 + 1: about 1e-12 rad/s
    np.testing.assert_allclose(got, v0, rtol=0, atol=2e-12)
    # the first-order difference after one step, the observed rate before
    first = rates_from_angles(wrapped[2], wrapped[1], wrapped[0], np.full(B, 1), np.full((B, 2), np.nan), DT)
    np.testing.assert_allclose(first, v0 - 0.5 * a * DT, rtol=0, atol=2e-12)
    seen = rng.normal(size=(B, 2))
    np.testing.assert_array_equal(rates_from_angles(wrapped[2], wrapped[1], wrapped[0], np.zeros(B), seen, DT), seen)


def test_the_difference_errs_by_a_third_of_the_jerk_and_amplifies_angle_noise_by_sqrt26_over_2dt():
    """The docstring's figures: on a cubic ``q = c t^3 / 6`` the estimate at t = 0 is ``-c dt^2 / 3`` (the rate is 0;
    9e-6 rad/s here, against the wrapped differences' rounding of about 4e-13);
    with independent angle noise of std s its std is ``s sqrt(26) / (2 dt)`` (1e5 samples: within 1 %)."""
    c = np.array([[7.0, -3.0]])
    q = [c * t**3 / 6 for t in (-2 * DT, -DT, 0.0)]
    np.testing.assert_allclose(
        rates_from_angles(q[2], q[1], q[0], np.array([2]), np.zeros((1, 2)), DT), -c * DT**2 / 3, rtol=0, atol=1e-12
    )  # the wrap's rounding (pi's ulp / dt)
    rng = np.random.default_rng(5)
    s = 1e-3
    n = rng.normal(0, s, (3, 100_000, 2))
    v = rates_from_angles(n[2], n[1], n[0], np.full(100_000, 2), np.zeros((100_000, 2)), DT)
    assert abs(v.std() / (s * np.sqrt(26) / (2 * DT)) - 1) < 0.01


class Recorder:
    """A policy that records the observations it is given and returns their rates as its action."""

    def __init__(self):
        self.seen = []

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self.seen.append(np.array(observation))
        return np.asarray(observation)[..., 4:5], state


def test_the_wrapped_policy_sees_the_differenced_rates_whatever_rates_are_observed():
    """Two observation streams with the same angles and different rates (noise of std 1 rad/s on the second): after the
    first step the wrapped policy sees the same observations, the angles untouched, and its memory restarts per member
    at ``episode_start``; the state passed in is not changed."""
    env = gym.make("mbs_envs/AcrobotDFKI-v1")
    rng = np.random.default_rng(1)
    B, T = 3, 6
    q = np.cumsum(rng.normal(0, 0.01, (T, B, 2)), axis=0)
    v = rng.normal(0, 1, (T, B, 2))
    streams = [encode_swingup(q, v), encode_swingup(q, v + rng.normal(0, 1, v.shape))]
    seen = []
    for obs in streams:
        inner = Recorder()
        p = RatesFromAngles(inner, env)
        state, start = None, np.ones(B, bool)
        for k in range(T):
            if k == 4:
                start = np.array([False, True, False])  # member 1 starts a new episode here
            _, state = p.predict(obs[k], state=state, episode_start=start)
            start = np.zeros(B, bool)
        seen.append(np.array(inner.seen))
    a, b = seen
    np.testing.assert_array_equal(a[:, :, :4], streams[0][:, :, :4])  # the angles as observed
    np.testing.assert_array_equal(a[1:4], b[1:4])  # steps 1-3: the rates from the angles alone
    np.testing.assert_array_equal(a[5], b[5])
    assert not np.array_equal(a[0], b[0])  # the first step: the observed rates
    assert not np.array_equal(a[4, 1], b[4, 1]) and np.array_equal(a[4, [0, 2]], b[4, [0, 2]])  # member 1 restarted
    q32 = np.arctan2(streams[0][..., 2:4].astype(float), streams[0][..., 0:2].astype(float))
    np.testing.assert_allclose(a[1, :, 4:6], ((q32[1] - q32[0]) / env.unwrapped.dt).astype(np.float32), rtol=1e-6)
    np.testing.assert_allclose(
        a[3, :, 4:6],
        ((3 * (q32[3] - q32[2]) - (q32[2] - q32[1])) / (2 * env.unwrapped.dt)).astype(np.float32),
        rtol=1e-6,
    )


def test_a_state_passed_in_is_left_as_it_was_and_single_equals_batched():
    env = gym.make("mbs_envs/AcrobotDFKI-v1")
    ctrl = RatesFromAngles(SwingUpLQR(env), env)
    obs, _ = env.reset(seed=0)
    _, state = ctrl.predict(obs, episode_start=True)
    obs2, *_ = env.step(np.array([0.3], np.float32))
    copy = [np.array(s, copy=True) if isinstance(s, np.ndarray) else s for s in state]
    a1, _ = ctrl.predict(obs2, state=state, episode_start=False)
    for s, c in zip(state, copy):
        if isinstance(c, np.ndarray):
            np.testing.assert_array_equal(s, c)
    batch = RatesFromAngles(SwingUpLQR(env), env)
    _, sb = batch.predict(np.stack([obs, obs]), episode_start=np.ones(2, bool))
    a2, _ = batch.predict(np.stack([obs2, obs2]), state=sb, episode_start=np.zeros(2, bool))
    assert a1.shape == (1,) and a2.shape == (2, 1)
    np.testing.assert_array_equal(a2[0], a1)
    np.testing.assert_array_equal(a2[1], a1)


def test_rates_from_angles_refuses_what_it_cannot_read():
    with pytest.raises(ValueError, match="env"):
        RatesFromAngles(SwingUpLQR(gym.make("mbs_envs/Acrobot-v1")), gym.make("mbs_envs/Planar2R-v0"))
    env = gym.make("mbs_envs/AcrobotDFKI-v1")
    with pytest.raises(ValueError, match="shape"):
        RatesFromAngles(SwingUpLQR(env), env).predict(np.zeros(5, np.float32))


def test_with_rates_from_angles_the_velocity_noise_axis_does_not_reach_the_controller():
    """The DFKI protocol with its sweep's velocity noise (observed rates only, std 0.5 rad/s, three members; one without):
    swing-up + LQR fails on noisy members with the observed rates and ends upright on every member with its rates from
    the angles (the benchmark's final-state rule)."""
    from mbs_envs.studies.dfki import final_success
    from mbs_envs.studies.robustness import Perturbation, run

    env_id = "mbs_envs/AcrobotDFKI-v1"
    sigmas = np.array([0.0, 0.5, 0.5, 0.5])
    ok = {}
    for wrap in (False, True):
        venv = gym.make_vec(env_id, num_envs=4, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
        env = gym.make(env_id)
        policy = RatesFromAngles(SwingUpLQR(env), env) if wrap else SwingUpLQR(env)
        res = run(venv, policy, [0] * 4, Perturbation(noise_sigma=sigmas, noise_index=(4, 5)), noise_seed=3)
        ok[wrap] = final_success(res["q"], res["v"]) & ~res["terminated"]
    assert ok[False][0] and not ok[False][1:].all()
    assert ok[True].all()


def test_stable_baselines3s_evaluate_policy_runs_the_wrapped_controller():
    """``evaluate_policy`` (SB3's own loop, memory through ``state`` and ``episode_start``) on the protocol: the
    wrapped swing-up + LQR gets the return of its own episode run by hand."""
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.vec_env import DummyVecEnv

    from mbs_envs.controllers import RatesFromAngles as exported

    assert exported is RatesFromAngles
    env = gym.make("mbs_envs/AcrobotDFKI-v1", max_episode_steps=600)
    venv = DummyVecEnv([lambda: gym.make("mbs_envs/AcrobotDFKI-v1", max_episode_steps=600)])
    venv.seed(4)
    mean, _ = evaluate_policy(RatesFromAngles(SwingUpLQR(env), env), venv, n_eval_episodes=1)
    ctrl = RatesFromAngles(SwingUpLQR(env), env)
    obs, _ = env.reset(seed=4)
    state, start, total, done = None, True, 0.0, False
    while not done:
        action, state = ctrl.predict(obs, state=state, episode_start=start)
        obs, r, term, trunc, _ = env.step(action)
        total, start, done = total + r, False, term or trunc
    assert mean == pytest.approx(
        total, rel=1e-6
    )  # the same rewards summed in another order and precision (SB3's float32 buffers)
