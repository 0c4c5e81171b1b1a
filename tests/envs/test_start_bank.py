"""Training starts from given states (``start_states``, :class:`~mbs_envs.envs.swingup.StartBank`): the draws, the
shares, the refusals, the vector env and the score-designed plan's rows (:func:`~mbs_envs.studies.dfki_swingup.plan_starts`)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding

import mbs_envs  # noqa: F401
from mbs_envs.envs.swingup import Q_DOWN, Q_UP, StartBank, start_bank

IDS = ["mbs_envs/Acrobot-v1", "mbs_envs/Pendubot-v2", "mbs_envs/AcrobotDFKI-v2"]
ROWS = np.array([[0.1, 0.2, 0.3, 0.4], [-1.0, 2.0, -3.0, 4.0], [2.5, -0.5, 6.0, -7.0]])


def starts(env, seeds) -> np.ndarray:
    out = []
    for s in seeds:
        env.reset(seed=s)
        out.append(np.concatenate([env.unwrapped.q, env.unwrapped.v]))
    return np.array(out)


@pytest.mark.parametrize("env_id", IDS)
def test_no_bank_or_a_zero_share_draws_the_task_starts_bit_for_bit(env_id):
    plain = starts(gym.make(env_id), range(20))
    np.testing.assert_array_equal(starts(gym.make(env_id, start_states={"share": 0.0, "rows": ROWS}), range(20)), plain)
    np.testing.assert_array_equal(starts(gym.make(env_id, start_states=None), range(20)), plain)


@pytest.mark.parametrize("env_id", IDS)
def test_a_whole_share_starts_every_episode_from_the_drawn_row_plus_the_noise(env_id):
    env = gym.make(env_id, start_states={"share": 1.0, "rows": ROWS}, start_noise=0.05)
    for seed in range(30):
        env.reset(seed=seed)
        d = seeding.np_random(seed)[0].random(6)  # the choice, the row, q noise (2), v noise (2)
        row = ROWS[int(d[1] * len(ROWS))]
        np.testing.assert_array_equal(env.unwrapped.q, row[:2] + (-0.05 + 0.1 * d[2:4]))
        np.testing.assert_array_equal(env.unwrapped.v, row[2:] + (-0.05 + 0.1 * d[4:6]))


def test_the_shares_of_upright_bank_and_hanging_starts():
    """upright with p_up; else from the bank with p_s; else hanging: shares p_up, p_s (1 - p_up), the rest. 3,000
    episodes; the bounds are 5 binomial sigmas."""
    p_up, p_s, n = 0.2, 0.5, 3000
    env = gym.make("mbs_envs/Pendubot-v1", start_upright=p_up, start_states={"share": p_s, "rows": ROWS},
                   start_noise=0.01)  # fmt: skip
    kinds, rows = np.zeros(3), np.zeros(len(ROWS))
    for x in starts(env, range(n)):
        up, down = np.abs(x[:2] - Q_UP).max() <= 0.01, np.abs(x[:2] - Q_DOWN).max() <= 0.01
        near = np.abs(ROWS - x).max(axis=1) <= 0.01
        assert up + down + near.sum() == 1
        kinds += (up, near.any(), down)
        rows += near
    for count, p in zip(kinds, (p_up, p_s * (1 - p_up), (1 - p_up) * (1 - p_s))):
        assert abs(count - n * p) <= 5 * np.sqrt(n * p * (1 - p)), (kinds, p)
    p = 1 / len(ROWS)  # each row alike among the banked starts
    assert np.all(np.abs(rows - kinds[1] * p) <= 5 * np.sqrt(kinds[1] * p * (1 - p))), rows


@pytest.mark.parametrize(
    "value, match",
    [
        ({"share": 1.5, "rows": ROWS}, r"start_states\['share'\]"),
        ({"share": np.nan, "rows": ROWS}, r"start_states\['share'\]"),
        ({"share": 0.5, "rows": ROWS[:, :3]}, r"start_states\['rows'\] must have shape \(K, 4\)"),
        ({"share": 0.5, "rows": np.zeros((0, 4))}, r"start_states\['rows'\] must have shape"),
        ({"share": 0.5, "rows": ROWS[0]}, r"start_states\['rows'\] must have shape"),
        ({"share": 0.5, "rows": np.where(ROWS > 2, np.inf, ROWS)}, r"start_states\['rows'\] must be finite"),
        ({"share": 0.5, "rows": [["a", 1, 2, 3]]}, r"start_states\['rows'\]"),
        ({"share": 0.5}, "exactly the keys 'share' and 'rows'"),
        ({"share": 0.5, "rows": ROWS, "stride": 2}, "exactly the keys 'share' and 'rows'"),
        ([0.5, ROWS], "start_states must be a dict"),
        ({"share": 0.5, "rows": ROWS * 1e9}, "divergence_limit"),
    ],
)
def test_a_refused_bank_names_the_culprit_and_leaves_the_env_as_it_was(value, match):
    env = gym.make("mbs_envs/Acrobot-v2", start_states={"share": 0.5, "rows": ROWS})
    env.reset(seed=3)
    before = env.unwrapped.start_states
    with pytest.raises(ValueError, match=match):
        env.unwrapped.start_states = value
    assert env.unwrapped.start_states is before
    with pytest.raises(ValueError, match=match):
        gym.make("mbs_envs/Acrobot-v2", start_states=value)
    after = starts(env, [7, 8])
    np.testing.assert_array_equal(
        after, starts(gym.make("mbs_envs/Acrobot-v2", start_states={"share": 0.5, "rows": ROWS}), [7, 8])
    )


def test_the_bank_is_read_only_and_a_changed_bank_changes_the_starts():
    env = gym.make("mbs_envs/Acrobot-v1", start_states=StartBank(1.0, ROWS))
    with pytest.raises(ValueError):
        env.unwrapped.start_states.rows[0, 0] = 9.0
    first = starts(env, [1])
    env.unwrapped.start_states = {"share": 1.0, "rows": ROWS + 1.0}
    np.testing.assert_array_equal(starts(env, [1]), first + 1.0)  # the task cache follows the setting
    env.unwrapped.start_states = None
    np.testing.assert_array_equal(starts(env, [1]), starts(gym.make("mbs_envs/Acrobot-v1"), [1]))
    assert start_bank(StartBank(0.3, ROWS), "x").share == 0.3


def test_the_vector_env_draws_each_member_as_the_single_env_does():
    bank = {"share": 0.6, "rows": ROWS}
    venv = gym.make_vec("mbs_envs/Pendubot-v2", num_envs=4, vectorization_mode="vector_entry_point",
                        start_states=bank, start_noise=0.02)  # fmt: skip
    venv.reset(seed=[10, 11, 12, 13])
    single = starts(gym.make("mbs_envs/Pendubot-v2", start_states=bank, start_noise=0.02), [10, 11, 12, 13])
    np.testing.assert_array_equal(np.concatenate([venv.unwrapped.q, venv.unwrapped.v], axis=1), single)
    venv.unwrapped.set_attr("start_states", None)  # as the single env's setting, through the vector env
    venv.reset(seed=[10, 11, 12, 13])
    plain = starts(gym.make("mbs_envs/Pendubot-v2", start_noise=0.02), [10, 11, 12, 13])
    np.testing.assert_array_equal(np.concatenate([venv.unwrapped.q, venv.unwrapped.v], axis=1), plain)


def test_plan_starts_are_the_score_designed_plan_from_hanging_at_rest():
    from mbs_envs.controllers.scored_swingup import ScoredSwingUp
    from mbs_envs.studies.dfki_swingup import plan_starts

    bank = plan_starts("mbs_envs/PendubotDFKI-v2", 0.25, stride=5)
    rows = np.array(bank["rows"])
    X = ScoredSwingUp(gym.make("mbs_envs/PendubotDFKI-v1")).X
    np.testing.assert_allclose(rows, X[::5], rtol=0, atol=1e-12)
    np.testing.assert_allclose(rows[0], np.concatenate([Q_DOWN, np.zeros(2)]), rtol=0, atol=1e-12)
    assert bank["share"] == 0.25 and len(rows) == len(range(0, len(X), 5))
    env = gym.make("mbs_envs/PendubotDFKI-v2", start_states=bank)  # the env takes it as JSON gives it
    assert env.unwrapped.start_states.rows.shape == rows.shape
    with pytest.raises(ValueError, match="share"):
        plan_starts("mbs_envs/PendubotDFKI-v2", 1.5)
    with pytest.raises(ValueError, match="stride"):
        plan_starts("mbs_envs/PendubotDFKI-v2", 0.5, stride=0)
    with pytest.raises(ValueError, match="not on the DFKI protocol's plant"):
        plan_starts("mbs_envs/Pendubot-v2", 0.5)
