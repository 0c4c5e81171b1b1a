"""Acrobot-v0 and Pendubot-v0: the swing-up scenes on the 2R model with one motor."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import PD, ComputedTorque, PDGravity, SwingUpLQR
from mbs_envs.controllers.swingup import collocated_pfl
from mbs_envs.envs.swingup import Q_UP, decode_swingup, encode_swingup
from mbs_envs.models import Planar2R
from mbs_envs.studies.evaluation import Episode, SCORING, rollout_batch, swing_up_metrics

IDS = ["mbs_envs/Acrobot-v0", "mbs_envs/Pendubot-v0"]


@pytest.mark.parametrize("env_id, driven", [(IDS[0], 1), (IDS[1], 0)])
def test_one_motor_on_the_named_joint_and_the_task_as_documented(env_id, driven):
    env = gym.make(env_id)
    base = env.unwrapped
    assert base.model.actuation.tolist() == np.eye(2)[:, [driven]].tolist() and base.model.nu == 1
    assert env.action_space.shape == (1,) and env.observation_space.shape == (6,)
    assert env.spec.max_episode_steps == 1500
    obs, info = env.reset(seed=3)
    assert np.all(np.abs(base.q - np.array([-np.pi / 2, 0.0])) <= 0.1) and np.all(np.abs(base.v) <= 0.1)
    obs, r, term, trunc, info = env.step(np.array([0.5], np.float32))
    q, v = base.q, base.v
    e = (q - Q_UP + np.pi) % (2 * np.pi) - np.pi
    h = 0.5 * (np.sin(q[0]) + np.sin(q[0] + q[1]))
    assert r == pytest.approx(h - 0.05 * e @ e - 0.01 * 0.25, abs=1e-12)
    assert info["power"] == pytest.approx(0.5 * base.u_max[0] * v[driven], abs=1e-12)
    np.testing.assert_allclose(info["tracking_error"], e, atol=1e-12)
    np.testing.assert_allclose(decode_swingup(obs).q, q, atol=1e-6)
    assert not term and not info["upright"]


@pytest.mark.parametrize("env_id", IDS)
def test_compiled_and_numpy_paths_give_the_same_episode(env_id):
    fast, slow = gym.make(env_id), gym.make(env_id, compiled=False)
    assert fast.unwrapped.compiled is not None and slow.unwrapped.compiled is None
    rng = np.random.default_rng(0)
    fast.reset(seed=1)
    slow.reset(seed=1)
    for _ in range(300):
        a = rng.uniform(-1, 1, 1)
        o1, r1, _, _, i1 = fast.step(a)
        o2, r2, _, _, i2 = slow.step(a)
        np.testing.assert_allclose(o1, o2, atol=1e-6)  # float32 observations
        assert r1 == pytest.approx(r2, abs=1e-12) and i1["power"] == pytest.approx(i2["power"], abs=1e-12)
        assert i1["energy"] == pytest.approx(i2["energy"], abs=1e-12) and i1["upright"] == i2["upright"]
    np.testing.assert_allclose(fast.unwrapped.q, slow.unwrapped.q, atol=1e-12)


def test_observation_round_trip():
    rng = np.random.default_rng(1)
    q, v = rng.uniform(-np.pi, np.pi, (50, 2)), rng.normal(size=(50, 2))
    d = decode_swingup(encode_swingup(q, v))
    np.testing.assert_allclose(np.cos(d.q - q), 1.0, atol=1e-6)
    with pytest.raises(ValueError, match="shape"):
        decode_swingup(np.zeros(5))


@pytest.mark.parametrize("driven", [(), (2,), (0, 0), (0.5,), "elbow", None])
def test_a_bad_driven_selection_is_refused_by_name(driven):
    with pytest.raises(ValueError, match="driven"):
        Planar2R(driven=driven)


@pytest.mark.parametrize("env_id", IDS)
def test_tracking_controllers_refuse_an_underactuated_scene(env_id):
    for cls in (PD, PDGravity, ComputedTorque):
        with pytest.raises(ValueError, match="acts on JointTrackingEnv"):
            cls(gym.make(env_id))


@pytest.mark.parametrize("a", [0, 1])
def test_collocated_pfl_gives_the_driven_joint_the_commanded_acceleration(a):
    model = Planar2R(driven=(a,), b1=0.3, f2=0.2)
    rng = np.random.default_rng(2)
    q, v, y = rng.uniform(-3, 3, (100, 2)), rng.normal(size=(100, 2)) * 3, rng.normal(size=100) * 10
    u = collocated_pfl(model, q, v, y, a)
    acc = model.forward_dynamics(q, v, u[:, None])
    np.testing.assert_allclose(acc[:, a], y, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("env_id, at_least", [(IDS[0], 15), (IDS[1], 1)])
def test_swing_up_controller_reaches_upright_at_the_nominal_plant(env_id, at_least):
    """On the 20 test seeds with the tuned gains, episodes end balanced (upright within 0.1 rad for the
    last 2 s): the acrobot 17 of 20 when measured, the pendubot 1 of 20 (its law is the weak side; 2 of
    20 with the first tuning stage's gains, which scored worse on the tuning seeds: 70 % failures against 67 %)."""
    env = gym.make(env_id)
    venv = gym.make_vec(env_id, num_envs=20, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    episodes = rollout_batch(venv, SwingUpLQR(env), list(range(20)))
    scored = [SCORING["swing-up"](ep) for ep in episodes]
    wins = [m for m, failed in scored if not failed]
    assert len(wins) >= at_least
    for m in wins:
        assert (
            0 < m["time_to_swing_up"] <= 13 and m["energy_used"] > 39.0
        )  # 13 s: the last 2 s of 15 are upright  # at least the 39.2 J from hanging to upright


def test_swing_up_controller_balances_from_near_upright_with_lqr():
    env = gym.make("mbs_envs/Acrobot-v0")
    ctrl = SwingUpLQR(env)
    obs, _ = env.reset(options={"q": Q_UP + [0.02, -0.02], "v": [0.0, 0.0]})
    state, start = None, np.ones(1, bool)
    for _ in range(600):  # 6 s: the slowest closed-loop mode decays with a time constant of about 1 s
        action, state = ctrl.predict(obs, state=state, episode_start=start)
        start = np.zeros(1, bool)
        obs, *_, info = env.step(action)
    assert bool(state) and info["upright"] and np.max(np.abs(info["tracking_error"])) < 1e-3


def test_a_larger_lqr_input_weight_gives_smaller_gains_and_a_larger_cost_to_go():
    """R trades gain for effort: K shrinks and S grows with R (Riccati's monotonicity); the tuned
    entry's R (1 without one) is what the controller uses."""
    env = gym.make("mbs_envs/Acrobot-v0")
    ctrls = [SwingUpLQR(env, lqr_r=r) for r in (0.1, 1.0, 10.0, 100.0)]
    norms = [np.abs(c.K).max() for c in ctrls]
    assert all(a > b for a, b in zip(norms, norms[1:]))
    assert all(np.all(np.linalg.eigvalsh(b.S - a.S) > 0) for a, b in zip(ctrls, ctrls[1:]))
    with pytest.raises(ValueError, match="lqr_r"):
        SwingUpLQR(env, lqr_r=0.0)


def test_second_tuning_stage_refines_the_lqr_weight_and_catch_around_a_pick():
    from mbs_envs.studies import tuning

    start = {"k_q": 2.0, "k_v": 5.0, "k_E": 2.0, "catch": 3.0}
    best, rows = tuning.tune("Acrobot", "swing-up + LQR", n_seeds=1, start=start, max_episode_steps=20)
    assert len(rows) == len(tuning.swing_up_refine_grid(start)) and {r["stage"] for r in rows} == {2}
    assert {**start, "lqr_r": 1.0} in [r["entry"] for r in rows]  # the first stage's pick is a candidate
    assert all(
        {k: r["entry"][k] for k in ("k_q", "k_v", "k_E")} == {k: start[k] for k in ("k_q", "k_v", "k_E")} for r in rows
    )
    grid = tuning.GRIDS["swing-up + LQR"]() + tuning.swing_up_refine_grid(start)
    assert set(tuning.at_grid_edge({**start, "lqr_r": 1e6}, grid)) == {"lqr_r"}  # settings of either stage
    chosen = next(r for r in rows if r["entry"] == best)
    assert all((chosen["failure_rate"], chosen["error"] if np.isfinite(chosen["error"]) else np.inf)
               <= (r["failure_rate"], r["error"] if np.isfinite(r["error"]) else np.inf) for r in rows)  # fmt: skip


def test_swing_up_metrics_on_a_made_up_episode():
    t = np.arange(1, 501) * 0.01
    up = t > 2.505
    ep = Episode(t=t, tracking_error=np.zeros((500, 2)), u=np.ones((500, 1)), reward=np.zeros(500), compute_time=np.zeros(500),
                 diverged=False, terminated=False, upright=up, power=np.where(t < 1, -2.0, 1.0))  # fmt: skip
    m = swing_up_metrics(ep)
    assert m["success"] and m["time_to_swing_up"] == pytest.approx(2.50)
    assert m["energy_used"] == pytest.approx(0.01 * (99 * 2.0 + 401 * 1.0))
    dip = up.copy()
    dip[-150] = False  # one step outside in the last 2 s
    assert not swing_up_metrics(Episode(**{**ep.__dict__, "upright": dip}))["success"]
    assert not swing_up_metrics(Episode(**{**ep.__dict__, "terminated": True}))["success"]
    with pytest.raises(ValueError, match="upright"):
        swing_up_metrics(Episode(**{**ep.__dict__, "upright": None}))


def test_an_input_delay_applies_the_previous_action():
    venv = gym.make_vec(
        IDS[0], num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode="Disabled", max_episode_steps=3
    )

    class Ramp:
        k = 0

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            self.k += 1
            return np.full((2, 1), 0.1 * self.k, np.float32), state

    eps = rollout_batch(venv, Ramp(), [0, 1], delay=1)
    np.testing.assert_allclose(eps[0].u[:, 0], venv.unwrapped.env.u_max[0] * np.array([0.0, 0.1, 0.2]), rtol=1e-6)
    with pytest.raises(ValueError, match="delay"):
        rollout_batch(venv, Ramp(), [0, 1], delay=-1)
