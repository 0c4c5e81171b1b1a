"""The 2R arm's base parameters, their energy-balance identification, the batched Riccati solver and the
adaptive swing-up + LQR built on them (controllers/identification.py, controllers/adaptive_swingup.py)."""

import control
import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import AdaptiveSwingUpLQR, SwingUpLQR
from mbs_envs.controllers import identification as ident
from mbs_envs.controllers.base import care, linearize
from mbs_envs.controllers.swingup import upright_linearization
from mbs_envs.controllers.tuned import tuned_gains
from mbs_envs.envs.swingup import Q_UP
from mbs_envs.models import Planar2R
from mbs_envs.studies.comparison import Condition, plant_kwargs


def random_arms(rng, n):
    """``n`` random physical 2R arms (Planar2R), masses 0.2-5 kg, lengths 0.2-2 m, COM anywhere on the link."""
    arms = []
    for _ in range(n):
        m1, m2, l1, l2 = rng.uniform(0.2, 5.0), rng.uniform(0.2, 5.0), rng.uniform(0.2, 2.0), rng.uniform(0.2, 2.0)
        r1, r2 = rng.uniform(0.0, 1.0) * l1, rng.uniform(0.05, 1.0) * l2
        I1, I2 = rng.uniform(0.0, 0.2) * m1 * l1**2, rng.uniform(0.0, 0.2) * m2 * l2**2
        arms.append(Planar2R(params=dict(m1=m1, m2=m2, l1=l1, l2=l2, r1=r1, r2=r2, I1=I1, I2=I2), driven=(1,)))
    return arms


def test_energy_is_linear_in_the_base_parameters():
    rng = np.random.default_rng(0)
    for arm in random_arms(rng, 20):
        q, v = rng.uniform(-4, 4, (50, 2)), rng.uniform(-10, 10, (50, 2))
        E = arm.energy(q, v)
        assert np.allclose(
            ident.energy_regressor(q, v) @ ident.base_parameters(arm.params),
            E,
            rtol=1e-12,
            atol=1e-12 * np.abs(E).max(),
        )


def test_a_model_from_base_parameters_has_the_same_dynamics():
    """Any physical arm -> th -> masses, lengths, inertias of the gauge: M, h, G, energy, forward dynamics equal."""
    rng = np.random.default_rng(1)
    arms = random_arms(rng, 30)
    th = np.array([ident.base_parameters(a.params) for a in arms])
    assert not np.isnan(ident.gauge(th, 9.81)).any()
    model = ident.identified_model(th, Planar2R(driven=(1,)))
    q, v, u = rng.uniform(-4, 4, (30, 2)), rng.uniform(-10, 10, (30, 2)), rng.uniform(-10, 10, (30, 1))
    for name, args in (
        ("mass_matrix", (q,)),
        ("bias", (q, v)),
        ("gravity", (q,)),
        ("energy", (q, v)),
        ("forward_dynamics", (q, v, u)),
    ):
        got = getattr(model, name)(*args)
        want = np.array([getattr(a, name)(*(x[i] for x in args)) for i, a in enumerate(arms)])
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max()), name
    p = ident.params_from_base(th, Planar2R().params)
    assert all((p[k] >= 0).all() for k in p) and all((p[k] > 0).all() for k in ("m1", "m2", "l1"))


@pytest.mark.parametrize("th", [[1.0, 0.5, -0.1, 14.7, 4.9], [1.0, 0.5, 0.3, 14.7, 0.0], [0.1, 0.5, 0.3, 14.7, 4.9],
                                [1.0, 0.5, 0.3, 1.0, 4.9], [np.nan, 0.5, 0.3, 14.7, 4.9]])  # fmt: skip
def test_base_parameters_of_no_physical_arm_are_refused(th):
    """th3 < 0, th5 = 0, th1 th3 < th2^2 (M not positive definite), m1 r1 < 0, NaN."""
    th = np.array(th)
    assert np.isnan(ident.gauge(th, 9.81))
    with pytest.raises(ValueError, match="th"):
        ident.params_from_base(th, Planar2R().params)


