"""Tuning the energy controllers on the DFKI protocol (mbs_envs.studies.dfki_tuning), the kick from the hanging rest
(controllers.swingup), and where the protocol's gains come from (controllers.tuned.stored_entry)."""

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import tuned
from mbs_envs.controllers.swingup import KICK, REST_TOL, SwingUpLQR, at_rest, collocated_pfl
from mbs_envs.envs.swingup import Q_DOWN
from mbs_envs.studies import dfki, dfki_tuning
from mbs_envs.studies.evaluation import make_controller

ACRO = "mbs_envs/AcrobotDFKI-v1"
ENTRIES = [{"k_q": 20.0, "k_v": 5.0, "k_E": 16.0, "catch": 30.0, "lqr_r": 1.0},
           {"k_q": 5.0, "k_v": 1.0, "k_E": 2.0, "catch": 3.0, "lqr_r": 100.0},
           {"k_q": 50.0, "k_v": 10.0, "k_E": 0.5, "catch": 100.0, "lqr_r": 1e4}]  # fmt: skip


def run(venv_members, policy, steps):
    venv = gym.make_vec(ACRO, num_envs=venv_members, vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                        max_episode_steps=steps)  # fmt: skip
    return dfki.record(venv, policy, list(range(venv_members)))


@pytest.mark.parametrize("spec, entries", [("mbs_envs.controllers:SwingUpLQR", ENTRIES),
                                           ("mbs_envs.controllers:AdaptiveSwingUpLQR", [dict(e, lqr_r=10.0) for e in ENTRIES])])  # fmt: skip
