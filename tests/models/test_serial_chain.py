"""SerialChain: RNEA, ABA and CRBA against each other, Planar2R, SymPy, and conservation."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from mbs_envs import simulate
from mbs_envs.models import Planar2R, SerialChain
from tests.lagrange import lagrange, planar_chain

RNG = np.random.default_rng(11)


def random_chain(n, rng=RNG):
    l = rng.uniform(0.1, 1.0, n)  # noqa: E741
    m = rng.uniform(0.1, 2.0, n)
    return SerialChain(
        n_links=n,
        m=m,
        l=l,
        r=l * rng.uniform(0, 1, n),
        I=m * l**2 * rng.uniform(0.01, 0.2, n),
        armature=rng.uniform(0, 0.05, n),
        b=rng.uniform(0, 0.2, n),
        f=rng.uniform(0, 0.1, n),
        v_s=0.3,
    )


def random_state(n, batch=(), rng=RNG):
    return rng.uniform(-np.pi, np.pi, batch + (n,)), rng.uniform(-3, 3, batch + (n,))


def test_two_links_reproduce_planar2r():
    p = dict(m1=1.3, m2=0.7, l1=0.9, l2=1.1, r1=0.4, r2=0.6, I1=0.05, I2=0.08, b1=0.2, b2=0.1, f1=0.3, f2=0.05, v_s=0.1)
    ref = Planar2R(**p)
    chain = SerialChain(
        n_links=2, m=[1.3, 0.7], l=[0.9, 1.1], r=[0.4, 0.6], I=[0.05, 0.08], b=[0.2, 0.1], f=[0.3, 0.05], v_s=0.1
    )
    q, v = random_state(2, (20,))
    u = RNG.uniform(-5, 5, (20, 2))
    np.testing.assert_allclose(chain.mass_matrix(q), ref.mass_matrix(q), atol=1e-12)
    np.testing.assert_allclose(chain.bias(q, v), ref.bias(q, v), atol=1e-12)
    np.testing.assert_allclose(chain.gravity(q), ref.gravity(q), atol=1e-12)
    np.testing.assert_allclose(chain.forward_dynamics(q, v, u), ref.forward_dynamics(q, v, u), atol=1e-12)
    np.testing.assert_allclose(chain.inverse_dynamics(q, v, u), ref.inverse_dynamics(q, v, u), atol=1e-12)
    np.testing.assert_allclose(chain.energy(q, v), ref.energy(q, v), atol=1e-12)
    np.testing.assert_allclose(chain.joint_positions(q), ref.joint_positions(q), atol=1e-12)


@functools.lru_cache(maxsize=None)
def sympy_chain3():
    ch = planar_chain(3)
    arm = sp.symbols("armature1:4")
    T = ch["T"] + sum(a * dq**2 for a, dq in zip(arm, ch["dq"])) / 2  # rotor energy of each drive
    M, Cv, G = lagrange(T, ch["V"], ch["q"], ch["dq"], simplify=False)
    names = [f"{k}{i}" for k in ("m", "l", "r", "I") for i in (1, 2, 3)] + ["g"]
    args = [ch["syms"][n] for n in names] + list(arm) + ch["q"] + ch["dq"]
    return names, {k: sp.lambdify(args, e, "numpy") for k, e in dict(M=M, Cv=Cv, G=G).items()}


def test_three_links_match_sympy_lagrange():
    chain = random_chain(3)
    p = chain.params
    names, f = sympy_chain3()
    vals = {f"{k}{i + 1}": getattr(p, k)[i] for k in ("m", "l", "r", "I") for i in range(3)}
    vals["g"] = p.g
    for _ in range(10):
        q, v = random_state(3)
        args = [vals[n] for n in names] + list(p.armature) + list(q) + list(v)
        np.testing.assert_allclose(chain.mass_matrix(q), np.array(f["M"](*args), float), atol=1e-12)
        np.testing.assert_allclose(chain.coriolis(q, v), np.ravel(f["Cv"](*args)), atol=1e-12)
        np.testing.assert_allclose(chain.gravity(q), np.ravel(f["G"](*args)), atol=1e-12)


@pytest.mark.parametrize("n", [1, 4, 17, 60])
def test_rnea_equals_crba_mass_matrix_times_a_plus_bias(n):
    chain = random_chain(n)
    q, v = random_state(n, (3,))
    a = RNG.uniform(-5, 5, (3, n))
    tau = chain.rnea(q, v, a)
    expected = np.einsum("bij,bj->bi", chain.mass_matrix(q), a) + chain.rnea(q, v, np.zeros_like(a))
    scale = np.max(np.abs(tau))
    np.testing.assert_allclose(tau, expected, atol=1e-12 * max(1.0, scale))
    M = chain.mass_matrix(q)
    np.testing.assert_allclose(M, np.swapaxes(M, -1, -2), atol=1e-14)
    assert np.all(np.linalg.eigvalsh(M) > 0)


@pytest.mark.parametrize("n", [1, 3, 25, 120])
def test_aba_equals_dense_solve(n):
    chain = random_chain(n)
    q, v = random_state(n, (4,))
    u = RNG.uniform(-2, 2, (4, n))
    a = chain.forward_dynamics(q, v, u)
    a_dense = chain.forward_dynamics_crba(q, v, u)
    # M's condition number grows with N; measured relative agreement 1e-14 (N=3) to 1e-10 (N=120)
    np.testing.assert_allclose(a, a_dense, rtol=0, atol=1e-9 * np.max(np.abs(a_dense)))
    np.testing.assert_allclose(chain.inverse_dynamics(q, v, a), u, atol=1e-8 * max(1.0, np.max(np.abs(u))))


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 12), st.integers(0, 2**32 - 1))
def test_random_chains_forward_inverse_roundtrip(n, seed):
    rng = np.random.default_rng(seed)
    chain = random_chain(n, rng)
    q, v = random_state(n, (), rng)
    u = rng.uniform(-3, 3, n)
    a = chain.forward_dynamics(q, v, u)
    np.testing.assert_allclose(chain.inverse_dynamics(q, v, a), u, atol=1e-9)
    np.testing.assert_allclose(a, chain.forward_dynamics_crba(q, v, u), atol=1e-9 * max(1.0, np.max(np.abs(a))))


def test_kinetic_energy_from_link_velocities_equals_quadratic_form():
    chain = random_chain(30)
    q, v = random_state(30, (5,))
    T_quad = 0.5 * np.einsum("bi,bij,bj->b", v, chain.mass_matrix(q), v)
    np.testing.assert_allclose(chain.kinetic_energy(q, v), T_quad, rtol=1e-12)


def test_energy_conserved_without_input_or_friction():
    """Energy error is RK4's: it shrinks ~16x per halving of the step (order 4)."""
    chain = SerialChain(n_links=10)
    rng = np.random.default_rng(5)
    q0, v0 = rng.uniform(-np.pi, np.pi, 10), rng.uniform(-1, 1, 10)
    E0 = chain.energy(q0, v0)
    drift = {}
    for dt in (2e-4, 1e-4):
        tr = simulate(chain, q0, v0, 0.5, dt=dt)
        assert not tr.diverged
        drift[dt] = np.max(np.abs(chain.energy(tr.q, tr.v) - E0))
    # measured 2.7e-6 J and 1.8e-7 J (|E0| = 0.50 J): ratio 15.2
    assert drift[1e-4] < 1e-6
    assert drift[2e-4] / drift[1e-4] > 12