@pytest.mark.parametrize("driven", [(1,), (0,)])
@pytest.mark.parametrize("r", [1e-3, 1.0, 1e3, 1e5])
def test_batched_riccati_solution_matches_python_control(driven, r):
    A, B = upright_linearization(Planar2R(driven=driven))
    Q, R = np.diag([10.0, 10.0, 1.0, 1.0]), np.array([[r]])
    K0, S0, _ = control.lqr(A, B, Q, R)
    K, S = care(np.stack([A, 2 * A, A]), B, Q, R)
    terms = (A.T @ S[0], S[0] @ A, -S[0] @ B @ np.linalg.inv(R) @ B.T @ S[0], Q)
    # the residual against the largest of the terms it sums (their rounding is its floor; measured against |S| alone
    # it was 1.4e-12 on an AMD EPYC at r = 1e-3, where |S A| is 5x |S|, and 0.3e-12 against the terms)
    assert np.abs(sum(terms)).max() <= 1e-12 * max(np.abs(t).max() for t in terms)
    # python-control's own residual is up to 3e-7 relative at r = 1e5 (S spans 1e-1 to 1e7): agree to that
    assert np.allclose(S[0], S0, rtol=1e-6, atol=1e-6 * np.abs(S0).max()) and np.allclose(
        K[0], K0, rtol=1e-6, atol=1e-6 * np.abs(K0).max()
    )
    assert np.array_equal(S[0], S[2])
    K1, S1 = care(2 * A, B, Q, R)
    assert np.allclose(S[1], S1, rtol=1e-13, atol=1e-13 * np.abs(S1).max())
    assert np.linalg.eigvals(A - B @ K[0]).real.max() < 0


def test_batched_linearization_equals_one_point_at_a_time():
    rng = np.random.default_rng(2)
    arms = random_arms(rng, 5)
    model = ident.identified_model(np.array([ident.base_parameters(a.params) for a in arms]), Planar2R(driven=(1,)))
    A, B = upright_linearization(model, (5,))
    for i, arm in enumerate(arms):
        Ai, Bi = upright_linearization(arm)
        assert np.allclose(A[i], Ai, rtol=1e-12, atol=1e-9) and np.allclose(B[i], Bi, rtol=1e-12, atol=1e-9)
    f = lambda x, u: np.stack([x[..., 1], -x[..., 0] + u[..., 0]], axis=-1)  # noqa: E731
    A2, B2 = linearize(f, rng.normal(size=(3, 4, 2)), np.zeros((3, 4, 1)))
    assert A2.shape == (3, 4, 2, 2) and np.allclose(A2, [[0, 1], [-1, 0]]) and np.allclose(B2, [[0], [1]])


def swing(env_id, scale, policy, seeds, steps=400):
    """States and final policy memory after ``steps`` control steps on the plant scaled by ``scale``."""
    venv = gym.make_vec(env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", autoreset_mode="Disabled",
                        **plant_kwargs(env_id.split("/")[1].split("-")[0], Condition("c", scale)))  # fmt: skip
    obs, _ = venv.reset(seed=seeds)
    state, start = None, np.ones(len(seeds), bool)
    for _ in range(steps):
        action, state = policy.predict(obs, state=state, episode_start=start)
        start[:] = False
        obs, *_ = venv.step(action)
    return venv, state


@pytest.mark.parametrize("env_id", ["mbs_envs/Acrobot-v1", "mbs_envs/Pendubot-v1"])
@pytest.mark.parametrize("scale", [0.8, 1.2])
def test_the_estimate_converges_to_the_plant_and_the_lqr_to_its_own(env_id, scale):
    """Masses and lengths off by +-20 %, a weak prior (1e-3 J^2): after 4 s of swing-up the base parameters
    are within 0.2 % (noise-free float32 observations; RK4's energy error), and the LQR's gain is the true
    plant's within 1 %. (The default prior, 1 J^2, biases the estimate toward the nominal by about 1 % at 4 s
    on the acrobot, decaying as 1 / t: :class:`AdaptiveSwingUpLQR`.) The observations taken as the state
    (no filter: the filter's estimate of a noise-free state lags it a little)."""
    nominal = gym.make(env_id)
    policy = AdaptiveSwingUpLQR(nominal, prior=1e-3, obs_noise=0.0)
    _, state = swing(env_id, scale, policy, [20000, 20001, 20002])
    true = gym.make(env_id, **plant_kwargs(env_id.split("/")[1].split("-")[0], Condition("c", scale))).unwrapped.model
    th_true = ident.base_parameters(true.params)
    th0 = ident.base_parameters(nominal.unwrapped.model.params)
    assert np.abs(th0 / th_true - 1).max() > 0.3  # the prior is far off
    from mbs_envs.controllers.adaptive_swingup import K_, THETA

    assert np.abs(state[:, THETA] / th_true - 1).max() < 2e-3
    oracle = SwingUpLQR(
        gym.make(env_id, **plant_kwargs(env_id.split("/")[1].split("-")[0], Condition("c", scale))), lqr_r=policy.lqr_r
    )
    K = state[:, K_]
    assert np.abs(K - oracle.K.ravel()).max() < 0.01 * np.abs(oracle.K).max()


