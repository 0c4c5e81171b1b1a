"""The O(N) implicit joint step (``joint_implicit_euler``): its solve, its order, its stability, its refusals."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs import integrators, simulate
from mbs_envs.dynamics.inputs import JointPD
from mbs_envs.models import FourBar, Planar2R, SerialChain
from mbs_envs.models.base import Model

NAME = "joint_implicit_euler"


def drives(n: int) -> SerialChain:
    """SerialChain-v0's chain: drives with the rotor inertia of a 30 rad/s^2 full-torque acceleration."""
    return SerialChain(n_links=n, armature=np.abs(SerialChain(n_links=n).gravity(np.zeros(n))) / 30.0)


@pytest.mark.parametrize("n", [1, 2, 7, 40])
def test_the_o_n_shifted_solve_equals_the_dense_one(n):
    """ABA with ``d`` on the armature equals ``(M + diag d)^-1 (tau - C v - G)`` by CRBA and Cholesky."""
    rng = np.random.default_rng(n)
    chain = SerialChain(n_links=n, m=rng.uniform(0.1, 2, n), l=rng.uniform(0.1, 1, n), armature=rng.uniform(0, 0.1, n))
    q, v, tau = rng.normal(size=(3, 5, n)) * np.array([2.0, 3.0, 5.0])[:, None, None]
    d = rng.uniform(0.0, 10.0, (5, n))
    a = chain.shifted_forward_dynamics(q, v, tau, d)
    dense = Model.shifted_forward_dynamics(chain, q, v, tau, d)
    assert np.max(np.abs(a - dense)) <= 1e-12 * max(1.0, np.max(np.abs(dense)))


def test_without_damping_it_is_semi_implicit_euler_exactly():
    """No friction, no PD: ``v+ = v + h a(q, v)``, ``q+ = q + h v+`` -- the symplectic Euler tableau."""
    model = Planar2R()
    u = np.array([0.3, -0.2])
    a = simulate(model, [-1.0, 0.5], [0.4, -0.3], 0.5, dt=0.01, integrator=NAME, u=u)
    b = simulate(model, [-1.0, 0.5], [0.4, -0.3], 0.5, dt=0.01, integrator="semi_implicit_euler", u=u, compiled=False)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-12)


def test_first_order_on_a_damped_driven_chain():
    """Final-state error against DOP853 at 1e-12 halves with the step (observed order 1 +- 0.15;
    friction smoothed over 0.5 rad/s: with the default 0.01 the bare rope is too stiff for DOP853)."""
    chain = SerialChain(n_links=5, b=0.05, f=0.02, v_s=0.5)
    q0, v0 = np.r_[-0.3, np.full(4, 0.3)], np.zeros(5)
    ref = simulate(chain, q0, v0, 1.0, dt=1.0, integrator="dop853", rtol=1e-12, atol=1e-12)
    assert not ref.diverged
    errors = [
        np.max(np.abs(simulate(chain, q0, v0, 1.0, dt=dt, integrator=NAME).q[-1] - ref.q[-1]))
        for dt in (4e-3, 2e-3, 1e-3)
    ]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 1.0) < 0.15), (errors, orders)