def test_member_gains_reproduce_one_rollout_per_candidate(spec, entries):
    """Every candidate as a member of one batch moves exactly as the candidate alone (the laws broadcast)."""
    env = gym.make(ACRO)
    batched = run(len(entries), dfki_tuning.with_member_gains(make_controller(spec, env, entries[0]), entries), 400)
    for e, b in zip(entries, batched):
        alone = run(1, make_controller(spec, env, e), 400)[0]
        np.testing.assert_allclose(b["q"], alone["q"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(b["u"], alone["u"], rtol=0, atol=1e-12)
    assert np.abs(batched[0]["u"]).max() > 0.1  # the kick started the motion: the comparison is not of rest with rest


def test_member_gains_refuse_per_member_weights_on_the_adaptive_controller():
    env = gym.make(ACRO)
    c = make_controller("mbs_envs.controllers:AdaptiveSwingUpLQR", env, ENTRIES[0])
    with pytest.raises(ValueError, match="lqr_r"):
        dfki_tuning.with_member_gains(c, ENTRIES)


def test_rank_puts_failures_first_then_the_mean_score():
    per = {
        "a": np.array([[1, 0.5], [1, 0.2], [0, 0.0], [1, 0.4]]),
        "b": np.array([[1, 0.1], [1, 0.3], [1, 0.9], [1, 0.3]]),
    }
    # failures: 0, 0, 1, 0; mean scores 0.3, 0.25, 0.45, 0.35
    assert dfki_tuning.rank(per).tolist() == [3, 0, 1, 2]


def test_tune_returns_a_candidate_of_each_stage(monkeypatch):
    grid = ENTRIES[:2]
    # a stored pick's weight must not leak into the first stage (it did: the candidates took the stored lqr_r)
    table = {ACRO: {"swing-up + LQR": {"k_q": 1.0, "k_v": 1.0, "k_E": 1.0, "catch": 1.0, "lqr_r": 1e5}}}
    monkeypatch.setattr(tuned, "_table", lambda: table)
    out = dfki_tuning.tune(ACRO, grid=lambda: [{k: v for k, v in e.items() if k != "lqr_r"} for e in grid], max_episode_steps=20,
                           gates=(None, 0.1), pulse_episodes=2)  # fmt: skip
    first = {k: out["swing-up + LQR"]["best"][k] for k in ("k_q", "k_v", "k_E")}
    assert first in [{k: e[k] for k in ("k_q", "k_v", "k_E")} for e in grid]
    assert len(out["swing-up + LQR"]["rows"]) == 2 + 128  # both stages' candidates
    assert [r["entry"]["lqr_r"] for r in out["swing-up + LQR"]["rows"][:2]] == [dfki_tuning.FIRST_STAGE_R] * 2
    adaptive = out["adaptive swing-up + LQR"]["rows"]
    assert len(adaptive) == 2 + 2  # the first grid, then the gates with its pick
    assert [r["entry"].get("gate") for r in adaptive[2:]] == [None, 0.1]
    assert all("pulses success" in r for r in adaptive[2:]) and not any("pulses success" in r for r in adaptive[:2])
    assert {k: v for k, v in out["adaptive swing-up + LQR"]["best"].items() if k != "gate"} in [
        r["entry"] for r in adaptive[:2]
    ]
    assert out["adaptive swing-up + LQR"]["best"]["lqr_r"] == out["swing-up + LQR"]["best"]["lqr_r"]
    own = dfki_tuning.own_scene_entry(ACRO, "identified iLQR + TVLQR")
    assert own == tuned.tuned_gains(gym.make("mbs_envs/Acrobot-v1"), "identified iLQR + TVLQR")
    assert [r["entry"] for r in out["identified iLQR + TVLQR"]["rows"]] == [own, out["adaptive swing-up + LQR"]["best"]]
    assert out["identified iLQR + TVLQR"]["best"] in (own, out["adaptive swing-up + LQR"]["best"])


def test_the_kick_moves_an_acrobot_at_rest_and_only_there():
    env = gym.make(ACRO)
    c = SwingUpLQR(env)
    q, v = np.array([Q_DOWN]), np.zeros((1, 2))
    u = c.swing_up(q, v)
    assert abs(u[0]) > 0.01  # at rest hanging the law pushes
    # the push is the PD toward the offset KICK (every other term of y vanishes at rest)
    np.testing.assert_allclose(u, collocated_pfl(c.model, q, v, np.array([c.k_q * KICK]), 1), rtol=1e-13, atol=1e-13)
    # one entry just outside the rest set (the others inside), or a start of the scenes' own: the law without the kick
    rng = np.random.default_rng(0)
    for k in range(60):
        if k % 2:
            x = rng.uniform(-0.9, 0.9, 4) * REST_TOL
            x[rng.integers(4)] = rng.choice([-1.0, 1.0]) * 1.01 * REST_TOL
        else:
            x = rng.uniform(-0.1, 0.1, 4)
        qq, vv = (Q_DOWN + x[:2])[None], x[None, 2:]
        assert not at_rest(qq, vv)[0]
        E_err = c.model.energy(qq, vv) - c.E_up
        y = -c.k_q * qq[0, 1] - c.k_v * vv[0, 1] + c.k_E * E_err * vv[0, 0]
        np.testing.assert_allclose(c.swing_up(qq, vv), collocated_pfl(c.model, qq, vv, y, 1), rtol=1e-13, atol=1e-13)
    # the episode starts moving: the elbow is off rest after the first step
    venv = gym.make_vec(
        ACRO, num_envs=1, vectorization_mode="vector_entry_point", autoreset_mode="Disabled", max_episode_steps=5
    )
    r = dfki.record(venv, c, [0])[0]
    assert np.abs(r["v"][-1]).max() > REST_TOL


def test_stored_entry_walks_the_chains_and_says_when_there_is_none(monkeypatch):
    table = {
        "mbs_envs/Acrobot-v0": {"swing-up + LQR": {"k_q": 1.0}},
        "mbs_envs/AcrobotDFKI-v1": {"adaptive swing-up + LQR": {"k_q": 2.0}},
    }
    monkeypatch.setattr(tuned, "_table", lambda: table)
    assert tuned.stored_entry("mbs_envs/Acrobot-v1", "adaptive swing-up + LQR") == {"k_q": 1.0}  # plant, then laws
    assert tuned.stored_entry("mbs_envs/AcrobotDFKI-v1", "identified iLQR + TVLQR") == {"k_q": 2.0}
    assert tuned.stored_entry("mbs_envs/AcrobotDFKI-v1", "swing-up + LQR") is None
    assert tuned.stored_entry("mbs_envs/Planar2R-v0", "PD") is None
    got = tuned.stored_entry("mbs_envs/Acrobot-v0", "swing-up + LQR")
    got["k_q"] = 5.0  # a copy: the table is untouched
    assert table["mbs_envs/Acrobot-v0"]["swing-up + LQR"] == {"k_q": 1.0}


def test_no_gate_counts_as_beyond_the_largest_at_the_grid_edge():
    from mbs_envs.studies import tuning

    grid = [{"k_q": 1.0, "gate": g} for g in dfki_tuning.GATES] + [{"k_q": 1.0}]  # a first stage without the setting
    assert tuning.at_grid_edge({"k_q": 1.0, "gate": 0.5}, grid) == []  # none is beyond it
    assert tuning.at_grid_edge({"k_q": 1.0, "gate": min(g for g in dfki_tuning.GATES if g)}, grid) == ["gate"]
    assert tuning.at_grid_edge({"k_q": 1.0, "gate": None}, grid) == []  # a choice, not a number


def test_pick_catches_needs_every_nominal_swing_up_then_the_best_mean_score():
    cands = [{"lqr_r": 1.0, "catch": 30.0}, {"lqr_r": 10.0, "catch": 30.0}, {"lqr_r": 30.0, "catch": 10.0}]

    def row(policy, k, ok, score):
        return {"policy": policy, **cands[k], "nominal_success": ok, "score": score}

    rows = [
        row("A", 0, 1.0, 0.70),
        row("A", 1, 1.0, 0.80),
        row("A", 2, 1.0, 0.80),  # a tie: the first candidate
        row("s0", 0, 1.0, 0.60),
        row("s0", 1, 1.0, 0.90),
        row("s0", 2, 1.0, 0.70),
        row("s1", 0, 1.0, 0.60),
        row("s1", 1, 0.0, 0.95),
        row("s1", 2, 1.0, 0.70),
    ]  # 1: best mean, but s1 fails nominally
    picks = dfki_tuning.pick_catches(rows, {"model-based": ["A"], "RL + LQR": ["s0", "s1"]}, cands)
    assert picks == {"model-based": cands[1], "RL + LQR": cands[2]}
    with pytest.raises(ValueError, match="group 'RL \\+ LQR' has 1 rows"):
        dfki_tuning.pick_catches(rows[:-1], {"RL + LQR": ["s0", "s1"]}, cands)
    assert dfki_tuning.robust_catch_grid()[0] == {
        "lqr_r": dfki_tuning.ROBUST_LQR_R[0],
        "catch": dfki_tuning.ROBUST_CATCH[0],
    }
    assert len(dfki_tuning.robust_catch_grid()) == len(dfki_tuning.ROBUST_LQR_R) * len(dfki_tuning.ROBUST_CATCH)


def test_release_grid_keeps_the_pick_and_tries_each_factor_in_order():
    pick = {"lqr_r": 10.0, "catch": 30.0, "release": 4.0}
    grid = dfki_tuning.release_grid(pick)
    assert [c["release"] for c in grid] == list(dfki_tuning.ROBUST_RELEASE) and grid[0][
        "release"
    ] == 4.0  # today's value first
    assert all((c["lqr_r"], c["catch"]) == (10.0, 30.0) for c in grid)
    assert [c["release"] for c in dfki_tuning.release_grid(pick, (16, 32.0))] == [16.0, 32.0]  # a widened grid
    for bad in ((), (1.0,), (0.5, 2.0), (np.inf,), (np.nan,)):
        with pytest.raises(ValueError, match="values"):
            dfki_tuning.release_grid(pick, bad)
    # the rule on stage-2 rows: candidates differing only in release are told apart
    rows = [{"policy": "A", **c, "nominal_success": 1.0, "score": s} for c, s in zip(grid, (0.7, 0.7, 0.8, 0.8, 0.6))]
    assert dfki_tuning.pick_catches(rows, {"g": ["A"]}, grid) == {"g": grid[2]}


def test_a_job_runs_with_the_catch_it_is_given(tmp_path):
    """``catch_gains`` replaces the catching LQR's weight and level: the tuned values give the tuned episode bit for bit,
    another weight another episode; a pair's LQR takes the weight too; unknown keys and a policy without a catch are
    refused by name."""
    from mbs_envs.studies.handover import HandOverPolicy, hand_over

    gains = tuned.stored_entry(ACRO, "swing-up + LQR")
    task = {"env_id": ACRO, "spec": "mbs_envs.controllers:SwingUpLQR", "gains": gains}
    plain = dfki.controller_job(task)["run"]
    same = dfki.controller_job({**task, "catch_gains": {"lqr_r": gains["lqr_r"], "catch": gains["catch"]}})["run"]
    other = dfki.controller_job({**task, "catch_gains": {"lqr_r": 100.0 * gains["lqr_r"]}})["run"]
    np.testing.assert_array_equal(plain["u"], same["u"])
    assert not np.array_equal(plain["u"], other["u"])
    with pytest.raises(ValueError, match="unknown keys \\['k_q'\\]"):
        dfki.controller_job({**task, "catch_gains": {"k_q": 1.0}})
    with pytest.raises(ValueError, match="neither a controller with gains nor an RL \\+ LQR pair"):
        dfki.controller_job(
            {"env_id": ACRO, "spec": "mbs_envs.controllers:SwingUpLQR", "gains": None, "catch_gains": {"catch": 1.0}}
        )

    class Agent:
        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.zeros((len(np.atleast_2d(obs)), 1), np.float32), state

    env = gym.make(ACRO)
    pair = hand_over(Agent(), env, catch=7.0, lqr_r=10.0)
    assert isinstance(pair, HandOverPolicy) and pair.level == 7.0 and pair.lqr.lqr_r == 10.0
    assert not np.allclose(pair.lqr.K, hand_over(Agent(), env).lqr.K)