def test_memory_is_per_member_and_reset_at_episode_start():
    """A batch acts as each member alone; a member whose episode starts gets fresh memory (the others keep theirs)."""
    env_id = "mbs_envs/Acrobot-v1"
    policy = AdaptiveSwingUpLQR(gym.make(env_id))
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    obs, _ = venv.reset(seed=[1, 2, 3])
    states = [None] * 3
    state, start = None, np.ones(3, bool)
    for k in range(60):
        action, state = policy.predict(obs, state=state, episode_start=start)
        for i in range(3):
            a_i, states[i] = policy.predict(obs[i], state=states[i], episode_start=bool(start[i]))
            assert np.array_equal(a_i, action[i]) and np.array_equal(states[i], state[i])
        start[:] = False
        obs, *_ = venv.step(action)
    fresh = policy.initial_state(
        *(np.atleast_2d(x) for x in (policy.decode_observation(obs).q, policy.decode_observation(obs).v))
    )
    _, after = policy.predict(obs, state=state, episode_start=np.array([False, True, False]))
    from mbs_envs.controllers.adaptive_swingup import MODE, U

    kept = np.ones(after.shape[1], bool)
    kept[[MODE, U]] = False  # this step's mode and input
    assert np.array_equal(after[1][kept], fresh[1][kept])
    assert not np.array_equal(after[0][1:26], fresh[0][1:26])


@pytest.mark.parametrize(
    "kwargs",
    [
        {"window": 0},
        {"window": 2.5},
        {"prior": 0.0},
        {"prior": -1.0},
        {"prior": np.nan},
        {"obs_noise": -0.01},
        {"obs_noise": np.inf},
        {"process_noise": (1e-4, 1e-2)},
        {"process_noise": ((1e-4, 0.0), (1e-3, 1e-2))},
        {"process_noise": "big"},
        {"gate": 0.0},
        {"gate": -0.1},
        {"gate": np.nan},
        {"gate": "tight"},
    ],
)
def test_bad_settings_are_refused_by_name(kwargs):
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        AdaptiveSwingUpLQR(gym.make("mbs_envs/Acrobot-v1"), **kwargs)


def test_gains_fall_back_to_the_swing_up_entry_only_without_an_own_entry():
    env = gym.make("mbs_envs/Acrobot-v1")
    base, own = tuned_gains(env, "swing-up + LQR"), tuned_gains(env, "adaptive swing-up + LQR")
    from mbs_envs.controllers import tuned

    table = tuned._table()
    entry = table.get("mbs_envs/Acrobot-v1", {}).get("adaptive swing-up + LQR") or table.get(
        "mbs_envs/Acrobot-v0", {}
    ).get("adaptive swing-up + LQR")
    assert own == (entry if entry is not None else base)
    saved = dict(table)
    try:  # without an own entry: the swing-up + LQR's
        for key in ("mbs_envs/Acrobot-v1", "mbs_envs/Acrobot-v0"):
            table[key] = {k: v for k, v in table.get(key, {}).items() if k != "adaptive swing-up + LQR"}
        assert tuned_gains(env, "adaptive swing-up + LQR") == base
    finally:
        table.clear()
        table.update(saved)
    assert AdaptiveSwingUpLQR(env).catch == own["catch"]


def test_upright_energy_of_the_identified_model_is_the_plants():
    """The pumping aims at the plant's own upright energy V(q_up) = th4 + th5."""
    rng = np.random.default_rng(3)
    arms = random_arms(rng, 4)
    th = np.array([ident.base_parameters(a.params) for a in arms])
    model = ident.identified_model(th, Planar2R(driven=(1,)))
    V = model.potential_energy(np.broadcast_to(Q_UP, (4, 2)))
    assert np.allclose(V, th[:, 3] + th[:, 4], rtol=1e-13)


class LinearPlant:
    """``q'' = -w^2 q - 2 z w v + u`` per coordinate (two coordinates, both driven): a linear control map."""

    nu = 2

    def forward_dynamics(self, q, v, u):
        return -4.0 * q - 0.4 * v + u


