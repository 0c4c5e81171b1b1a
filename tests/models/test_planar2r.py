"""Planar2R against independent references: SymPy Lagrange, Gymnasium's Acrobot, identities."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from mbs_envs.models import Planar2R, Planar2RParams
from tests.lagrange import lagrange, planar_chain

RNG = np.random.default_rng(12345)
PARAMS = dict(m1=1.3, m2=0.7, l1=0.9, l2=1.1, r1=0.4, r2=0.6, I1=0.05, I2=0.08, g=9.81)


@functools.lru_cache(maxsize=None)
def sympy_2r():
    """Lambdified M, Cv, G and E of the SymPy derivation, as functions of (params, q, dq)."""
    chain = planar_chain(2)
    q, dq, syms = chain["q"], chain["dq"], chain["syms"]
    M, Cv, G = lagrange(chain["T"], chain["V"], q, dq)
    order = [syms[k] for k in ("m1", "m2", "l1", "l2", "r1", "r2", "I1", "I2", "g")]
    args = order + q + dq
    E = chain["T"] + chain["V"]
    ddq = sp.symbols("ddq1:3")
    dEdt = sum(sp.diff(E, x) * dx for x, dx in zip(q + dq, dq + list(ddq)))
    return {
        "M": sp.lambdify(args, M, "numpy"),
        "Cv": sp.lambdify(args, Cv, "numpy"),
        "G": sp.lambdify(args, G, "numpy"),
        "E": sp.lambdify(args, E, "numpy"),
        "dEdt": sp.lambdify(args + list(ddq), dEdt, "numpy"),
    }


def sym_args(p: dict, q, v):
    return [p[k] for k in ("m1", "m2", "l1", "l2", "r1", "r2", "I1", "I2", "g")] + list(q) + list(v)


def random_states(n=20):
    q = RNG.uniform(-np.pi, np.pi, (n, 2))
    v = RNG.uniform(-5, 5, (n, 2))
    return q, v


def test_matches_sympy_lagrange_derivation():
    model = Planar2R(**PARAMS)
    f = sympy_2r()
    q, v = random_states()
    for qi, vi in zip(q, v):
        a = sym_args(PARAMS, qi, vi)
        np.testing.assert_allclose(model.mass_matrix(qi), np.array(f["M"](*a), float), rtol=0, atol=1e-12)
        np.testing.assert_allclose(model.coriolis(qi, vi), np.ravel(f["Cv"](*a)), rtol=0, atol=1e-12)
        np.testing.assert_allclose(model.gravity(qi), np.ravel(f["G"](*a)), rtol=0, atol=1e-12)
        np.testing.assert_allclose(model.energy(qi, vi), f["E"](*a), rtol=0, atol=1e-12)


def test_closed_form_at_special_configurations():
    """Hand-evaluated docs/physics.md §3 formulas: arm stretched along +x, at rest."""
    p = Planar2RParams(**PARAMS)
    model = Planar2R(p)
    M = model.mass_matrix([0.0, 0.0])
    assert M[0, 0] == pytest.approx(p.I1 + p.I2 + p.m1 * p.r1**2 + p.m2 * (p.l1 + p.r2) ** 2, abs=1e-12)
    assert M[1, 1] == pytest.approx(p.I2 + p.m2 * p.r2**2, abs=1e-12)
    # horizontal arm: gravity torque = weight times lever arm
    G = model.gravity([0.0, 0.0])
    assert G[0] == pytest.approx(p.g * (p.m1 * p.r1 + p.m2 * (p.l1 + p.r2)), abs=1e-12)
    assert G[1] == pytest.approx(p.g * p.m2 * p.r2, abs=1e-12)
    # hanging straight down: no gravity torque, potential = -g (m1 r1 + m2 (l1 + r2))
    np.testing.assert_allclose(model.gravity([-np.pi / 2, 0.0]), 0.0, atol=1e-12)
    assert model.potential_energy([-np.pi / 2, 0.0]) == pytest.approx(
        -p.g * (p.m1 * p.r1 + p.m2 * (p.l1 + p.r2)), abs=1e-12
    )
    # Coriolis at th2 = pi/2, dth1 = 1, dth2 = 0: (0, m2 l1 r2)
    np.testing.assert_allclose(model.coriolis([0.3, np.pi / 2], [1.0, 0.0]), [0.0, p.m2 * p.l1 * p.r2], atol=1e-12)


def acrobot_env():
    gym = pytest.importorskip("gymnasium")
    from gymnasium.envs.classic_control.acrobot import AcrobotEnv

    return gym, AcrobotEnv()


def acrobot_model(env):
    return Planar2R(
        m1=env.LINK_MASS_1,
        m2=env.LINK_MASS_2,
        l1=env.LINK_LENGTH_1,
        l2=env.LINK_LENGTH_2,
        r1=env.LINK_COM_POS_1,
        r2=env.LINK_COM_POS_2,
        I1=env.LINK_MOI,
        I2=env.LINK_MOI,
        g=9.8,
    )


def test_reproduces_gymnasium_acrobot_accelerations():
    """Acrobot-v1 (book dynamics) is this system with theta1 = th1 + pi/2, tau1 = 0."""
    _, env = acrobot_env()
    assert env.book_or_nips == "book"
    model = acrobot_model(env)
    for _ in range(50):
        theta = RNG.uniform(-np.pi, np.pi, 2)
        dtheta = RNG.uniform(-4, 4, 2)
        torque = RNG.uniform(-1, 1)
        ref = np.array(env._dsdt(np.r_[theta, dtheta, torque])[2:4])
        q = np.array([theta[0] - np.pi / 2, theta[1]])
        a = model.forward_dynamics(q, dtheta, [0.0, torque])
        np.testing.assert_allclose(a, ref, rtol=1e-10, atol=1e-10)


def test_reproduces_gymnasium_acrobot_rk4_step():
    """One Acrobot step (its own RK4 over dt = 0.2 s) against ours with the same method."""
    from gymnasium.envs.classic_control.acrobot import rk4

    from mbs_envs.dynamics.simulate import advance
    from mbs_envs import integrators

    _, env = acrobot_env()
    model = acrobot_model(env)
    stepper = integrators.get("rk4")
    for _ in range(20):
        s = np.r_[RNG.uniform(-np.pi, np.pi, 2), RNG.uniform(-3, 3, 2)]
        torque = float(RNG.choice([-1.0, 0.0, 1.0]))
        ref = rk4(env._dsdt, np.r_[s, torque], [0, env.dt])[:4]
        q, v = advance(model, stepper, 0.0, s[:2] - [np.pi / 2, 0], s[2:], env.dt, 1, [0.0, torque])
        np.testing.assert_allclose(np.r_[q + [np.pi / 2, 0], v], ref, rtol=1e-10, atol=1e-10)


def test_inverse_dynamics_inverts_forward_dynamics():
    model = Planar2R(**PARAMS, b1=0.3, b2=0.1, f1=0.2, f2=0.4)
    q, v = random_states(100)
    u = RNG.uniform(-20, 20, (100, 2))
    a = model.forward_dynamics(q, v, u)
    np.testing.assert_allclose(model.inverse_dynamics(q, v, a), u, rtol=0, atol=1e-11)
    # and the other way round
    a2 = RNG.uniform(-30, 30, (100, 2))
    np.testing.assert_allclose(model.forward_dynamics(q, v, model.inverse_dynamics(q, v, a2)), a2, rtol=0, atol=1e-11)


def test_energy_rate_is_input_power_minus_friction_power():
    """dE/dt from the SymPy energy (chain rule, exact) vs v.Bu - v.F(v) along the model's a."""
    p = dict(PARAMS)
    model = Planar2R(**p, b1=0.7, b2=0.2, f1=0.5, f2=0.3, v_s=0.05)
    dEdt = sympy_2r()["dEdt"]
    q, v = random_states(30)
    u = RNG.uniform(-10, 10, (30, 2))
    a = model.forward_dynamics(q, v, u)
    for i in range(30):
        lhs = dEdt(*sym_args(p, q[i], v[i]), *a[i])
        rhs = model.input_power(v[i], u[i]) - model.friction_power(v[i])
        assert lhs == pytest.approx(rhs, rel=1e-12, abs=1e-10)
    assert np.all(model.friction_power(v) >= 0)


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.floats(0.05, 20.0), min_size=4, max_size=4),
    st.floats(-10.0, 10.0),
    st.floats(-10.0, 10.0),
)
def test_mass_matrix_symmetric_positive_definite(masses_lengths, th1, th2):
    m1, m2, l1, l2 = masses_lengths
    model = Planar2R(m1=m1, m2=m2, l1=l1, l2=l2, r1=l1 / 2, r2=l2 / 2, I1=0.0, I2=0.0)
    M = model.mass_matrix([th1, th2])
    np.testing.assert_array_equal(M, M.T)
    assert np.all(np.linalg.eigvalsh(M) > 0)