def test_batched_equals_unbatched():
    chain = random_chain(7)
    q, v = random_state(7, (2, 3))
    u = RNG.uniform(-1, 1, (2, 3, 7))
    a = chain.forward_dynamics(q, v, u)
    tau = chain.inverse_dynamics(q, v, a)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(a[i, j], chain.forward_dynamics(q[i, j], v[i, j], u[i, j]), atol=1e-13)
            np.testing.assert_allclose(tau[i, j], chain.inverse_dynamics(q[i, j], v[i, j], a[i, j]), atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, culprit",
    [
        ({"n_links": 0}, "n_links"),
        ({"n_links": 2.5}, "n_links"),
        ({"n_links": 3, "m": [1.0, 2.0]}, "'m'"),
        ({"l": -1.0}, "'l'"),
        ({"I": 0.0, "r": 0.0}, "I, r"),
        ({"links": 3}, "links"),
    ],
)
def test_bad_parameters(kwargs, culprit):
    with pytest.raises(ValueError, match=culprit):
        SerialChain(**kwargs)


def test_defaults_make_a_one_metre_one_kilogram_rope():
    chain = SerialChain(n_links=8)
    assert chain.nq == chain.nv == chain.nu == 8
    assert np.sum(chain.params.m) == pytest.approx(1.0) and np.sum(chain.params.l) == pytest.approx(1.0)
    tip = chain.joint_positions(np.r_[-np.pi / 2, np.zeros(7)])[-1]
    np.testing.assert_allclose(tip, [0.0, -1.0], atol=1e-14)


@pytest.mark.parametrize("n", [3, 40])
def test_aba_agrees_with_pinocchio(n):
    """A third-party implementation (optional benchmark dependency ``pin``): skipped when absent."""
    pytest.importorskip("pinocchio")
    from mbs_envs.studies.benchmarking import pinocchio_chain

    chain = random_chain(n)
    pin, model, data = pinocchio_chain(chain)
    q, v = random_state(n)
    u = RNG.uniform(-1, 1, n)
    a_pin = np.array(pin.aba(model, data, q, v, u))
    np.testing.assert_allclose(chain.aba(q, v, u), a_pin, atol=1e-10 * np.max(np.abs(a_pin)))
    np.testing.assert_allclose(
        chain.rnea(q, v, u), np.array(pin.rnea(model, data, q, v, u)), atol=1e-10 * max(1.0, np.max(np.abs(u)))
    )


def test_numpy_kinematics_follow_the_kernels_formulas():
    """``SerialChain.kinematics`` (numpy, batched over any leading shape) against the member kernel
    ``_member_kinematics`` chain by chain: the running sums in the same order give the same angles
    bit for bit; sin/cos differ by at most an ulp, so positions agree to 1e-15 m per link."""
    from mbs_envs.models import serial_recursions as sc

    rng = np.random.default_rng(4)
    N = 9
    model = SerialChain(n_links=N, l=rng.uniform(0.05, 0.3, N), r=rng.uniform(0.01, 0.05, N))
    q = rng.uniform(-4, 4, (3, 5, N))
    k = model.kinematics(q)
    assert k["th"].shape == (3, 5, N) and k["p"].shape == k["c"].shape == k["e"].shape == (3, 5, N, 2)
    p_ = model.params
    for idx in np.ndindex(3, 5):
        th, sn, cs, P, C = np.empty(N), np.empty(N), np.empty(N), np.empty((N, 2)), np.empty((N, 2))
        sc._member_kinematics(q[idx], p_.l, p_.r, th, sn, cs, P, C)
        np.testing.assert_array_equal(k["th"][idx], th)
        np.testing.assert_allclose(k["e"][idx], np.stack([cs, sn], -1), rtol=0, atol=2.3e-16)
        np.testing.assert_allclose(k["p"][idx], P, rtol=0, atol=N * 1e-15)
        np.testing.assert_allclose(k["c"][idx], C, rtol=0, atol=N * 1e-15)
    assert np.all(k["p"][..., 0, :] == 0.0)
