"""The DFKI benchmark's success rule and score as the project computes them (mbs_envs.studies.dfki)."""

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mbs_envs  # noqa: F401
from mbs_envs.studies import dfki

L1, L2 = 0.2, 0.3
DT = 0.002


def upright_run(n=50):
    """A hand-made run: upright at rest the whole time."""
    T = np.arange(n) * DT
    q = np.tile([np.pi / 2, 0.0], (n, 1))
    return T, q, np.zeros((n, 2)), np.zeros((n, 2))


def test_swingup_time_rule_sample_by_sample():
    T = np.arange(10) * 1.0
    up = np.ones(10, bool)
    assert dfki.swingup_time(T, up) == 1.0  # their loop stops at sample 1: sample 0 is never the time
    up[:4] = False
    assert dfki.swingup_time(T, up) == 4.0
    up[-1] = False  # the last sample is not read
    assert dfki.swingup_time(T, up) == 4.0
    up[-2] = False  # down at N-2: no swing-up
    assert dfki.swingup_time(T, up) == 9.0
    up = np.zeros(10, bool)
    up[3:6] = True  # up, then down again before the end
    assert dfki.swingup_time(T, up) == 9.0
    with pytest.raises(ValueError, match="T and up"):
        dfki.swingup_time(T, up[:-1])


def reference_swingup_time(T, up):
    """Their loop, transcribed (leaderboard.get_swingup_time, method "height", has_to_stay)."""
    index = len(T) - 1
    for i in range(len(up) - 2, 0, -1):
        if up[i]:
            index = i
        else:
            break
    return T[index]


def test_swingup_time_equals_their_loop_on_random_runs():
    rng = np.random.default_rng(3)
    for _ in range(500):
        n = int(rng.integers(3, 30))
        T = np.sort(rng.uniform(0, 10, n))
        up = rng.uniform(size=n) < rng.uniform()
        assert dfki.swingup_time(T, up) == reference_swingup_time(T, up)


def test_criteria_of_hand_made_runs():
    n = 101
    T = np.arange(n) * DT
    w = 2.0  # joint 2 turns at w rad/s under a constant 1 N m; joint 1 hangs still
    q = np.column_stack([np.full(n, -np.pi / 2), w * T])
    v = np.column_stack([np.zeros(n), np.full(n, w)])
    u = np.column_stack([np.zeros(n), np.ones(n)])
    c = dfki.criteria(T, q, v, u, L1, L2)
    assert c["success"] == 0.0 and c["swingup_time"] == T[-1]
    assert c["energy"] == pytest.approx(w * DT * (n - 1), rel=1e-12)
    assert c["tau_cost"] == pytest.approx(DT * (n - 1), rel=1e-12)
    assert c["velocity_cost"] == pytest.approx(w**2 * DT * (n - 1), rel=1e-12)
    assert c["tau_smoothness"] == 0.0
    u[:, 1] = (-1.0) ** np.arange(n)  # a bang-bang torque: changes of +-2, std 2
    assert dfki.criteria(T, q, v, u, L1, L2)["tau_smoothness"] == pytest.approx(2.0, rel=1e-12)


def test_energy_sees_steps_across_the_wrap():
    """An angle stored wrapped to [-pi, pi) jumps by 2 pi; its step is still small."""
    T = np.arange(3) * DT
    q = np.array([[0.0, np.pi - 0.01], [0.0, -np.pi + 0.01], [0.0, -np.pi + 0.03]])
    u = np.array([[0.0, 1.0]] * 3)
    c = dfki.criteria(T, q, np.zeros((3, 2)), u, L1, L2)
    assert c["energy"] == pytest.approx(0.04, rel=1e-9)