def test_batched_equals_unbatched():
    model = Planar2R(**PARAMS, b1=0.2, f2=0.1)
    q = RNG.uniform(-3, 3, (4, 5, 2))
    v = RNG.uniform(-3, 3, (4, 5, 2))
    u = RNG.uniform(-3, 3, (4, 5, 2))
    a = model.forward_dynamics(q, v, u)
    E = model.energy(q, v)
    assert a.shape == (4, 5, 2) and E.shape == (4, 5)
    for i in range(4):
        for j in range(5):
            np.testing.assert_allclose(
                a[i, j], model.forward_dynamics(q[i, j], v[i, j], u[i, j]), rtol=1e-14, atol=1e-14
            )
            assert E[i, j] == pytest.approx(model.energy(q[i, j], v[i, j]), rel=1e-14)
    # broadcasting: one q against many v
    a_b = model.forward_dynamics(q[0, 0], v[0], None)
    assert a_b.shape == (5, 2)


@pytest.mark.parametrize(
    "kwargs, culprit",
    [
        ({"m1": 0.0}, "m1"),
        ({"m2": -1.0}, "m2"),
        ({"l1": 0.0}, "l1"),
        ({"l2": float("nan")}, "l2"),
        ({"I1": -0.1}, "I1"),
        ({"g": float("inf")}, "g"),
        ({"b1": -1.0}, "b1"),
        ({"f2": -1.0}, "f2"),
        ({"v_s": 0.0}, "v_s"),
        ({"r2": 0.0, "I2": 0.0}, "I2"),
        ({"mass1": 1.0}, "mass1"),
        ({"m1": "heavy"}, "m1"),
    ],
)
def test_bad_parameters_raise_naming_the_parameter(kwargs, culprit):
    with pytest.raises(ValueError, match=culprit):
        Planar2R(**kwargs)


def test_params_are_frozen_and_overrides_validate():
    model = Planar2R(m1=2.0)
    assert model.params.m1 == 2.0 and model.params.m2 == 1.0
    with pytest.raises(AttributeError):
        model.params.m1 = 3.0  # frozen dataclass
    assert Planar2R({"m1": 2.0}) == model
    with pytest.raises(ValueError, match="q"):
        model.mass_matrix([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="u"):
        model.forward_dynamics([0.0, 0.0], [0.0, 0.0], [1.0])
