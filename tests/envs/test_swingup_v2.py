"""Acrobot-v2, Pendubot-v2 and the protocol plant's AcrobotDFKI-v2, PendubotDFKI-v2: the swing-up task paid for
reaching the region the upright LQR catches (mbs_envs/envs/swingup_v2.py)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import scipy.linalg

import mbs_envs  # noqa: F401
from mbs_envs.controllers.region import PlantCase, closed_loop_final, estimate_region
from mbs_envs.envs.swingup import Q_UP
from mbs_envs.envs.swingup_v2 import DEFAULT_WEIGHTS, REGION_Q, REGION_R
from mbs_envs.envs.upright import upright_linearization

V2 = ["mbs_envs/Acrobot-v2", "mbs_envs/Pendubot-v2", "mbs_envs/AcrobotDFKI-v2", "mbs_envs/PendubotDFKI-v2"]
X_UP = np.concatenate([Q_UP, np.zeros(2)])


def riccati(env) -> np.ndarray:
    """``S`` by SciPy's Riccati solver (the env takes python-control's ``lqr``)."""
    A, B = upright_linearization(env.unwrapped.model)
    return scipy.linalg.solve_continuous_are(A, B, REGION_Q, REGION_R)


def rate_formula(env, q, v, a, weights=DEFAULT_WEIGHTS) -> np.ndarray:
    """The reward rate [1/s] written out from the module docstring; ``q, v`` (N, 2), ``a`` (N,); ``weights`` seven,
    or eight with ``w_p`` last."""
    w_e, w_v1, w_v2, w_u, w_line, w_region, w_hold, w_p = (*weights, 0.0)[:8]
    u = a * env.unwrapped.u_max[0]
    v_d = v[:, env.unwrapped.driven]
    p = env.unwrapped.model.params
    e = np.mod(q - Q_UP + np.pi, 2 * np.pi) - np.pi
    x = np.concatenate([e, v], axis=1)
    cost = np.einsum("bi,ij,bj->b", x, riccati(env), x)
    h = (p.l1 * np.sin(q[:, 0]) + p.l2 * np.sin(q[:, 0] + q[:, 1])) / (p.l1 + p.l2)
    return (-w_e * (e**2).sum(1) - w_v1 * v[:, 0] ** 2 - w_v2 * v[:, 1] ** 2 - w_u * a**2
            + w_line * (h >= 0.8) + w_region * (cost < env.unwrapped.region_level)
            + w_hold * np.all(np.abs(e) <= 0.1, axis=1) - w_p * np.abs(u * v_d))  # fmt: skip


def state_reward(env_id: str, q, v, a: float = 0.0, dt: float = 1e-9, **kwargs) -> tuple[float, dict]:
    """The reward of one step of ~0 length from ``(q, v)``: the state's ``dt * rate``."""
    env = gym.make(env_id, dt=dt, substeps=1, integrator="rk4", **kwargs)
    env.reset(options={"q": np.asarray(q, float), "v": np.asarray(v, float)})
    _, r, _, _, info = env.step(np.array([a], np.float32))
    return r, info


