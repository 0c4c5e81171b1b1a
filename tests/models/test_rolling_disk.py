"""RollingDisk against an independent SymPy/KKT model, conservation, steady motions, critical spin."""

from __future__ import annotations

import numpy as np
import pytest

from mbs_envs import simulate
from mbs_envs.models import RollingDisk, critical_spin
from tests.disk_reference import disk_functions, kkt_accelerations

RNG = np.random.default_rng(3)


def random_state(model):
    return model.rolling_state(
        heading=RNG.uniform(-3, 3),
        lean=RNG.uniform(-1.2, 1.2),
        spin=RNG.uniform(-3, 3),
        dheading=RNG.uniform(-3, 3),
        dlean=RNG.uniform(-3, 3),
        dspin=RNG.uniform(-10, 10),
        x=RNG.uniform(-1, 1),
        y=RNG.uniform(-1, 1),
    )


def test_matches_independent_sympy_model():
    model = RollingDisk(m=1.3, r=0.25)
    p = model.params
    f = disk_functions()
    for _ in range(20):
        q, v = random_state(model)
        u = RNG.uniform(-1, 1, 2)
        args = [p.m, p.r, p.g, *q, *v]
        np.testing.assert_allclose(model.mass_matrix(q), np.array(f["M"](*args), float), atol=1e-12)
        np.testing.assert_allclose(model.constraint_jacobian(q), np.array(f["Psi"](*args), float), atol=1e-12)
        np.testing.assert_allclose(model.constraint_bias(q, v), np.ravel(f["dPsi_v"](*args)), atol=1e-12)
        a_ref, lam_ref = kkt_accelerations(p.m, p.r, p.g, q, v, model.actuation @ u)
        a, lam, _ = model.solve(q, v, u)
        np.testing.assert_allclose(a, a_ref, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(lam, lam_ref, rtol=1e-10, atol=1e-10)
        assert model.kinetic_energy(q, v) == pytest.approx(f["T"](*args), rel=1e-12)
        # the orientation (drawn by the renderer) and the contact offset are SymPy's R and lowest rim point
        R = model.orientation(q)
        np.testing.assert_allclose(R, np.array(f["R"](*args), float), atol=1e-14)
        np.testing.assert_allclose(R[:, 1], model.spin_axis(q), atol=1e-15)
        np.testing.assert_allclose(model.contact_offset(q), np.ravel(f["rC"](*args)), atol=1e-12)
    qs = np.stack([random_state(model)[0] for _ in range(4)])
    np.testing.assert_array_equal(model.orientation(qs)[2], model.orientation(qs[2]))  # batched = one at a time


def test_multipliers_are_the_contact_force():
    """Newton for the centre: m a = lam - m g e_z."""
    model = RollingDisk()
    for _ in range(5):
        q, v = random_state(model)
        u = RNG.uniform(-0.5, 0.5, 2)
        a, lam, _ = model.solve(q, v, u)
        np.testing.assert_allclose(lam, model.params.m * (a[:3] + [0.0, 0.0, model.params.g]), atol=1e-12)


def test_sign_facts_of_physics_md():
    model = RollingDisk()
    q, v = model.rolling_state(dspin=2.0)
    assert v[0] == pytest.approx(model.params.r * 2.0) and abs(v[1]) < 1e-15  # rolls to +x
    q, _ = model.rolling_state(lean=0.2)
    assert model.contact_offset(q)[1] > 0  # contact at +y: the top tips towards -y
    np.testing.assert_allclose(model.constraint_residual(q), 0, atol=1e-15)


def test_energy_conserved_and_constraints_kept_without_input():
    model = RollingDisk()
    q0, v0 = model.rolling_state(lean=0.3, dlean=0.5, dheading=1.0, dspin=6.0)
    E0 = model.energy(q0, v0)
    tr = simulate(model, q0, v0, 5.0, dt=1e-3)
    assert not tr.diverged
    # measured 6e-12 J relative to |E0| = 3.4 J
    assert np.max(np.abs(model.energy(tr.q, tr.v) - E0)) < 1e-10
    assert np.max(np.abs(model.constraint_residual(tr.q))) < 1e-12
    Psi_v = np.einsum("nki,ni->nk", model.constraint_jacobian(tr.q), tr.v)
    assert np.max(np.abs(Psi_v)) < 1e-12


def test_inputs_do_the_work_energy_balance():
    """dE/dt = v . B u along the motion (constraint forces do no work): integrated check."""
    model = RollingDisk()
    u = np.array([0.05, -0.02])
    q0, v0 = model.rolling_state(lean=0.1, dspin=5.0)
    tr = simulate(model, q0, v0, 2.0, dt=5e-4, u=u)
    P = model.input_power(tr.v, u)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1]) * np.diff(tr.t))])
    dE = model.energy(tr.q, tr.v) - model.energy(q0, v0)
    np.testing.assert_allclose(dE, work, atol=1e-7)  # trapezoid error ~ T dt^2 |P''| / 12