@given(st.integers(0, 2**32 - 1), st.sampled_from([0, 1]), st.floats(0.01, 0.2))
@settings(max_examples=50, deadline=None)
def test_torque_use_is_one_for_torque_following_the_rate_and_below_one_otherwise(seed, driven, t_end):
    rng = np.random.default_rng(seed)
    n = 101
    T = np.cumsum(np.r_[0.0, rng.uniform(0.5, 1.5, n - 1) * DT])  # uneven steps: the sums weigh each by its dt
    v = rng.normal(0, 3.0, (n, 2))
    u = np.zeros((n, 2))
    u[:, driven] = -2.5 * v[:, driven]  # |u| proportional to |v| (of either sign): the bound is reached
    r = dfki.torque_use(T, v, u, driven, t_end)
    m = T[:-1] < t_end
    dt = np.diff(T)[m]
    assert r["swingup_tau_cost"] == pytest.approx((6.25 * v[:-1, driven][m] ** 2 * dt).sum(), rel=1e-12)
    assert r["torque_use"] == pytest.approx(1.0, rel=1e-12)
    assert r["least_tau_cost"] == pytest.approx(r["swingup_tau_cost"], rel=1e-12)
    u[:, driven] += rng.normal(0, 1.0, n)  # any other torque: strictly less of it does work
    r = dfki.torque_use(T, v, u, driven, t_end)
    assert 0.0 <= r["torque_use"] < 1.0 and r["least_tau_cost"] < r["swingup_tau_cost"]
    # the other joint's rates do not enter
    v2 = v.copy()
    v2[:, 1 - driven] *= 7.0
    assert dfki.torque_use(T, v2, u, driven, t_end) == r


def test_torque_use_of_hand_made_runs_and_refusals():
    T = np.arange(5) * 0.5
    v = np.zeros((5, 2))
    u = np.zeros((5, 2))
    v[:, 1] = [1.0, 0.0, 2.0, 0.0, 9.0]
    u[:, 1] = [2.0, 3.0, 1.0, 0.0, 9.0]  # intervals 0..3 before t_end = 2.0; the last sample is not an interval
    r = dfki.torque_use(T, v, u, 1, 2.0)
    # C = (4 + 9 + 1 + 0) / 2 = 7, W = (2 + 0 + 2 + 0) / 2 = 2, V = (1 + 0 + 4 + 0) / 2 = 2.5
    assert r == {"swingup_tau_cost": 7.0, "work": 2.0, "least_tau_cost": 1.6, "torque_use": pytest.approx(1.6 / 7)}
    # the window ends at the swing-up: from t_end = 1.0 on, intervals 0 and 1 only
    assert dfki.torque_use(T, v, u, 1, 1.0) == {"swingup_tau_cost": 6.5, "work": 1.0, "least_tau_cost": 2.0,
                                                "torque_use": pytest.approx(2.0 / 6.5)}  # fmt: skip
    held = dfki.torque_use(T, np.zeros((5, 2)), u, 1, 2.0)  # torque against a joint that never moves: no work
    assert held["work"] == held["least_tau_cost"] == 0.0 and np.isnan(held["torque_use"])
    assert np.isnan(dfki.torque_use(T, v, np.zeros((5, 2)), 1, 2.0)["torque_use"])  # no torque
    with pytest.raises(ValueError, match="driven"):
        dfki.torque_use(T, v, u, 2, 2.0)
    with pytest.raises(ValueError, match="shape"):
        dfki.torque_use(T, v[:4], u, 1, 2.0)


def test_upright_run_succeeds_and_scores_by_its_criteria():
    c = dfki.criteria(*upright_run(), L1, L2)
    assert c["success"] == 1.0 and c["swingup_time"] == DT
    assert dfki.score(c) == pytest.approx(1 - np.tanh(np.pi * DT / 20.0) / 5, rel=1e-12)
    q = upright_run()[1].copy()
    q[-2, 0] = np.pi / 2 - 0.5  # end effector at 0.5 * 0.2 + ... below 0.9 (l1 + l2) near the end
    assert dfki.end_effector_height(q[-2], L1, L2) < 0.9 * (L1 + L2)
    c = dfki.criteria(upright_run()[0], q, np.zeros_like(q), np.zeros_like(q), L1, L2)
    assert c["success"] == 0.0 and dfki.score(c) == 0.0


