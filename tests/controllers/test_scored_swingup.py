"""The score-designed swing-up: its design within the torque limit, ending in the success region, scored on the
protocol as its design's rollout is, its memory in SB3's state, its refusals."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers.scored_swingup import ScoredSwingUp, feedforward, stored_design
from mbs_envs.studies import dfki, dfki_swingup

IDS = ("mbs_envs/AcrobotDFKI-v1", "mbs_envs/PendubotDFKI-v1")


@pytest.mark.parametrize("env_id", IDS)
def test_the_shipped_design_stays_within_the_limit_and_its_plan_ends_where_the_lqr_catches(env_id):
    env = gym.make(env_id)
    ctrl = ScoredSwingUp(env)
    assert np.all(np.abs(ctrl.U) <= ctrl.u_max[0])
    e = ctrl.X[-1] - ctrl.goal
    e[:2] = np.mod(e[:2] + np.pi, 2 * np.pi) - np.pi
    assert np.max(np.abs(e[:2])) < 0.1 and np.max(np.abs(e[2:])) < 1.0  # near upright: the upright LQR's to catch
    p = env.unwrapped.model.params
    y = dfki.end_effector_height(ctrl.X[-1, :2], p.l1, p.l2)
    assert y > dfki.HEIGHT * (p.l1 + p.l2)  # in the success region


@pytest.mark.parametrize("env_id", IDS)
def test_the_protocols_score_is_the_designs_rollout_score(env_id):
    """The episode the protocol records (the env, the controller) scores as the design's own rollout (the same
    trajectory: the feedback terms are zero along the plan on the nominal plant), to rounding."""
    env = gym.make(env_id)
    design = stored_design(env_id)
    plant = dfki_swingup.Plant.of(env)
    objective, c = dfki_swingup.design_score(plant, np.array(design["knots"]), design["knot_dt"])
    venv = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    run = dfki.record(venv, ScoredSwingUp(env), [0])
    p = env.unwrapped.model.params
    got = dfki.evaluate(run, p.l1, p.l2)[0]
    assert got["success"] == 1.0 and c["success"] == 1.0
    for k in ("swingup_time", "energy", "tau_cost", "tau_smoothness", "velocity_cost", "score"):
        assert got[k] == pytest.approx(c[k], rel=1e-6, abs=1e-9), k  # RK4 of the env's kernel against the planner's
    assert -objective == c["score"]


def test_the_step_since_the_start_is_the_controllers_state_per_member():
    env = gym.make(IDS[0])
    ctrl = ScoredSwingUp(env)
    obs, _ = env.reset(seed=0)
    batch = np.stack([obs, obs])
    a1, s1 = ctrl.predict(batch, None, np.array([True, True]))
    a2, s2 = ctrl.predict(batch, s1, np.array([False, True]))  # the second member starts again
    assert s1.tolist() == [1, 1] and s2.tolist() == [2, 1]
    np.testing.assert_array_equal(a2[1], a1[1])
    assert a2[0] != a1[0]  # the plan moved on a step


def test_feedforward_is_the_spline_through_the_knots_clipped():
    u = feedforward(np.array([0.0, 10.0, -10.0, 0.0]), 0.05, 0.002, 6.0)
    assert len(u) == 75 and np.max(np.abs(u)) == 6.0 and u[0] == 0.0 and u[25] == 6.0


def test_a_design_missing_or_malformed_is_refused_by_name():
    with pytest.raises(ValueError, match="no scored swing-up design for 'mbs_envs/Acrobot-v1'"):
        ScoredSwingUp(gym.make("mbs_envs/Acrobot-v1"))
    env = gym.make(IDS[0])
    with pytest.raises(ValueError, match="knots"):
        ScoredSwingUp(env, design={"knot_dt": 0.05, "knots": [0.0, np.nan, 1.0, 0.0]})
    with pytest.raises(ValueError, match="knot_dt"):
        ScoredSwingUp(env, design={"knot_dt": -0.05, "knots": [0.0] * 5})


def test_the_search_never_worsens_the_design_and_repeats_from_its_seed():
    env_id = IDS[1]
    plant = dfki_swingup.Plant.of(gym.make(env_id))
    design = stored_design(env_id)
    knots = np.array(design["knots"]) + 0.05 * np.sin(np.arange(len(design["knots"])))  # a design a little off
    start = dfki_swingup.design_score(plant, knots, design["knot_dt"])[0]
    z1, f1 = dfki_swingup.search(plant, knots, design["knot_dt"], evaluations=60, seed=4)
    z2, f2 = dfki_swingup.search(plant, knots, design["knot_dt"], evaluations=60, seed=4)
    assert f1 <= start and f1 == f2 and np.array_equal(z1, z2)
    assert dfki_swingup.design_score(plant, z1, design["knot_dt"])[0] == f1
    assert np.all(np.abs(z1) <= plant.u_max)


def test_a_design_that_does_not_swing_up_scores_worse_than_any_that_does():
    plant = dfki_swingup.Plant.of(gym.make(IDS[0]))
    f, c = dfki_swingup.design_score(plant, np.zeros(10), 0.05)  # no torque: the arm hangs
    assert c["success"] == 0.0 and c["score"] == 0.0 and f >= 1.0 + np.pi - 1e-9


def test_an_identification_window_whose_every_lqr_is_refused_keeps_the_gains_it_had(monkeypatch):
    """A window closes where no member's new estimate gives an LQR (all non-finite): the memory keeps the old
    gains and the step goes on (it raised a reshape error on the global-policy protocol's disturbed states)."""
    from mbs_envs.controllers.adaptive_swingup import K_, AdaptiveSwingUpLQR

    env = gym.make("mbs_envs/AcrobotDFKI-v1")
    ctrl = AdaptiveSwingUpLQR(env, window=5)
    monkeypatch.setattr(
        ctrl, "gains", lambda model, n, Q=None, R=None: (np.full((n, 1, 4), np.nan), np.full((n, 4, 4), np.nan))
    )
    obs, _ = env.reset(seed=0)
    state, start = None, True
    for k in range(30):
        action, state = ctrl.predict(obs[None], state, np.array([start]))
        start = False
        if k == 0:
            K0 = np.array(state[:, K_])
        obs, *_ = env.step(action[0])
    np.testing.assert_array_equal(state[:, K_], K0)


def test_the_design_report_covers_every_robot_designed_into_the_folder(tmp_path):
    """Robots designed by separate runs into one folder share one report, each with the command that made it."""
    c = {"swingup_time": 1.0, "energy": 8.0, "tau_cost": 2.0, "tau_smoothness": 0.01, "velocity_cost": 50.0,
         "score": 0.6}  # fmt: skip
    settings = {"horizon": 1.5, "period": 0.3, "amplitude": 1.0, "w_u": 1.0, "w_v": 0.03}
    for robot, command in (("Pendubot", "python scripts/dfki_design.py --robot Pendubot"), ("Acrobot", None)):
        entry = {"env_id": f"mbs_envs/{robot}DFKI-v1", "knot_dt": 0.05, "knots": [0.0] * 5, "criteria": c,
                 "settings": settings, "candidates": []}  # fmt: skip
        if command:
            entry["command"] = command
        (tmp_path / robot).mkdir()
        (tmp_path / robot / "design.json").write_text(json.dumps(entry))
    entries = dfki_swingup.designs_in(tmp_path)
    assert [e["env_id"] for e in entries] == ["mbs_envs/AcrobotDFKI-v1", "mbs_envs/PendubotDFKI-v1"]
    text = dfki_swingup.design_report(entries)
    assert "### mbs_envs/AcrobotDFKI-v1" in text and "### mbs_envs/PendubotDFKI-v1" in text
    assert text.count("Designed by `python scripts/dfki_design.py --robot Pendubot`") == 1
    assert dfki_swingup.designs_in(tmp_path / "empty") == []
