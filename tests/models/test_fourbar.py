"""FourBar against independent references: SymPy, a reduced 1-DOF formulation, closed forms."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp

from mbs_envs import simulate
from mbs_envs.models import FourBar, grashof_class
from tests.lagrange import lagrange, planar_chain

RNG = np.random.default_rng(7)
PARAMS = dict(
    l0=1.1, l1=0.35, l2=0.9, l3=0.85, m1=0.4, m2=1.2, m3=0.7, r1=0.2, r2=0.4, r3=0.5, I1=0.01, I2=0.09, I3=0.05
)


@functools.lru_cache(maxsize=None)
def sympy_fourbar():
    """Open-loop (cut) system by Lagrange and the loop closure, lambdified."""
    chain = planar_chain(2)  # crank + coupler with relative angles q1 = th1, q2 = ph2
    th1, ph2 = chain["q"]
    dth1, dph2 = chain["dq"]
    ph1, dph1 = sp.symbols("ph1 dph1")
    s = chain["syms"]
    m3, r3, I3, l0, l3 = sp.symbols("m3 r3 I3 l0 l3", positive=True)
    T = chain["T"] + sp.Rational(1, 2) * (m3 * r3**2 + I3) * dph1**2
    V = chain["V"] + m3 * s["g"] * r3 * sp.sin(ph1)
    q = [th1, ph2, ph1]
    dq = [dth1, dph2, dph1]
    M, Cv, G = lagrange(T, V, q, dq)
    phi = sp.Matrix(
        [
            s["l1"] * sp.cos(th1) + s["l2"] * sp.cos(th1 + ph2) - l0 - l3 * sp.cos(ph1),
            s["l1"] * sp.sin(th1) + s["l2"] * sp.sin(th1 + ph2) - l3 * sp.sin(ph1),
        ]
    )
    Psi = phi.jacobian(q)
    dPsi_v = (Psi * sp.Matrix(dq)).jacobian(q) * sp.Matrix(dq)
    names = ["l0", "l1", "l2", "l3", "m1", "m2", "m3", "r1", "r2", "r3", "I1", "I2", "I3", "g"]
    lookup = {**s, "m3": m3, "r3": r3, "I3": I3, "l0": l0, "l3": l3}
    args = [lookup[n] for n in names] + q + dq
    return names, {
        k: sp.lambdify(args, e, "numpy") for k, e in dict(M=M, Cv=Cv, G=G, phi=phi, Psi=Psi, dPsi_v=dPsi_v).items()
    }


def random_consistent_states(model, n=10):
    th1 = RNG.uniform(-np.pi, np.pi, n)
    return model.consistent_state(th1, RNG.uniform(-4, 4, n))


def test_matches_sympy_derivation_of_the_cut_system_and_loop_closure():
    model = FourBar(**PARAMS)
    names, f = sympy_fourbar()
    p = model.params.as_dict()
    for _ in range(15):
        q = RNG.uniform(-np.pi, np.pi, 3)
        v = RNG.uniform(-4, 4, 3)
        args = [p[k] for k in names] + list(q) + list(v)
        np.testing.assert_allclose(model.mass_matrix(q), np.array(f["M"](*args), float), atol=1e-12)
        np.testing.assert_allclose(model.coriolis(q, v), np.ravel(f["Cv"](*args)), atol=1e-12)
        np.testing.assert_allclose(model.gravity(q), np.ravel(f["G"](*args)), atol=1e-12)
        np.testing.assert_allclose(model.constraint_residual(q), np.ravel(f["phi"](*args)), atol=1e-12)
        np.testing.assert_allclose(model.constraint_jacobian(q), np.array(f["Psi"](*args), float), atol=1e-12)
        np.testing.assert_allclose(model.constraint_bias(q, v), np.ravel(f["dPsi_v"](*args)), atol=1e-12)


def reduced_crank_acceleration(model, q, v, u):
    """Velocity transformation: v = T dth1 with T spanning null(Psi) (SVD, independent of the model's solvers).

    T^T (M (T ddth1 + a_p) + h) = T^T B u, with a_p the minimum-norm solution of Psi a_p = -dPsi v.
    """
    Psi = model.constraint_jacobian(q)
    _, _, Vt = np.linalg.svd(Psi)
    T = Vt[-1] / Vt[-1][0]  # null vector, scaled to T_0 = 1 (valid away from a crank dead point)
    a_p = np.linalg.lstsq(Psi, -model.constraint_bias(q, v), rcond=None)[0]
    M = model.mass_matrix(q)
    h = model.bias(q, v)
    ddth1 = (T @ (model.actuation @ u) - T @ (M @ a_p + h)) / (T @ M @ T)
    return T * ddth1 + a_p


def test_multiplier_formulation_matches_reduced_formulation():
    model = FourBar(**PARAMS, b1=0.1, b3=0.2, f2=0.05, v_s=0.1)
    q, v = random_consistent_states(model, 25)
    u = RNG.uniform(-5, 5, (25, 1))
    a = model.forward_dynamics(q, v, u)
    for i in range(25):
        np.testing.assert_allclose(a[i], reduced_crank_acceleration(model, q[i], v[i], u[i]), rtol=1e-10, atol=1e-10)


def test_forward_dynamics_satisfies_equations_and_inverse_dynamics_inverts_it():
    model = FourBar(**PARAMS, b2=0.3)
    q, v = random_consistent_states(model, 30)
    u = RNG.uniform(-5, 5, (30, 1))
    a, lam, cond = model.solve(q, v, u)
    Psi = model.constraint_jacobian(q)
    # (1): M a + h = B u + Psi^T lam ; (2): Psi a + dPsi v = 0
    lhs = np.einsum("nij,nj->ni", model.mass_matrix(q), a) + model.bias(q, v)
    rhs = u @ model.actuation.T + np.einsum("nki,nk->ni", Psi, lam)
    np.testing.assert_allclose(lhs, rhs, atol=1e-11)
    np.testing.assert_allclose(np.einsum("nki,ni->nk", Psi, a) + model.constraint_bias(q, v), 0, atol=1e-11)
    u_id, lam_id = model.inverse_dynamics_with_multipliers(q, v, a)
    np.testing.assert_allclose(u_id, u, atol=1e-10)
    np.testing.assert_allclose(lam_id, lam, atol=1e-10)
    np.testing.assert_allclose(model.multipliers(q, v, u), lam, atol=1e-12)
    assert np.all(np.isfinite(cond)) and np.all(cond >= 1)


def test_consistent_states_on_both_branches():
    model = FourBar(**PARAMS)
    for branch in (1, -1):
        q, v = model.consistent_state(np.linspace(-3, 3, 13), 2.0, branch=branch)
        np.testing.assert_allclose(model.constraint_residual(q), 0, atol=1e-12)
        np.testing.assert_allclose(np.einsum("nki,ni->nk", model.constraint_jacobian(q), v), 0, atol=1e-12)
        np.testing.assert_allclose(v[:, 0], 2.0)
    up, _ = model.consistent_state(0.3, branch=1)
    down, _ = model.consistent_state(0.3, branch=-1)
    assert model.joint_positions(up)[2, 1] > 0 > model.joint_positions(down)[2, 1]


def test_energy_conserved_without_torque_or_friction():
    model = FourBar()
    q0, v0 = model.consistent_state(0.4, 3.0)
    E0 = model.energy(q0, v0)
    tr = simulate(model, q0, v0, 5.0, dt=1e-3, stabilization="projection")
    # measured 1.2e-10 relative (RK4 error plus the projection's O(h^5) energy changes)
    assert np.max(np.abs(model.energy(tr.q, tr.v) - E0)) / abs(E0) < 1e-8


def test_work_energy_balance_under_constant_crank_torque():
    """E(t) - E(0) = tau (th1(t) - th1(0)), the work of a constant torque; the
    simulation's mismatch is integration error, so it shrinks ~h^4 with the step."""
    model = FourBar()
    tau = 3.5  # above the largest static torque (3.04 N m): the crank spins up
    q0, v0 = model.consistent_state(-1.0, 0.5)
    mismatch = {}
    for dt in (1e-3, 5e-4):
        tr = simulate(model, q0, v0, 1.0, dt=dt, u=np.array([tau]), stabilization="projection")
        work = tau * (tr.q[:, 0] - q0[0])
        dE = model.energy(tr.q, tr.v) - model.energy(q0, v0)
        mismatch[dt] = np.max(np.abs(dE - work)) / np.max(np.abs(work))
    assert tr.q[-1, 0] - q0[0] > 2 * np.pi  # it turned through a full revolution
    assert mismatch[1e-3] < 1e-6
    assert mismatch[1e-3] / mismatch[5e-4] > 8  # converges with the step (order > 3)


def test_drift_ordering_none_baumgarte_projection():
    model = FourBar()
    q0, v0 = model.consistent_state(0.2, 4.0)
    drift = {}
    for kind in ("none", "baumgarte", "projection"):
        tr = simulate(model, q0, v0, 5.0, dt=1e-3, stabilization=kind)
        drift[kind] = np.max(np.abs(model.constraint_residual(tr.q[-1])))
    assert drift["none"] > drift["baumgarte"] > drift["projection"]
    assert drift["projection"] <= 1e-10


def test_change_point_linkage_passes_its_singular_configuration():
    """Parallelogram (s + l = p + q): at th1 = 0 all links are collinear and Psi loses rank."""
    model = FourBar(l0=1.0, l1=0.5, l2=1.0, l3=0.5, r1=0.25, r2=0.5, r3=0.25)
    assert model.grashof == "change-point"
    assert np.linalg.matrix_rank(model.constraint_jacobian(model.assemble(0.0)), tol=1e-9) == 1
    assert model.constraint_conditioning(model.assemble(0.0)) > 1e12
    q0, v0 = model.consistent_state(-0.6, 3.0)
    tr = simulate(model, q0, v0, 1.0, dt=1e-3, u=np.array([2.0]))
    assert not tr.diverged.any()
    assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v))
    assert tr.q[0, 0] < 0 < tr.q[-1, 0]  # the crank went through th1 = 0
    assert np.max(np.abs(model.constraint_residual(tr.q))) < 1e-10