#: the published simulation leaderboard v2 (criteria and score as printed), as the module stores it, every robot
LEADERBOARD_V2 = {
    f"{robot}: {name}": row
    for robot, board in dfki.PUBLISHED_SIMULATION_V2.items()
    for name, row in board["rows"].items()
}


@pytest.mark.parametrize("name", sorted(LEADERBOARD_V2))
def test_score_reproduces_the_published_leaderboard(name):
    """Their printed criteria give their printed score. Tolerance 0.004: the criteria are printed to 2
    decimals (smoothness to 3: its rounding alone moves the score by up to (pi / 0.1) 0.0005 / 5 = 0.0031),
    the score to 3; a normalizer off by 10 % moves some row by more than 0.0075 (the next test)."""
    t, e, tc, sm, vc, published = LEADERBOARD_V2[name]
    c = {"success": 1.0, "swingup_time": t, "energy": e, "tau_cost": tc, "tau_smoothness": sm, "velocity_cost": vc}
    assert dfki.score(c) == pytest.approx(published, abs=0.004)


@pytest.mark.parametrize("factor", [0.9, 1.1])
@pytest.mark.parametrize("key", sorted(dfki.NORMALIZERS))
def test_a_wrong_normalizer_is_caught_by_the_published_rows(key, factor):
    """The check above can fail: any one normalizer 10 % off puts some published row beyond its tolerance."""
    wrong = {**dfki.NORMALIZERS, key: dfki.NORMALIZERS[key] * factor}
    misses = []
    for t, e, tc, sm, vc, published in LEADERBOARD_V2.values():
        c = {"success": 1.0, "swingup_time": t, "energy": e, "tau_cost": tc, "tau_smoothness": sm, "velocity_cost": vc}
        misses.append(abs(dfki.score(c, wrong) - published))
    assert max(misses) > 0.006


class Bang:
    """Full torque one way: the arm never reaches the threshold in 10 s... it is checked, not assumed."""

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return np.ones((len(obs), 1), np.float32), state


def test_record_follows_the_protocol_and_matches_the_env():
    venv = gym.make_vec(
        "mbs_envs/AcrobotDFKI-v1", num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode="Disabled"
    )
    runs = dfki.record(venv, Bang(), [0, 1])
    assert len(runs) == 2
    r = runs[0]
    assert r["T"].shape == (5000,) and r["T"][-1] == pytest.approx(9.998) and not r["terminated"]
    np.testing.assert_array_equal(r["q"][0], [-np.pi / 2, 0.0])
    np.testing.assert_array_equal(r["u"][:, 0], 0.0)  # the passive shoulder
    np.testing.assert_array_equal(r["u"][:, 1], 6.0)  # the elbow at its limit
    np.testing.assert_array_equal(runs[1]["q"], r["q"])  # at rest from hanging: the seed does not matter
    # the recorded state is the single env's, step for step
    env = gym.make("mbs_envs/AcrobotDFKI-v1")
    env.reset(seed=0)
    for i in range(30):
        np.testing.assert_allclose(env.unwrapped.q, r["q"][i], rtol=0, atol=1e-12)
        env.step(np.ones(1, np.float32))
    out = dfki.evaluate(runs, L1, L2)
    assert out[0]["score"] == (dfki.score(out[0]) if out[0]["success"] else 0.0)


def test_published_tables_are_consistent():
    """The stored robustness rows: every score is the mean of its six fractions (to their rounding)."""
    for scene in dfki.PUBLISHED_ROBUSTNESS_V2.values():
        for row in scene["rows"].values():
            assert np.mean(row[:6]) / 100 == pytest.approx(row[6], abs=0.0015)