def test_the_filter_converges_to_the_steady_kalman_filter_on_a_noisy_linear_plant():
    """Gain and covariance equal the discrete Riccati equation's (1e-10); the empirical error covariance over
    20,000 steps equals the filter's own within sampling error (10 %), and is below the observation noise."""
    import scipy.linalg

    from mbs_envs.controllers.control_map import rk4_map
    from mbs_envs.controllers.estimator import ekf_step, map_jacobian

    plant, dt = LinearPlant(), 0.01
    Ad = map_jacobian(plant, np.zeros((1, 4)), np.zeros((1, 2)), dt, 2)[1][0]
    Q_w, R_n = np.diag([1e-6, 1e-6, 1e-4, 1e-4]), 1e-4 * np.eye(4)
    P_pred = scipy.linalg.solve_discrete_are(Ad.T, np.eye(4), Q_w, R_n)
    rng = np.random.default_rng(4)
    B = 64
    x = rng.normal(0, 0.1, (B, 4))
    xh, P = x + rng.normal(0, 1e-2, (B, 4)), np.tile(R_n, (B, 1, 1))
    errors = []
    for k in range(20000 // B * 4):
        u = rng.normal(0, 1.0, (B, 2))
        x = rk4_map(plant, x, u, dt, 2) + rng.multivariate_normal(np.zeros(4), Q_w, B)
        y = x + rng.normal(0, 1e-2, (B, 4))
        xh, P = ekf_step(plant, xh, P, u, y, dt, 2, Q_w, R_n)
        if k > 100:
            errors.append(xh - x)
    assert np.allclose(Ad @ P[0] @ Ad.T + Q_w, P_pred, rtol=1e-10, atol=1e-10 * np.abs(P_pred).max())
    e = np.concatenate(errors)
    C = e.T @ e / len(e)
    assert np.allclose(np.diag(C), np.diag(P[0]), rtol=0.1)
    assert (np.diag(C)[:2] < 0.2 * np.diag(R_n)[:2]).all() and (np.diag(C)[2:] < np.diag(R_n)[2:]).all()


def test_the_filter_follows_the_nonlinear_arm_through_a_swing_up():
    """Acrobot, noise 0.01 on every observation entry: the estimate's angle error stays well below the noise."""
    env_id = "mbs_envs/Acrobot-v1"
    policy = AdaptiveSwingUpLQR(gym.make(env_id))
    venv = gym.make_vec(env_id, num_envs=8, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    obs, _ = venv.reset(seed=list(range(20000, 20008)))
    rng = np.random.default_rng(5)
    state, start, err = None, np.ones(8, bool), []
    from mbs_envs.controllers.adaptive_swingup import XH

    for k in range(300):
        seen = obs + rng.normal(0, 0.01, obs.shape).astype(np.float32)
        action, state = policy.predict(seen, state=state, episode_start=start)
        start[:] = False
        if k > 20:
            err.append(np.abs(((state[:, XH][:, :2] - venv.unwrapped._q) + np.pi) % (2 * np.pi) - np.pi))
        obs, *_ = venv.step(action)
    err = np.array(err)
    assert np.sqrt(np.mean(err**2)) < 0.6 * 0.01


def test_without_the_filter_the_observation_is_the_state():
    """With ``obs_noise = 0`` the filter's memory does not enter the action; with the filter it does."""
    env_id = "mbs_envs/Acrobot-v1"
    from mbs_envs.controllers.adaptive_swingup import XH

    for obs_noise, enters in ((0.0, False), (0.01, True)):
        policy = AdaptiveSwingUpLQR(gym.make(env_id), obs_noise=obs_noise)
        venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
        obs, _ = venv.reset(seed=[0, 1])
        state, start = None, np.ones(2, bool)
        for _ in range(5):  # early in the swing-up, where the input is not saturated
            action, state = policy.predict(obs, state=state, episode_start=start)
            start[:] = False
            obs, *_ = venv.step(action)
        moved = state.copy()
        moved[:, XH] += [0.05, -0.05, 0.5, -0.5]
        a0, _ = policy.predict(obs, state=state, episode_start=start)
        a1, _ = policy.predict(obs, state=moved, episode_start=start)
        assert np.abs(a0).max() < 1.0 and (not np.array_equal(a0, a1)) == enters


@pytest.mark.parametrize("scale", [0.8, 1.0, 1.2])
def test_it_balances_from_near_upright_on_every_plant_of_the_tuning_set(scale):
    """Started 0.005 rad off upright at rest (inside the nominal LQR's catch along q1 on every plant of the
    set, 0.016 rad at +20 %: the report's catch table), with no motion to identify from yet (the nominal
    model's LQR, which stabilizes the +-20 % plants' linearizations), noise-free observations through the
    filter (whose estimate, on the nominal model of a +-20 % plant, converges more slowly: 2.5e-3 rad after
    6 s at +20 %, against 1e-6 unfiltered); from 0.5 rad off it does not take the LQR."""
    env_id = "mbs_envs/Acrobot-v1"
    env = gym.make(env_id, **plant_kwargs("Acrobot", Condition("c", scale)))
    ctrl = AdaptiveSwingUpLQR(gym.make(env_id))
    obs, _ = env.reset(options={"q": Q_UP + [0.5, -0.5], "v": [0.0, 0.0]})
    assert ctrl.predict(obs, episode_start=True)[1][0] == 0.0
    obs, _ = env.reset(options={"q": Q_UP + [0.005, -0.005], "v": [0.0, 0.0]})
    state, start, err = None, True, []
    for _ in range(600):
        action, state = ctrl.predict(obs, state=state, episode_start=start)
        start = False
        obs, *_, info = env.step(action)
        err.append(np.max(np.abs(info["tracking_error"])))
    assert state[0] > 0.5 and info["upright"] and max(err[-100:]) < 5e-3 and max(err[-100:]) < 0.5 * max(err[100:200])


def test_riccati_of_an_unstabilizable_member_is_nan_and_leaves_the_others():
    A_ok, B = upright_linearization(Planar2R(driven=(1,)))
    A_bad = np.diag([1.0, -1.0, -2.0, -3.0])  # its unstable mode is not reached by B
    B_bad = np.array([[0.0], [1.0], [1.0], [1.0]])
    Q, R = np.diag([10.0, 10.0, 1.0, 1.0]), np.array([[1.0]])
    K, S = care(np.stack([A_ok, A_bad, A_ok]), np.stack([B, B_bad, B]), Q, R)
    assert np.isnan(K[1]).all() and np.isnan(S[1]).all()
    K0, S0 = care(A_ok, B, Q, R)
    assert np.array_equal(K[0], K0) and np.array_equal(K[2], K0) and np.isfinite(K0).all()


def test_a_lost_filter_restarts_from_the_observation():
    """A non-finite or far-off estimate in the memory (e.g. a plant far from the identified model) is replaced
    by the observation, and the input stays finite."""
    env_id = "mbs_envs/Acrobot-v1"
    policy = AdaptiveSwingUpLQR(gym.make(env_id))
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode="Disabled")
    obs, _ = venv.reset(seed=[0, 1, 2])
    _, state = policy.predict(obs, episode_start=np.ones(3, bool))
    from mbs_envs.controllers.adaptive_swingup import XH

    state[0, XH] = np.nan
    state[1, XH] = state[1, XH] + [3.0, 0.0, 50.0, 0.0]
    action, new = policy.predict(obs, state=state, episode_start=np.zeros(3, bool))
    decoded = policy.decode_observation(obs)
    y = np.concatenate([decoded.q, decoded.v], 1)
    assert np.isfinite(action).all() and np.array_equal(new[:2, XH], y[:2])
    assert np.abs(new[2, XH] - y[2]).max() < 0.05


@pytest.mark.parametrize("delay", [0, 1])
def test_a_one_step_input_delay_is_detected_and_identified_through(delay):
    """The plant applies the input chosen ``delay`` steps earlier: the energy balance under the right hypothesis fits
    (its residuals are the smaller), the estimate is the plant's, and the filter predicts with the applied input."""
    from mbs_envs.controllers.adaptive_swingup import THETA

    env_id = "mbs_envs/Acrobot-v1"
    policy = AdaptiveSwingUpLQR(gym.make(env_id), obs_noise=0.0)
    plant = gym.make(env_id, **plant_kwargs("Acrobot", Condition("c", 1.2)))
    th_true = ident.base_parameters(plant.unwrapped.model.params)
    obs, _ = plant.reset(seed=3)
    state, queue = None, [np.zeros(1, np.float32)] * delay
    for k in range(300):
        action, state = policy.predict(obs, state=state, episode_start=k == 0)
        queue.append(action)
        obs, *_ = plant.step(queue.pop(0))
    row = state[None]
    assert bool(policy.delayed(row)[0]) == bool(delay)
    # what remains at 3 s is the prior's bias (1.2 % on this plant with or without the delay; it decays as 1 / t);
    # with the commanded input taken as applied the delayed plant's estimate was off by 5-20 %
    assert np.abs(state[THETA] / th_true - 1).max() < 0.015


def test_the_gate_takes_every_window_a_plant_within_it_explains_and_no_push_beyond():
    """:func:`ident.explained` is exact both ways: a plant within ``gate`` of the estimate in every base parameter
    (relative to the estimate) always passes; a window carrying external work ``X`` with
    ``|X| (1 - gate) > gate (|W| + sum |d th|)`` (its residual then exceeds the gate's bound, which counts ``X`` in the
    work) never does; without a gate every window passes."""
    rng = np.random.default_rng(3)
    for arm in random_arms(rng, 30):
        th_true = ident.base_parameters(arm.params)
        q0, v0 = rng.uniform(-4, 4, (40, 2)), rng.uniform(-8, 8, (40, 2))
        q1, v1 = q0 + rng.normal(0, 0.05, (40, 2)), v0 + rng.normal(0, 0.5, (40, 2))
        d = ident.energy_regressor(q1, v1) - ident.energy_regressor(q0, v0)
        work = d @ th_true  # the energy balance of the true plant, exactly
        for gate in (0.05, 0.25, 0.5):
            th = th_true / (1 + rng.uniform(-gate, gate, (40, 5)))  # th_true within gate of th, relative to th
            r = work - np.einsum("bi,bi->b", d, th)
            assert ident.explained(r, work, d, th, gate).all()
            X = np.where(r < 0, -1.0, 1.0) * 1.01 * gate * (np.abs(work) + np.abs(d * th).sum(axis=1)) / (1 - gate)
            w2 = work + X
            r2 = w2 - np.einsum("bi,bi->b", d, th)
            assert (np.abs(r2) > gate * (np.abs(w2) + np.abs(d * th).sum(axis=1))).all()
            assert not ident.explained(r2, w2, d, th, gate).any()
            assert ident.explained(r2, w2, d, th, np.inf).all()


def test_a_push_does_not_bias_the_gated_estimate_and_a_batch_of_gates_acts_as_each_alone():
    """The DFKI pendubot (its nominal plant, the prior exact) pushed on its passive joint (-3 N m, a Gaussian pulse of
    0.05 s at 1.2 s): without the gate the base parameters end 23 % off, with a gate of 0.1 within 0.7 % (measured;
    bounds 10 % and 1 %). Members with different gates (:func:`mbs_envs.studies.dfki_tuning.with_member_gains`) move
    as each alone, to 1e-12."""
    from mbs_envs.controllers.adaptive_swingup import THETA
    from mbs_envs.studies.dfki_tuning import MEMBER_GAINS, with_member_gains
    from mbs_envs.studies.robustness import Perturbation, run

    env_id, steps, dt = "mbs_envs/PendubotDFKI-v1", 1000, 0.002
    env = gym.make(env_id)
    t = np.arange(steps) * dt
    push = np.zeros((1, steps, 2))
    push[0, :, 1] = -3.0 * np.exp(-0.5 * ((t - 1.2) / 0.05) ** 2)
    th_true = ident.base_parameters(env.unwrapped.model.params)
    entries = [{"gate": g} for g in (None, 0.1, 0.25)]

    def rollout(policy, n):
        states = []

        class Logged:
            def predict(self, obs, state=None, episode_start=None, deterministic=True):
                a, s = policy.predict(obs, state=state, episode_start=episode_start)
                states.append(np.array(s, copy=True))
                return a, s

        venv = gym.make_vec(
            env_id,
            num_envs=n,
            vectorization_mode="vector_entry_point",
            autoreset_mode="Disabled",
            max_episode_steps=steps,
        )
        res = run(venv, Logged(), list(range(n)), Perturbation(pulses=np.repeat(push, n, axis=0)), noise_seed=0)
        return res, np.array(states).reshape(len(states), n, -1)

    policy = AdaptiveSwingUpLQR(env)  # the protocol's entry
    gains = {k: float(getattr(policy, k)) for k in MEMBER_GAINS}
    batch, S = rollout(with_member_gains(policy, [{**gains, **e} for e in entries]), 3)
    err = np.abs(S[-1, :, THETA] / th_true - 1).max(axis=1)
    assert err[0] > 0.1 and err[1] < 0.01
    for i, e in enumerate(entries):
        alone, S1 = rollout(AdaptiveSwingUpLQR(env, **e), 1)
        np.testing.assert_allclose(batch["q"][i], alone["q"][0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(S[:, i], S1[:, 0], rtol=0, atol=1e-12)