def test_joint_forces_balance_the_weight_at_rest():
    model = FourBar(**PARAMS)
    q, v = model.consistent_state(0.8, 0.0)
    u_static = model.inverse_dynamics(q, v, np.zeros(3))
    np.testing.assert_allclose(model.forward_dynamics(q, v, u_static), 0, atol=1e-12)
    F = model.joint_forces(q, v, u_static)
    p = model.params
    weight = (p.m1 + p.m2 + p.m3) * p.g
    np.testing.assert_allclose(F[0] + F[3], [0.0, weight], atol=1e-10)
    np.testing.assert_allclose(F[2], model.multipliers(q, v, u_static), atol=1e-14)


def test_joint_forces_give_each_link_its_momentum_rate():
    """Sum of external forces = total mass times centre-of-mass acceleration (finite differences of the COM)."""
    model = FourBar(**PARAMS)
    p = model.params
    q0, v0 = model.consistent_state(0.5, 2.5)
    u = np.array([1.0])
    F = model.joint_forces(q0, v0, u)

    def com(q):
        pts = model.joint_positions(q)
        e = lambda a: np.array([np.cos(a), np.sin(a)])  # noqa: E731
        c1 = p.r1 * e(q[0])
        c2 = pts[1] + p.r2 * e(q[0] + q[1])
        c3 = np.array([p.l0, 0]) + p.r3 * e(q[2])
        return (p.m1 * c1 + p.m2 * c2 + p.m3 * c3) / (p.m1 + p.m2 + p.m3)

    h = 1e-3
    tr = simulate(model, q0, v0, 2 * h, dt=h / 10, u=u)
    c = [com(tr.q[k]) for k in (0, 10, 20)]
    a_com = (c[2] - 2 * c[1] + c[0]) / h**2  # second difference centred at t = h
    tr0 = simulate(model, q0, v0, h, dt=h / 10, u=u)
    F_mid = model.joint_forces(tr0.q[-1], tr0.v[-1], u)
    total = (p.m1 + p.m2 + p.m3) * (a_com - [0.0, -p.g])
    # central difference error O(h^2) ~ 1e-6 of the accelerations
    np.testing.assert_allclose(F_mid[0] + F_mid[3], total, atol=1e-4)
    assert np.all(np.isfinite(F))


