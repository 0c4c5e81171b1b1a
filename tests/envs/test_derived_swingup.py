"""The swing-up task on derived underactuated models (mbs_envs.envs.derived_swingup) and its model-based baseline.

Checked against independent things: a derived acrobot's episodes against the hand-written ``Acrobot-v1``'s (the same
plant, starts and error terms), the cart-pole's height against its closed form ``cos th``, the compiled step
against the numpy one, the rail's penalty against the worst in-bounds return, and the controller's collocated input
against the forward dynamics it must produce.
"""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

import mbs_envs  # noqa: F401  (registers the ids)
from mbs_envs.envs import derived as derived_env
from mbs_envs.envs.cart_pole import CartPole, th, x
from mbs_envs.envs.derived_swingup import DerivedSwingUpEnv, task_rows
from mbs_envs.models import Planar2R, symbolic

ID = "mbs_envs/CartPoleSwingUp-v0"
t = dynamicsymbols._t


@pytest.fixture(scope="module")
def derived_acrobot(tmp_path_factory):
    """The 2R arm from its Lagrangian with only the elbow driven, at Planar2R's defaults (Acrobot-v1's plant)."""
    q1, q2 = dynamicsymbols("q1 q2")
    p = Planar2R().params
    names = ("m1", "m2", "l1", "l2", "r1", "r2", "I1", "I2", "g")
    m1, m2, l1, l2, r1, r2, I1, I2, g = sp.symbols(names)
    c1 = sp.Matrix([r1 * sp.cos(q1), r1 * sp.sin(q1)])
    c2 = sp.Matrix([l1 * sp.cos(q1) + r2 * sp.cos(q1 + q2), l1 * sp.sin(q1) + r2 * sp.sin(q1 + q2)])
    sq = lambda c: c.diff(t).dot(c.diff(t))  # noqa: E731
    T = (m1 * sq(c1) + I1 * q1.diff(t) ** 2 + m2 * sq(c2) + I2 * (q1.diff(t) + q2.diff(t)) ** 2) / 2
    V = g * (m1 * c1[1] + m2 * c2[1])
    d = symbolic.cached_derivation("Acrobot2R", (q1, q2), T, V, {k: getattr(p, k) for k in names}, actuation=[[0.0], [1.0]],
                                   cache=tmp_path_factory.mktemp("derived"))  # fmt: skip
    tip = (p.l1 * sp.cos(q1) + p.l2 * sp.cos(q1 + q2), p.l1 * sp.sin(q1) + p.l2 * sp.sin(q1 + q2))
    derived_env.register("mbs_envs_test/DerivedAcrobot-v0", symbolic.model_class(d)(), task="swing-up", max_episode_steps=1500,
                         torque_limit=10.0, upright=(np.pi / 2, 0.0), hanging=(-np.pi / 2, 0.0), substeps=2,
                         coordinates=(q1, q2), points=[(0, 0), (p.l1 * sp.cos(q1), p.l1 * sp.sin(q1)), tip])  # fmt: skip
    return "mbs_envs_test/DerivedAcrobot-v0"


