"""The global swing-up by nonlinear MPC: it recovers from a disturbed state in a short episode on both protocol
robots, its solutions stay within the torque limit, its memory is SB3's state (per member, never written in place),
its refusals."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers.mpc_swingup import COST, MODE, VALID, MPCSettings, MPCSwingUp
from mbs_envs.studies import dfki, dfki_v3

IDS = ("mbs_envs/AcrobotDFKI-v1", "mbs_envs/PendubotDFKI-v1")


def rollout(env_id: str, ctrl: MPCSwingUp, q0, v0, seconds: float):
    """The controller on the env from ``(q0, v0)``: the end effector's heights over the reach, and the last state."""
    env = gym.make(env_id)
    obs, _ = env.reset(options={"q": np.asarray(q0, float), "v": np.asarray(v0, float)})
    p = env.unwrapped.model.params
    state, heights = None, []
    for k in range(int(round(seconds / env.unwrapped.dt))):
        action, state = ctrl.predict(obs, state, np.array([k == 0]))
        obs, _, terminated, _, info = env.step(action)
        assert not terminated
        q = np.arctan2(obs[2:4], obs[0:2])
        heights.append(dfki.end_effector_height(q, p.l1, p.l2) / (p.l1 + p.l2))
    return np.array(heights), state


@pytest.mark.parametrize("env_id", IDS)
def test_it_recovers_from_a_disturbed_state_in_a_short_episode(env_id):
    """From a state a disturbance could leave (off upright by 2 rad on the shoulder, the elbow bent, both moving
    fast), within 3 s the arm is up and balanced by the upright LQR for the last second."""
    ctrl = MPCSwingUp(gym.make(env_id))
    heights, state = rollout(env_id, ctrl, q0=(np.pi / 2 - 2.0, 1.5), v0=(4.0, -6.0), seconds=3.0)
    assert heights[0] < dfki.HEIGHT
    last_second = heights[-int(round(1.0 / ctrl.dt)) :]
    assert np.all(last_second > 0.99), last_second.min()
    assert state[0, MODE] == 1.0  # balancing


@pytest.mark.parametrize("env_id", IDS)
def test_a_solution_from_hanging_stays_within_the_limit_and_lowers_the_cost_of_its_start(env_id):
    ctrl = MPCSwingUp(gym.make(env_id))
    x = np.array([-np.pi / 2, 0.0, 0.0, 0.0])
    start = ctrl.fresh_start(x)
    _, _, J0, _, _, _ = ctrl.solve(x, start, 0)  # the start's own cost: no iteration
    U, X, J, _, _, _ = ctrl.solve(x, start, ctrl.settings.fresh_iterations)
    assert np.all(np.abs(U) <= ctrl.u_lim) and np.all(np.abs(start) <= ctrl.u_lim)
    assert np.isfinite(J) and J < J0
    assert X.shape == (ctrl.N + 1, 4) and np.array_equal(X[0], x)


def test_the_memory_is_per_member_and_a_given_state_is_never_written():
    env_id = IDS[0]
    ctrl = MPCSwingUp(gym.make(env_id))
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    batch = np.stack([obs, obs])
    a1, s1 = ctrl.predict(batch, None, np.array([True, True]))
    assert s1.shape == (2, ctrl.state_size) and np.all(s1[:, VALID] == 1.0) and np.all(np.isfinite(s1[:, COST]))
    np.testing.assert_array_equal(a1[0], a1[1])
    kept = s1.copy()
    a2, s2 = ctrl.predict(batch, s1, np.array([False, True]))  # the second member starts again
    np.testing.assert_array_equal(s1, kept)  # not written in place
    np.testing.assert_array_equal(a2[1], a1[1])  # a fresh start: the same first action
    np.testing.assert_array_equal(s2[1], s1[1])
    single, _ = ctrl.predict(obs, s1[:1], np.array([False]))
    np.testing.assert_array_equal(single, a2[0])  # one member alone acts as in the batch


def test_a_short_protocol_run_recovers_after_each_disturbance():
    """The v3 protocol for 8 s with 2 disturbances: the arm is up more than half of the time."""
    env_id = IDS[1]
    r = dfki_v3.run(env_id, MPCSwingUp(gym.make(env_id)), seed=3, t_max=8.0, n=2)
    assert r["reset"].any()
    assert r["score"] > 0.5, r["score"]


@pytest.mark.parametrize(
    "field, value",
    [
        ("horizon", 0.0),
        ("knot_dt", -0.01),
        ("iterations", 1.5),
        ("w_q", -1.0),
        ("replan_factor", 0.5),
        ("catch_tol", float("nan")),
        ("lqr_r", 0.0),
    ],  # fmt: skip
)
def test_bad_settings_are_refused_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        MPCSettings(**{field: value})
    with pytest.raises(ValueError, match=field):
        MPCSwingUp(gym.make(IDS[0]), **{field: value})


def test_unknown_settings_and_a_wrong_state_are_refused():
    env = gym.make(IDS[0])
    with pytest.raises(ValueError, match="horizn"):
        MPCSwingUp(env, horizn=0.4)
    with pytest.raises(ValueError, match="MPCSettings"):
        MPCSwingUp(env, settings={"horizon": 0.4})
    ctrl = MPCSwingUp(env, settings=dataclasses.replace(MPCSettings(), horizon=0.3))
    assert ctrl.N == 30
    obs, _ = env.reset(seed=0)
    with pytest.raises(ValueError, match="state must have shape"):
        ctrl.predict(obs, np.zeros((1, 3)), np.array([False]))
    with pytest.raises(ValueError, match="MPCSwingUp acts on"):
        MPCSwingUp(gym.make("mbs_envs/Planar2R-v0"))