@pytest.mark.parametrize(
    "lengths, expected",
    [
        ((1.0, 0.3, 1.0, 0.8), "crank-rocker"),
        ((0.3, 1.0, 0.9, 0.8), "double-crank"),
        ((1.0, 0.8, 0.3, 0.9), "double-rocker"),
        ((1.0, 0.8, 0.9, 0.3), "rocker-crank"),
        ((1.0, 0.5, 1.0, 0.5), "change-point"),
        ((1.0, 0.75, 0.8, 0.9), "triple-rocker"),
    ],
)
def test_grashof_classification(lengths, expected):
    assert grashof_class(*lengths) == expected


def test_lengths_that_cannot_assemble_raise_naming_the_link():
    with pytest.raises(ValueError, match="l0.*cannot assemble"):
        FourBar(l0=3.0, l1=0.5, l2=1.0, l3=1.0)
    with pytest.raises(ValueError, match="l2"):
        FourBar(l2=2.1)  # 0.3 + 1.0 + 0.8 = 2.1: only a straight line
    model = FourBar(l0=1.0, l1=0.75, l2=0.8, l3=0.9)  # triple-rocker: the crank cannot turn fully
    model.assemble(0.5)
    with pytest.raises(ValueError, match="cannot assemble at crank angle"):
        model.assemble(np.pi)
    with pytest.raises(ValueError, match="branch"):
        model.assemble(0.5, branch=0)


@pytest.mark.slow
def test_projection_keeps_the_residual_below_1e_10_over_1e5_steps():
    model = FourBar()
    q0, v0 = model.consistent_state(0.2, 4.0)
    E0 = model.energy(q0, v0)
    tr = simulate(model, q0, v0, 100.0, dt=1e-3, stabilization="projection")
    assert len(tr.t) == 100_001
    assert np.max(np.abs(model.constraint_residual(tr.q))) <= 1e-10
    assert np.max(np.abs(model.energy(tr.q, tr.v) - E0)) / abs(E0) < 1e-6