@pytest.mark.parametrize("lean, heading_rate", [(0.3, -2.0), (-0.5, 1.5), (0.1, -4.0)])
def test_steady_circular_rolling(lean, heading_rate):
    """The relation between lean, heading rate and spin: zero accelerations in the independent
    model, and constant lean and rates in our simulation."""
    model = RollingDisk()
    p = model.params
    W = model.steady_turning_spin(lean, heading_rate)
    q, v = model.rolling_state(lean=lean, dheading=heading_rate, dspin=W)
    a_ref, _ = kkt_accelerations(p.m, p.r, p.g, q, v, np.zeros(6))
    np.testing.assert_allclose(a_ref[3:], 0, atol=1e-12)
    tr = simulate(model, q, v, 2.0, dt=1e-3)
    np.testing.assert_allclose(tr.q[:, 4], lean, atol=1e-8)
    np.testing.assert_allclose(tr.v[:, 3], heading_rate, atol=1e-8)
    np.testing.assert_allclose(tr.v[:, 5], W, atol=1e-8)
    # the centre moves on a circle: |v| constant
    speed = np.linalg.norm(tr.v[:, :2], axis=1)
    np.testing.assert_allclose(speed, speed[0], rtol=1e-8)


def lean_eigenvalues(model, W, eps=1e-6):
    """Eigenvalues of the lean/heading-rate dynamics linearized (central differences) about upright rolling at spin W."""
    x0 = np.array([0.0, 0.0, 0.0, 0.0, W])
    idx = [1, 2, 3]  # (lean, heading rate, lean rate)
    J = np.zeros((3, 3))
    for j, k in enumerate(idx):
        dx = np.zeros(5)
        dx[k] = eps
        J[:, j] = (model.reduced_dynamics(x0 + dx)[idx] - model.reduced_dynamics(x0 - dx)[idx]) / (2 * eps)
    return np.linalg.eigvals(J)


def test_critical_spin_formula_against_linearized_full_model():
    model = RollingDisk(m=2.0, r=0.4)
    Wc = model.critical_spin
    assert Wc == pytest.approx(np.sqrt(9.81 / (3 * 0.4)), rel=1e-14)
    assert critical_spin(2.0, 0.4, 9.81) == Wc
    # the unstable real eigenvalue disappears at Wc: bisect on it
    lo, hi = 0.5 * Wc, 1.5 * Wc
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if np.max(lean_eigenvalues(model, mid).real) > 1e-4:
            lo = mid
        else:
            hi = mid
    # 1e-4 threshold on Re(lambda) ~ sqrt(k (Wc^2 - W^2)) shifts the crossing by ~1e-8 relative
    assert hi == pytest.approx(Wc, rel=1e-6)


def max_lean(model, W, lean0=0.01, t_final=10.0):
    q, v = model.rolling_state(lean=lean0, dspin=W)
    tr = simulate(model, q, v, t_final, dt=4e-3)  # smooth motion: same maximum as at 2e-3 to 3e-7
    return np.max(np.abs(tr.q[:, 4])), tr


def test_upright_rolling_bounded_above_and_growing_below_the_critical_spin():
    """Above Wc the lean oscillates with the linear theory's amplitude; below it grows.

    Starting upright-ish (lean0) with no heading rate, heading' - C W lean / A is
    conserved, so the linearized lean swings between lean0 and
    lean0 (1 - 2 W^2 / (W^2 - Wc^2)) (see ``critical_spin``'s derivation).
    """
    model = RollingDisk()
    Wc = model.critical_spin
    lean0 = 0.01
    for factor in (1.3, 2.0):
        W = factor * Wc
        above, _ = max_lean(model, W, lean0)
        predicted = lean0 * (2 * W**2 / (W**2 - Wc**2) - 1)
        assert above == pytest.approx(predicted, rel=0.02)  # nonlinear terms O(lean^2)
    below, _ = max_lean(model, 0.7 * Wc, lean0)
    assert below > 30 * lean0


def test_going_flat_stops_cleanly():
    """Very slow spin: the disk falls; the simulation stops before th2 = pi/2, flagged, finite."""
    model = RollingDisk()
    q, v = model.rolling_state(lean=0.05, dspin=0.2)
    tr = simulate(model, q, v, 2.0, dt=1e-3)  # it reaches the flat margin at t = 0.82 s
    assert tr.diverged
    assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v))
    assert np.max(np.abs(tr.q[:, 4])) <= model.flat_lean
    with pytest.raises(ValueError, match="lean"):
        model.rolling_state(lean=1.56)


@pytest.mark.parametrize(
    "kwargs, culprit", [({"m": 0.0}, "m"), ({"r": -1.0}, "r"), ({"b_roll": -0.1}, "b_roll"), ({"g": np.nan}, "g")]
)
def test_bad_parameters(kwargs, culprit):
    with pytest.raises(ValueError, match=culprit):
        RollingDisk(**kwargs)


def test_batched_equals_unbatched():
    model = RollingDisk()
    states = [random_state(model) for _ in range(4)]
    q = np.stack([s[0] for s in states])
    v = np.stack([s[1] for s in states])
    a = model.forward_dynamics(q, v, np.ones((4, 2)) * 0.1)
    for i in range(4):
        np.testing.assert_allclose(a[i], model.forward_dynamics(q[i], v[i], [0.1, 0.1]), rtol=1e-13, atol=1e-13)