def test_a_derived_acrobot_swings_as_acrobot_v1(derived_acrobot):
    """Same seed, same actions: the derived swing-up env's states, distance to upright, upright flags, power and
    error term are the hand-written Acrobot-v1's (1e-10), single and batched, compiled and numpy."""
    ours, theirs = gym.make(derived_acrobot), gym.make("mbs_envs/Acrobot-v1")
    slow = gym.make(derived_acrobot, compiled=False)
    assert ours.unwrapped.compiled is not None and slow.unwrapped.compiled is None
    assert ours.unwrapped.unwrapped.horizon == 1500  # register's max_episode_steps
    a = np.random.default_rng(0).uniform(-1, 1, (150, 1)).astype(np.float32)
    for env in (ours, theirs, slow):
        env.reset(seed=11)
    np.testing.assert_array_equal(ours.unwrapped.q, theirs.unwrapped.q)
    for k in range(150):
        (_, r1, _, _, i1), (_, _, _, _, i2), (_, r3, _, _, i3) = (env.step(a[k]) for env in (ours, theirs, slow))
        for key in ("tracking_error", "upright", "power", "reward_upright"):
            np.testing.assert_allclose(i1[key], i2[key], rtol=0, atol=1e-10, err_msg=key)
        assert abs(r1 - r3) <= 1e-12 * max(1.0, abs(r3))
    np.testing.assert_allclose(ours.unwrapped.q, theirs.unwrapped.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(ours.unwrapped.v, slow.unwrapped.v, rtol=0, atol=1e-12)
    venv = gym.make_vec(derived_acrobot, num_envs=3, vectorization_mode="vector_entry_point")
    vo, _ = venv.reset(seed=[11, 12, 13])
    o1, _ = ours.reset(seed=11)
    np.testing.assert_array_equal(vo[0], o1)
    for k in range(20):
        vo, vr, *_ = venv.step(np.repeat(a[k][None], 3, axis=0))
        o1, r1, *_ = ours.step(a[k])
    np.testing.assert_allclose(vo[0], o1, rtol=0, atol=1e-6)
    assert abs(vr[0] - r1) <= 1e-12


def test_the_cart_poles_height_is_its_closed_form_and_observations_decode():
    env = gym.make(ID).unwrapped
    rng = np.random.default_rng(1)
    q = rng.uniform(-2.4, 2.4, (500, 2)) * np.array([1.0, 3.0])
    v = rng.normal(size=(500, 2)) * 5
    info, obs, _ = task_rows(env.task_params, env.model, q, v, np.full(500, 0.5), np.zeros((500, 1)))
    np.testing.assert_allclose(
        info[:, 1], np.cos(q[:, 1]), rtol=0, atol=1e-12
    )  # h = cos th: the pole's centre's height over l / 2
    dec = env.decode_observation(obs)
    np.testing.assert_allclose(np.cos(dec.q[:, 1] - q[:, 1]), 1.0, atol=1e-6)  # float32 observations
    np.testing.assert_allclose(dec.q[:, 0], q[:, 0], rtol=1e-6)
    np.testing.assert_allclose(dec.v, v, rtol=1e-6, atol=1e-6)
    assert obs.shape == (500, 5) and env.observation_space.shape == (5,)
    p = env.model.params  # docs/physics.md §6c's closed forms
    c, sn = np.cos(q[:, 1]), np.sin(q[:, 1])
    M = np.stack(
        [
            np.stack([np.full(500, p.m0 + p.m), p.m * p.l / 2 * c], -1),
            np.stack([p.m * p.l / 2 * c, np.full(500, p.m * p.l**2 / 3)], -1),
        ],
        -2,
    )
    np.testing.assert_allclose(env.model.mass_matrix(q), M, rtol=1e-12, atol=1e-15)
    h = np.stack(
        [-p.m * p.l / 2 * sn * v[:, 1] ** 2 + p.b_x * v[:, 0], -p.m * p.g * p.l / 2 * sn + p.b_th * v[:, 1]], -1
    )
    np.testing.assert_allclose(env.model.bias(q, v), h, rtol=1e-12, atol=1e-12)


def test_running_off_the_rail_terminates_and_costs_at_least_what_staying_on_it_could():
    """Full force one way: the cart leaves the rail, the episode terminates there with ``r_x = -P k_left``; the
    return so far minus that is no more than the worst return of the steps left inside the bounds, and every
    in-bounds step (states at the bounds' corners, wrapped extremes, saturated actions) loses at most ``P``.
    Compiled and numpy steps agree on all of it."""
    envs = [gym.make(ID), gym.make(ID, compiled=False)]
    results = []
    for env in envs:
        env.reset(seed=3)
        total, k, term = 0.0, 0, False
        while not term:
            _, r, term, trunc, info = env.step(np.ones(1, np.float32))
            total, k = total + r, k + 1
            assert not trunc and k < 1000
        results.append((k, total, info))
    (k, total, info), (k2, total2, info2) = results
    assert k == k2 and abs(total - total2) <= 1e-9 * abs(total2)
    assert info["out_of_bounds"] and not info["diverged"]
    assert envs[0].observation_space.contains(envs[0].unwrapped._observation())  # the last observation, off the rail
    before = envs[0].unwrapped.np_random.bit_generator.state
    with pytest.raises(ValueError, match="outside bounds"):
        envs[0].reset(options={"q": [2.5, np.pi]})
    assert envs[0].unwrapped.np_random.bit_generator.state == before
    p = envs[0].unwrapped.task_params
    assert info["reward_bound"] == pytest.approx(-p.step_loss * (1000 - k), rel=1e-12)
    assert total <= -p.step_loss * (1000 - k) + (k - 1) * (p.weights[0] + p.weights[3])  # the worst continuation
    rng = np.random.default_rng(2)
    corners = np.array([[-2.4, np.pi], [2.4, -np.pi], [-2.4, 0.0], [2.4, np.pi - 1e-9]])
    q = np.concatenate([corners, rng.uniform([-2.4, -10.0], [2.4, 10.0], (5000, 2))])
    act = np.concatenate([np.ones((4, 1)), rng.uniform(-1, 1, (5000, 1))])
    rows, _, out = task_rows(p, envs[0].unwrapped.model, q, np.zeros_like(q), np.full(len(q), 0.5), act)
    assert not out.any() and np.all(rows[:, 0] >= -p.step_loss - 1e-12)
    assert (
        rows[:4, 0].min() >= -p.step_loss - 1e-12 and rows[0, 0] <= -p.step_loss + 0.05
    )  # the bound is nearly attained


def test_bad_swing_up_settings_are_refused_by_name(derived_acrobot):
    model = CartPole()
    kw = dict(torque_limit=10.0, upright=[0.0, 0.0], hanging=[0.0, np.pi], coordinates=[x, th])
    with pytest.raises(ValueError, match=r"bounds: coordinate th\(t\) is an angle"):
        DerivedSwingUpEnv(model, angles=[th], bounds={th: (-1, 1)}, **kw)
    with pytest.raises(ValueError, match=r"bounds\[x\(t\)\].*strictly inside"):
        DerivedSwingUpEnv(model, angles=[th], bounds={x: (0.5, 1.0)}, **kw)
    with pytest.raises(ValueError, match="angles: .* is not one of the coordinates"):
        DerivedSwingUpEnv(model, angles=[sp.Symbol("y")], **kw)
    with pytest.raises(ValueError, match="more potential energy than hanging"):
        DerivedSwingUpEnv(model, **{**kw, "upright": [0.0, np.pi], "hanging": [0.0, 0.0]}, angles=[th])
    with pytest.raises(ValueError, match="underactuated"):
        DerivedSwingUpEnv(
            gym.make("mbs_envs/CartDoublePendulum-v0").unwrapped.model,
            torque_limit=1.0,
            upright=[0, 0, 0],
            hanging=[0, np.pi, 0],
        )
    with pytest.raises(ValueError, match="task must be one of"):
        derived_env.register("mbs_envs_test/Bad-v0", model, task="balance", torque_limit=1.0)
    with pytest.raises(ValueError, match="start_noise = 3 reaches beyond bounds of coordinate 0"):
        DerivedSwingUpEnv(model, angles=[th], bounds={x: (-2.4, 2.4)}, start_noise=3.0, **kw)
    with pytest.raises(ValueError, match="bounds must be a mapping"):
        DerivedSwingUpEnv(model, angles=[th], bounds=[(x, 2.4)], **kw)


def test_the_cart_pole_renders_and_pickles():
    env = gym.make(ID, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(1, np.float32))
    frame = env.render()
    assert frame.shape == (500, 500, 3) and frame.std() > 0
    copy = pickle.loads(pickle.dumps(env.unwrapped))
    np.testing.assert_array_equal(copy.q, env.unwrapped.q)


def test_the_collocated_input_gives_the_commanded_acceleration():
    from mbs_envs.controllers.swingup import collocated_pfl

    model = CartPole()
    rng = np.random.default_rng(4)
    q, v, y = rng.normal(size=(200, 2)) * 3, rng.normal(size=(200, 2)) * 3, rng.normal(size=200) * 10
    u = collocated_pfl(model, q, v, y, 0)
    a = model.forward_dynamics(q, v, u[:, None])
    np.testing.assert_allclose(a[:, 0], y, rtol=1e-12, atol=1e-11)


def test_the_pumping_law_drives_the_poles_energy_to_upright():
    """Without friction and with only the pumping term (k_q = k_v = 0), ``dE_p/dt = -k_E E~ (M_ap v_p)^2 <= 0`` for
    ``E~ > 0`` (module docstring of controllers/energy_swingup.py): checked on the model by the energy's rate
    along the commanded motion."""
    from mbs_envs.controllers.energy_swingup import EnergySwingUpLQR

    env = gym.make(ID, params={"b_x": 0.0, "b_th": 0.0})
    c = EnergySwingUpLQR(env, k_q=0.0, k_v=0.0, k_E=50.0, a_max=1e9)
    model, rng = env.unwrapped.model, np.random.default_rng(5)
    q, v = rng.uniform(-3, 3, (300, 2)), rng.normal(size=(300, 2)) * 3

    def E_p(q, v):
        M = model.mass_matrix(q)
        return 0.5 * M[..., 1, 1] * v[..., 1] ** 2 + model.potential_energy(q)

    u = c.swing_up(q, v)
    a = model.forward_dynamics(q, v, u[:, None])
    h = 1e-6
    rate = (E_p(q + h * v, v + h * a) - E_p(q - h * v, v - h * a)) / (2 * h)
    M = model.mass_matrix(q)
    expected = -50.0 * (E_p(q, v) - c.E_up) * (M[:, 0, 1] * v[:, 1]) ** 2
    np.testing.assert_allclose(
        rate, expected, rtol=1e-6, atol=1e-7
    )  # central differences: O(h^2) and 1e-10 / h round-off
    sat = EnergySwingUpLQR(env, k_q=0.0, k_v=0.0, k_E=50.0, a_max=2.0)  # saturated: the same sign, the pump bounded
    a = model.forward_dynamics(q, v, sat.swing_up(q, v)[:, None])
    rate = (E_p(q + h * v, v + h * a) - E_p(q - h * v, v - h * a)) / (2 * h)
    momentum = M[:, 0, 1] * v[:, 1]
    bounded = -momentum * np.clip(50.0 * (E_p(q, v) - c.E_up) * momentum, -2.0, 2.0)  # dE_p/dt = -(M_ap v_p) y
    np.testing.assert_allclose(rate, bounded, rtol=1e-6, atol=1e-7)


def test_the_energy_controller_swings_the_cart_pole_up_and_holds_it():
    from mbs_envs.controllers import EnergySwingUpLQR
    from mbs_envs.studies.evaluation import rollout_batch, swing_up_metrics

    venv = gym.make_vec(ID, num_envs=4, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    c = EnergySwingUpLQR(gym.make(ID))
    eps = rollout_batch(venv, c, [20000, 20001, 20002, 20003])
    m = [swing_up_metrics(e) for e in eps]
    assert all(x["success"] for x in m), [x["time_to_swing_up"] for x in m]
    assert all(x["time_to_swing_up"] < 8.0 for x in m)
    with pytest.raises(ValueError, match="acts on DerivedSwingUpEnv"):
        EnergySwingUpLQR(gym.make("mbs_envs/Acrobot-v1"))
