"""Acrobot-v1 and Pendubot-v1: the swing-up task with a reward that pays for holding within the tolerance."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.envs.swingup import Q_UP
from mbs_envs.studies.evaluation import Episode, swing_up_metrics

V1 = ["mbs_envs/Acrobot-v1", "mbs_envs/Pendubot-v1"]


def reward_at(env_id: str, offset: np.ndarray, v: np.ndarray = np.zeros(2), action: float = 0.0) -> tuple[float, dict]:
    """The reward of one step of size ~0 (dt = 1e-9) from ``q_up + offset``: the reward of that state."""
    env = gym.make(env_id, dt=1e-9, substeps=1)
    env.reset(options={"q": Q_UP + offset, "v": v})
    _, r, _, _, info = env.step(np.array([action], np.float32))
    return r, info


@pytest.mark.parametrize("env_id", V1)
def test_holding_within_the_tolerance_pays_more_than_hovering_outside_it(env_id):
    held, info = reward_at(env_id, np.array([0.09, -0.09]))
    assert info["upright"] and info["reward_hold"] == 1.0
    for offset in ([0.11, 0.0], [0.0, 0.11], [0.3, 0.0], [0.2, -0.2]):
        hover, info = reward_at(env_id, np.array(offset))
        assert not info["upright"] and info["reward_hold"] == 0.0
        assert held > hover + 0.9  # about twice: v0 paid 0.995 at 0.1 rad against 0.951 at 0.3 rad
    # the terms add up to the reward, with the hold bonus the one difference to v0
    old, _ = reward_at(env_id.replace("v1", "v0"), np.array([0.05, 0.0]), action=0.5)
    new, info = reward_at(env_id, np.array([0.05, 0.0]), action=0.5)
    assert new == pytest.approx(old + 1.0, abs=1e-12)
    assert new == pytest.approx(
        info["reward_height"] + info["reward_upright"] + info["reward_effort"] + info["reward_hold"], abs=1e-12
    )


@pytest.mark.parametrize("env_id", V1)
def test_v0_keeps_its_reward_and_both_versions_are_registered(env_id):
    r0, info0 = reward_at(env_id.replace("v1", "v0"), np.array([0.01, 0.0]))
    assert info0["reward_hold"] == 0.0 and info0["upright"]
    q = Q_UP + np.array([0.01, 0.0])
    h = 0.5 * (np.sin(q[0]) + np.sin(q[0] + q[1]))
    assert r0 == pytest.approx(h - 0.05 * 0.01**2, abs=1e-12)
    assert gym.spec(env_id).max_episode_steps == gym.spec(env_id.replace("v1", "v0")).max_episode_steps == 1500


@pytest.mark.parametrize("env_id", V1)
def test_vector_env_pays_the_same_bonus(env_id):
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", dt=1e-9, substeps=1)
    venv.reset(seed=0, options={"q": Q_UP + np.array([0.05, 0.0]), "v": np.zeros(2)})
    _, r, _, _, info = venv.step(np.zeros((3, 1), np.float32))
    np.testing.assert_array_equal(info["reward_hold"], 1.0)
    single, _ = reward_at(env_id, np.array([0.05, 0.0]))
    np.testing.assert_allclose(r, single, atol=1e-12)
    with pytest.raises(ValueError, match="hold_bonus"):
        gym.make(env_id, hold_bonus=-1.0)


def test_swing_up_metrics_at_the_wider_tolerance_and_near_upright():
    t = np.arange(1, 501) * 0.01
    e = np.zeros((500, 2))
    e[:100] = 2.0  # hanging for the first second
    e[100:150, 0] = 0.25  # then 0.5 s within 0.3 rad but not 0.2
    e[-100:, 1] = 0.15  # the last second within 0.2 rad but not 0.1
    ep = Episode(t=t, tracking_error=e, u=np.zeros((500, 1)), reward=np.zeros(500), compute_time=np.zeros(500),
                 diverged=False, terminated=False, upright=np.all(np.abs(e) <= 0.1, axis=1), power=np.zeros(500))  # fmt: skip
    m = swing_up_metrics(ep)
    assert not m["success"] and m["success_wide"]
    assert m["time_near_upright"] == pytest.approx(4.0)  # every step after the first second
    e[-1, 1] = 0.21
    assert not swing_up_metrics(Episode(**{**ep.__dict__, "tracking_error": e}))["success_wide"]


def test_start_upright_curriculum():
    """start_upright = p starts a share p of the episodes about upright; p = 0 draws exactly the hanging
    task's starts (the same generator calls as before the option existed)."""
    from gymnasium.utils import seeding

    from mbs_envs.envs.swingup import Q_DOWN, Q_UP

    env = gym.make("mbs_envs/Acrobot-v1")
    for seed in range(5):
        env.reset(seed=seed)
        rng = seeding.np_random(seed)[0]
        np.testing.assert_array_equal(env.unwrapped.q, Q_DOWN + rng.uniform(-0.1, 0.1, 2))
        np.testing.assert_array_equal(env.unwrapped.v, rng.uniform(-0.1, 0.1, 2))
    for p, lo, hi in ((1.0, 200, 200), (0.5, 70, 130)):  # 200 episodes: 0.5 within +-4.2 sigma
        env = gym.make("mbs_envs/Pendubot-v1", start_upright=p, start_noise=0.3)
        up = 0
        for seed in range(200):
            env.reset(seed=seed)
            near_up = np.abs(env.unwrapped.q - Q_UP).max() <= 0.3
            assert near_up or np.abs(env.unwrapped.q - Q_DOWN).max() <= 0.3
            up += near_up
        assert lo <= up <= hi
    with pytest.raises(ValueError, match="start_upright"):
        gym.make("mbs_envs/Acrobot-v1", start_upright=1.5)