@pytest.mark.parametrize("env_id", V2)
def test_the_reward_is_dt_times_the_written_rate(env_id):
    env = gym.make(env_id)
    rng = np.random.default_rng(3)
    n = 200
    # states around upright (inside and outside the region), across the circle, and fast ones
    scale = 10.0 ** rng.uniform(-3, -0.5, (n // 2, 1))  # near upright at every scale: the region is thin
    q = np.concatenate([Q_UP + scale * rng.normal(0, 1, (n // 2, 2)), rng.uniform(-np.pi, np.pi, (n // 2, 2))])
    v = np.concatenate([scale * rng.normal(0, 3, (n // 2, 2)), rng.normal(0, 8.0, (n // 2, 2))])
    a = rng.uniform(-1, 1, n)
    task = env.unwrapped.task_params
    from mbs_envs.envs.swingup_v2 import task_rows

    rows = task_rows(task, q, v, a[:, None])
    rate = rate_formula(env, q, v, a)
    inside = rows[:, 9] > 0
    assert 10 <= inside.sum() <= n // 2  # the sample reaches into the region and out of it
    np.testing.assert_allclose(rows[:, 0], env.unwrapped.dt * rate, rtol=1e-12, atol=1e-12)
    # the terms add up to the reward
    held = rows[:, 10] > 0
    assert (held & ~inside).any()  # the angles within the tolerance at any rates: not all in the region
    np.testing.assert_allclose(rows[:, [1, 2, 3, 8, 9, 10]].sum(1), rows[:, 0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("env_id", V2)
def test_the_optional_power_term_is_the_written_rate(env_id):
    """An eighth weight adds ``- w_p |u v_d|`` to the effort term and nothing else; an eighth weight of 0 is the
    registered reward, bit for bit."""
    from mbs_envs.envs.swingup_v2 import task_rows

    rng = np.random.default_rng(5)
    n = 200
    q = rng.uniform(-np.pi, np.pi, (n, 2))
    v = rng.normal(0, 4.0, (n, 2))
    a = rng.uniform(-1, 1, n)
    weights = (*DEFAULT_WEIGHTS, 70.0)
    env = gym.make(env_id, reward_weights=weights)
    base = gym.make(env_id)
    rows = task_rows(env.unwrapped.task_params, q, v, a[:, None])
    rows0 = task_rows(base.unwrapped.task_params, q, v, a[:, None])
    dt = env.unwrapped.dt
    np.testing.assert_allclose(rows[:, 0], dt * rate_formula(env, q, v, a, weights), rtol=1e-12, atol=1e-12)
    # only the effort term moves, by dt * w_p * |power|, the power as info reports it
    extra = dt * 70.0 * np.abs(rows[:, 7])
    np.testing.assert_allclose(rows[:, 3], rows0[:, 3] - extra, rtol=1e-12, atol=1e-12)
    assert np.array_equal(rows[:, [1, 2, 4, 5, 6, 7, 8, 9, 10]], rows0[:, [1, 2, 4, 5, 6, 7, 8, 9, 10]])
    assert (extra > 0).all()
    # through step: the episode's sum of the term is w_p times the motor's energy, sum |u v_d| dt at the step's start
    env.reset(seed=2)
    base.reset(seed=2)
    for k in range(30):
        act = np.array([np.cos(0.2 * k)], np.float32)
        _, r, *_, info = env.step(act)
        _, r0, *_, info0 = base.step(act)
        assert np.array_equal(info["power"], info0["power"])
        assert r == pytest.approx(r0 - dt * 70.0 * abs(info["power"]), rel=0, abs=1e-12)
    # an eighth weight of 0: the registered reward and dynamics, step for step
    e7, e8 = gym.make(env_id), gym.make(env_id, reward_weights=(*DEFAULT_WEIGHTS, 0.0))
    e7.reset(seed=4)
    e8.reset(seed=4)
    for k in range(50):
        act = np.array([np.sin(0.3 * k)], np.float32)
        o7, r7, *_ = e7.step(act)
        o8, r8, *_ = e8.step(act)
        assert r7 == r8 and np.array_equal(o7, o8)


@pytest.mark.parametrize("env_id", V2[:2])
def test_the_return_does_not_depend_on_the_control_step(env_id):
    r1, _ = state_reward(env_id, Q_UP + [0.3, -0.2], [1.0, -2.0], 0.5, dt=1e-9)
    r2, _ = state_reward(env_id, Q_UP + [0.3, -0.2], [1.0, -2.0], 0.5, dt=2e-9)
    assert r2 == pytest.approx(2 * r1, rel=1e-6)  # the state moves by ~1e-9 in the longer step


@pytest.mark.parametrize("env_id", V2)
def test_only_the_region_pays_the_big_bonus(env_id):
    r_up, info = state_reward(env_id, Q_UP, [0.0, 0.0])
    assert info["upright"] and info["reward_region"] > 0 and info["reward_line"] > 0 and info["reward_hold"] > 0
    assert r_up / 1e-9 == pytest.approx(1050.0, abs=1e-6)  # 50 + 500 + 500, nothing to pay
    # at rest with the elbow bent 0.15 rad and the shoulder where the cost-to-go is least: inside the region, outside
    # the success tolerance, so without the hold bonus
    S = riccati(gym.make(env_id))
    e = np.array([-S[0, 1] / S[0, 0] * 0.15, 0.15])
    r_bent, info = state_reward(env_id, Q_UP + e, [0.0, 0.0])
    assert info["reward_region"] > 0 and not info["upright"] and info["reward_hold"] == 0
    assert r_bent / 1e-9 == pytest.approx(550 - 5 * e @ e, abs=1e-6)
    # straight up but spinning: above the line, outside the region
    r_spin, info = state_reward(env_id, Q_UP, [6.0, 0.0])
    assert info["reward_region"] == 0 and info["reward_line"] > 0 and info["reward_hold"] > 0
    assert r_spin / 1e-9 == pytest.approx(550 - 0.02 * 36, abs=1e-6)  # the line and the hold, no region
    # hanging at rest: only the distance costs
    r_down, info = state_reward(env_id, -Q_UP, [0.0, 0.0])
    assert info["reward_region"] == info["reward_line"] == 0
    assert r_down / 1e-9 == pytest.approx(-5 * np.pi**2, rel=1e-9)


@pytest.mark.parametrize("env_id", V2)
def test_the_registered_region_level_is_caught_by_the_saturated_lqr(env_id):
    """Fresh states below the registered level are caught by ``u = clip(-K x)`` on the env's own map (within 0.1 of
    upright after 3 s, never leaving twice the saturation bound); and the level is not far below what a fresh
    estimate gives (another seed; within 30 %, the estimate's own spread between seeds being about 10 %)."""
    from mbs_envs.controllers.catch_region import saturation_bound
    from mbs_envs.envs.upright import upright_lqr

    env = gym.make(env_id).unwrapped
    K, S = upright_lqr(env.model, REGION_Q, REGION_R)
    np.testing.assert_allclose(S, riccati(gym.make(env_id)), rtol=1e-8)
    A, B = upright_linearization(env.model)
    u = float(env.u_max[0])
    box = np.minimum(2 * saturation_bound(A, B, u), [np.pi / 2, np.pi, 20, 40])
    level = env.region_level
    rng = np.random.default_rng(7)
    draw = rng.uniform(-1, 1, (2_000_000, 4)) * box
    inside = draw[np.einsum("bi,ij,bj->b", draw, S, draw) < level][:300]
    assert len(inside) == 300
    err = closed_loop_final([PlantCase(env.model)], X_UP + inside, X_UP, K, u, env.dt, env.substeps,
                            int(round(3.0 / env.dt)), box)  # fmt: skip
    assert np.all(np.abs(err) <= 0.1)
    estimate, details = estimate_region([PlantCase(env.model)], X_UP, K, S, u, env.dt, env.substeps, box,
                                        samples=800, horizon=3.0, seed=5)  # fmt: skip
    assert not details["bounded_by_box"] and level <= 1.3 * estimate and estimate <= 1.6 * level


@pytest.mark.parametrize("env_id", V2)
def test_vector_and_numpy_paths_pay_the_same(env_id):
    rng = np.random.default_rng(0)
    env, ref = gym.make(env_id), gym.make(env_id, compiled=False)
    env.reset(seed=9)
    ref.reset(seed=9)
    for _ in range(40):
        a = rng.uniform(-1, 1, 1).astype(np.float32)
        _, r1, _, _, i1 = env.step(a)
        _, r2, _, _, i2 = ref.step(a)
        assert r1 == pytest.approx(r2, abs=1e-12)
        for k in ("reward_upright", "reward_rates", "reward_effort", "reward_line", "reward_region", "reward_hold"):
            assert i1[k] == pytest.approx(i2[k], abs=1e-12)
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=[11, 12, 13])
    actions = rng.uniform(-1, 1, (3, 1)).astype(np.float32)
    _, r, _, _, _ = venv.step(actions)
    for i, s in enumerate([11, 12, 13]):
        e = gym.make(env_id)
        e.reset(seed=s)
        assert e.step(actions[i])[1] == pytest.approx(r[i], abs=1e-12)


@pytest.mark.parametrize("env_id", V2[:2])
def test_bad_settings_are_refused(env_id):
    with pytest.raises(ValueError, match="hold_bonus"):
        gym.make(env_id, hold_bonus=1.0)
    with pytest.raises(ValueError, match="reward_weights"):
        gym.make(env_id, reward_weights=(1.0, 0.05, 0.01))
    with pytest.raises(ValueError, match="reward_weights"):
        gym.make(env_id, reward_weights=(5, 0.02, 0.015, 10, 50, 500, -1))
    with pytest.raises(ValueError, match=r"reward_weights must have shape \(7,\) or \(8,\)"):
        gym.make(env_id, reward_weights=(5, 0.02, 0.015, 10, 50, 500, 500, 1, 1))
    for bad in (np.nan, -1.0, np.inf):
        with pytest.raises(ValueError, match="reward_weights"):
            gym.make(env_id, reward_weights=(5, 0.02, 0.015, 10, 50, 500, 500, bad))
    with pytest.raises(ValueError, match="region_level"):
        gym.make(env_id, region_level=-1.0)
    with pytest.raises(ValueError, match="line_height"):
        gym.make(env_id, line_height=2.0)
    env = gym.make(env_id)
    env.reset(seed=0)
    before = env.unwrapped.task_params
    with pytest.raises(ValueError, match="region_level"):
        env.unwrapped.region_level = np.nan
    assert env.unwrapped.task_params is before  # a refused setting leaves the task as it was
    with pytest.raises(ValueError, match="reward_weights"):
        env.unwrapped.reward_weights = np.zeros(9)
    assert env.unwrapped.task_params is before
    # a plant given by preset has its own measured level; the defaults are the scene's
    assert gym.make(env_id, preset="dfki_c1").unwrapped.region_level != env.unwrapped.region_level


def test_the_protocol_training_ids_are_the_protocol_plant():
    for robot in ("Acrobot", "Pendubot"):
        new, old = gym.make(f"mbs_envs/{robot}DFKI-v2"), gym.make(f"mbs_envs/{robot}DFKI-v1")
        assert new.unwrapped.model.params == old.unwrapped.model.params
        assert (new.unwrapped.dt, new.unwrapped.u_max[0], new.spec.max_episode_steps) == (
            old.unwrapped.dt, old.unwrapped.u_max[0], old.spec.max_episode_steps)  # fmt: skip
        a = np.array([0.7], np.float32)
        new.reset(seed=0)
        old.reset(seed=0)
        for _ in range(20):
            o1 = new.step(a)[0]
            o2 = old.step(a)[0]
        np.testing.assert_array_equal(o1, o2)  # the same motion: only the reward differs