def test_the_linear_rotor_is_stable_at_any_step():
    """One free rotor (g = 0) under a joint PD at h omega = 1e3 and with h b / J = 1e3: the exact
    linear recurrence of the step, computed here from the step's equations, and its amplification
    matrix's spectral radius below one."""
    J = 1.0 / 3.0 + 0.5  # uniform rod about its end (m = l = 1) plus armature 0.5
    chain = SerialChain(n_links=1, m=1.0, l=1.0, g=0.0, armature=0.5, b=2.0)
    h, w = 0.01, 1e5
    kp, kd = w * w * J, 0.0
    law = JointPD(kp, kd, 0.2)
    q, v = np.array([1.0]), np.array([3.0])
    for _ in range(200):
        tr = simulate(chain, q, v, h, dt=h, integrator=NAME, u=law)
        q_new, v_new = tr.q[-1], tr.v[-1]
        # (J + h b + h^2 kp) a = kp (q_ref - q - h v) - b v ;  v+ = v + h a ; q+ = q + h v+
        a = (kp * (0.2 - q - h * v) - 2.0 * v) / (J + h * 2.0 + h * h * kp)
        np.testing.assert_allclose(v_new, v + h * a, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(q_new, q + h * (v + h * a), rtol=1e-12, atol=1e-12)
        q, v = q_new, v_new
    s = J + h * 2.0 + h * h * kp  # the step is y+ = R y with
    R = np.array([[1 - h * h * kp / s, h - h * h * (h * kp + 2.0) / s], [-h * kp / s, 1 - h * (h * kp + 2.0) / s]])
    assert np.max(np.abs(np.linalg.eigvals(R))) < 1.0
    assert abs(q[0] - 0.2) < 1e-3


def test_stiff_pd_chain_rk4_diverges_where_the_implicit_step_holds():
    """A 20-link chain under a joint PD of 1000 rad/s bandwidth per joint: RK4 at 10 ms is flagged
    as diverged; the implicit joint step settles on the target (error 1e-5) at the same step."""
    n = 20
    chain = drives(n)
    J = 1.0 / np.diag(np.linalg.inv(chain.mass_matrix(np.r_[-np.pi / 2, np.zeros(n - 1)])))
    target = np.r_[-np.pi / 2 + 0.3, np.zeros(n - 1)]
    law = JointPD(1e6 * J, 2e3 * J, target)
    q0, v0 = np.r_[-np.pi / 2, np.zeros(n - 1)], np.zeros(n)
    assert simulate(chain, q0, v0, 0.5, dt=0.01, integrator="rk4", u=law).diverged
    tr = simulate(chain, q0, v0, 0.5, dt=0.01, integrator=NAME, u=law)
    assert not tr.diverged
    assert np.max(np.abs(tr.q[-1] - target)) < 1e-4


def test_batched_equals_one_by_one():
    chain = drives(6)
    rng = np.random.default_rng(3)
    q, v = rng.normal(size=(4, 6)), rng.normal(size=(4, 6))
    law = JointPD(50.0, 5.0, np.zeros(6))
    batch = simulate(chain, q, v, 0.1, dt=0.01, integrator=NAME, u=law)
    for k in range(4):
        one = simulate(chain, q[k], v[k], 0.1, dt=0.01, integrator=NAME, u=law)
        np.testing.assert_allclose(batch.q[:, k], one.q, rtol=0, atol=1e-13)


def test_in_an_environment_and_its_refusals():
    env = gym.make("mbs_envs/SerialChain-v0", n_links=8, params={"b": 5.0}, integrator=NAME)
    env.reset(seed=0)
    for _ in range(5):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert np.all(np.isfinite(obs)) and not terminated
    with pytest.raises(ValueError, match="unconstrained models"):
        gym.make("mbs_envs/FourBar-v0", integrator=NAME)
    with pytest.raises(ValueError, match="unconstrained models"):
        simulate(FourBar(), *FourBar().consistent_state(0.2, 1.0), 0.1, dt=0.01, integrator=NAME)
    with pytest.raises(ValueError, match="steps a model"):
        integrators.get(NAME).step(lambda t, q, v: q, 0.0, np.zeros(2), np.zeros(2), 0.01)
    with pytest.raises(ValueError, match="takes no options"):
        integrators.get(NAME, rtol=1e-3)
    assert not integrators.applies(NAME, FourBar()) and integrators.applies(NAME, Planar2R())
    for bad in (
        {"kp": -1.0, "kd": 0.0, "q_ref": 0.0},
        {"kp": 1.0, "kd": np.nan, "q_ref": 0.0},
        {"kp": 1.0, "kd": 0.0, "q_ref": np.inf},
    ):
        with pytest.raises(ValueError, match="JointPD"):
            JointPD(**bad)


def test_a_pd_through_a_non_selecting_actuation_is_refused():
    law = JointPD(10.0, 1.0, [0.0, 0.0])
    with pytest.raises(ValueError, match="select joints"):
        law.diagonals(np.array([[1.0, 1.0], [0.0, 1.0]]))
    kp, kd = law.diagonals(np.array([[0.0], [1.0]]) @ np.ones((1, 1)))  # elbow only (an acrobot)
    assert kp.tolist() == [0.0, 10.0] and kd.tolist() == [0.0, 1.0]


def test_the_spatial_chain_takes_the_o_n_implicit_step_stably_where_rk4_fails():
    """SpatialChain-v0 with heavy joint damping (b = 50 N m s/rad on links of 0.1 kg): the joint-implicit
    Euler step (one O(N) articulated-body solve with ``h b`` on the armature) stays finite and calm at the
    env's 10 ms, where RK4's explicit step is far beyond its stability limit and is reported diverged."""
    kwargs = {"n_links": 10, "params": {"b": 50.0}}
    calm = gym.make("mbs_envs/SpatialChain-v0", integrator=NAME, **kwargs)
    wild = gym.make("mbs_envs/SpatialChain-v0", **kwargs)
    calm.reset(seed=0)
    wild.reset(seed=0)
    a = np.zeros(10, np.float32)
    diverged = False
    for _ in range(50):
        obs, reward, terminated, truncated, info = calm.step(a)
        assert np.all(np.isfinite(obs)) and not terminated and np.max(np.abs(calm.unwrapped.v)) < 10.0
        diverged |= bool(wild.step(a)[4]["diverged"])
    assert diverged
