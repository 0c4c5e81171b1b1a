"""RL + LQR: the agent swings up, the LQR takes over inside its catch level (mbs_envs/studies/handover.py)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import SwingUpLQR
from mbs_envs.envs.swingup import Q_DOWN, Q_UP, encode_swingup
from mbs_envs.studies.evaluation import rollout_batch, swing_up_metrics
from mbs_envs.controllers.region import PlantCase, estimate_region
from mbs_envs.studies.handover import HandOverPolicy, hand_over


class Push:
    """An 'agent' that always pushes with +1 and counts its calls in its state."""

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        n = np.asarray(observation).reshape(-1, 6).shape[0]
        return np.ones((n, 1), np.float32), (0 if state is None else state) + 1


@pytest.fixture(scope="module")
def acrobot():
    env = gym.make("mbs_envs/Acrobot-v1")
    lqr = SwingUpLQR(env)
    return env, lqr, lqr.catch


def test_hands_over_inside_the_region_only_and_keeps_the_agent_state(acrobot):
    env, lqr, level = acrobot
    policy = HandOverPolicy(Push(), lqr, level)
    x_in = np.array([0.002, -0.004, 0.01, 0.0])
    obs = encode_swingup(np.array([Q_UP + x_in[:2], Q_DOWN]), np.array([x_in[2:], np.zeros(2)]))
    assert x_in @ lqr.S @ x_in < level
    a, (inner, balancing) = policy.predict(obs, episode_start=np.ones(2, bool))
    assert balancing.tolist() == [True, False] and inner == 1
    np.testing.assert_allclose(a[0], np.clip(-(lqr.K @ x_in) / lqr.u_max, -1, 1), atol=1e-5)  # float32 observations
    assert a[1, 0] == 1.0
    # hysteresis: a balancing member stays with the LQR up to release * level, a new episode starts with the agent
    x_mid = x_in * np.sqrt(2.0 * level / (x_in @ lqr.S @ x_in))
    mid = encode_swingup((Q_UP + x_mid[:2])[None], x_mid[None, 2:])
    assert policy.predict(mid, state=(inner, np.array([True])))[1][1].tolist() == [True]
    assert policy.predict(mid, state=(inner, np.array([False])))[1][1].tolist() == [False]
    assert policy.predict(mid, state=(inner, np.array([True])), episode_start=np.array([True]))[1][1].tolist() == [
        False
    ]
    with pytest.raises(ValueError, match="level"):
        HandOverPolicy(Push(), lqr, 0.0)


def test_hand_over_uses_the_pairs_tuned_catch_else_the_controllers():
    from mbs_envs.controllers.tuned import tuned_gains
    from mbs_envs.studies.handover import TUNED_NAME

    for env_id in ("mbs_envs/Acrobot-v1", "mbs_envs/Pendubot-v1"):
        env = gym.make(env_id)
        pair, lqr, entry = hand_over(Push(), env), SwingUpLQR(env), tuned_gains(env, TUNED_NAME)
        assert (pair.level, pair.release) == (entry.get("catch", lqr.catch), entry.get("release", lqr.release))
        np.testing.assert_array_equal(pair.lqr.K, lqr.K)
        assert hand_over(Push(), env, catch=5.0, release=2.0).level == 5.0


def test_from_inside_the_sampled_region_the_pair_balances_to_the_end(acrobot):
    env, lqr, level = acrobot
    policy = HandOverPolicy(Push(), lqr, level)
    x_up = np.concatenate([Q_UP, np.zeros(2)])
    box = np.array([0.4, 0.8, 2.0, 4.0])
    c_star, _ = estimate_region(
        [PlantCase(lqr.model)], x_up, lqr.K, lqr.S, float(lqr.u_max[0]), 0.01, 2, box, samples=300, rounds=6
    )
    dx = (
        np.random.default_rng(3).uniform(-1, 1, (2_000_000, 4)) * box
    )  # where the estimate samples: the box, below half its level
    starts = dx[np.einsum("bi,ij,bj->b", dx, lqr.S, dx) < 0.5 * c_star][:3]
    assert len(starts) == 3
    for x0 in starts:
        env.reset(seed=0, options={"q": Q_UP + x0[:2], "v": x0[2:]})
        obs, state, start = (
            env.unwrapped.observe(env.unwrapped.q[None], env.unwrapped.v[None], None, None)[0],
            None,
            True,
        )
        for _ in range(400):
            a, state = policy.predict(obs, state, np.array([start]))
            start = False
            obs, _, _, _, info = env.step(a)
        assert state[1].tolist() == [True] and info["upright"] and state[0] == 400  # the agent's own state kept
    # from hanging, the pushing 'agent' never swings up: the pair is no better than its agent there
    venv = gym.make_vec("mbs_envs/Acrobot-v1", num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                        max_episode_steps=300)  # fmt: skip
    assert not any(swing_up_metrics(e)["success"] for e in rollout_batch(venv, policy, [0, 1]))


def test_the_catch_level_is_tuned_on_tuning_seeds_over_the_plant_set():
    from mbs_envs.studies.handover import tune_catch
    from mbs_envs.studies.tuning import TUNING_CONDITIONS

    pump = SwingUpLQR(gym.make("mbs_envs/Acrobot-v1"), catch=1e-12)  # the energy pump alone: it never catches by itself
    grid = [{"catch": 1e-6, "release": 4.0}, {"catch": 1000.0, "release": 4.0}]
    best, rows = tune_catch("Acrobot", [pump], grid, [20_000, 20_001])
    assert len(rows) == len(grid) * len(TUNING_CONDITIONS) and {r["condition"] for r in rows} == {
        c.name for c in TUNING_CONDITIONS
    }
    nominal = {r["catch"]: r["success"] for r in rows if r["condition"] == "nominal"}
    assert nominal[1e-6] == 0.0 and nominal[1000.0] > 0.0  # no catch, no balance; the swing-up + LQR's level catches
    assert best == grid[1]
