"""The L-stable implicit steppers: stability functions, orders, Newton fall-backs, stiff cases."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs import integrators, simulate
from mbs_envs.models import Planar2R
from tests.test_integrators import observed_order

IMPLICIT = ["implicit_euler", "sdirk2", "sdirk3"]


def stability_matrix(tab, Z):
    """``R(Z) = I + (b^T kron Z) (I - A kron Z)^-1 (1 kron I)`` for ``y' = L y``, ``Z = h L``.

    The textbook stability function of a Runge-Kutta method, evaluated for a
    matrix argument: independent of the stepper's stage-by-stage Newton path.
    """
    A = np.array(tab.A, float)
    b = A[-1]
    s, n = len(b), Z.shape[0]
    big = np.eye(s * n) - np.kron(A, Z)
    ones = np.kron(np.ones((s, 1)), np.eye(n))
    return np.eye(n) + np.kron(b[None, :], Z) @ np.linalg.solve(big, ones)


@pytest.mark.parametrize("name", IMPLICIT)
def test_linear_damped_rotor_follows_the_stability_function(name):
    """q'' = -c q' (c = 2000 1/s, h c = 20: far beyond explicit stability) from (q, v) = (0.3, 5)."""
    c, h = 2000.0, 0.01
    stepper = integrators.get(name)
    y = np.array([0.3, 5.0])
    q, v = y[:1], y[1:]
    L = np.array([[0.0, 1.0], [0.0, -c]])
    R = stability_matrix(stepper.tableau, h * L)
    for _ in range(20):
        q, v = stepper.step(lambda t, q, v: -c * v, 0.0, q, v, h)
        y = R @ y
        np.testing.assert_allclose(np.r_[q, v], y, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", IMPLICIT)
def test_l_stability(name):
    """|R(z)| -> 0 as z -> -inf: the stiff mode is annihilated in one step."""
    tab = integrators.get(name).tableau
    r = stability_matrix(tab, np.array([[-1e8]]))[0, 0]
    assert abs(r) < 1e-7
    for z in (-0.5, -5.0, -50.0):
        assert abs(stability_matrix(tab, np.array([[z]]))[0, 0]) < 1


@pytest.mark.parametrize(
    "name, dts",
    [
        ("implicit_euler", [2e-3, 1e-3, 5e-4, 2.5e-4]),
        ("sdirk2", [1e-2, 5e-3, 2.5e-3, 1.25e-3]),
        ("sdirk3", [2e-2, 1e-2, 5e-3, 2.5e-3]),
    ],
)
def test_convergence_order_on_the_2r(name, dts):
    # measured 0.991, 2.007, 3.009
    p = observed_order(name, dts)
    assert abs(p - integrators.get(name).order) < 0.15, p


def cubic_damping(t, q, v):
    return -100.0 * v**3


def test_slow_newton_refreshes_the_jacobian_and_halves_the_step():
    """v' = -100 v^3 from v = 10, h = 1: the step-start Jacobian is 30x too stiff."""
    stepper = integrators.get("implicit_euler")
    q0, v0 = np.zeros(1), np.array([10.0])
    q, v = stepper.step(cubic_damping, 0.0, q0, v0, 1.0)
    assert np.all(np.isfinite(v))
    assert stepper.counters["halvings"] >= 1  # counted for the reports
    # one full step does not converge, even with Jacobian refreshes ...
    no_halving = dataclasses.replace(stepper, max_halvings=0)
    assert np.all(np.isnan(no_halving.step(cubic_damping, 0.0, q0, v0, 1.0)[1]))
    # ... so the result is two half steps, each allowed one halving less
    half = dataclasses.replace(stepper, max_halvings=stepper.max_halvings - 1)
    qm, vm = half.step(cubic_damping, 0.0, q0, v0, 0.5)
    q2, v2 = half.step(cubic_damping, 0.5, qm, vm, 0.5)
    np.testing.assert_array_equal(v, v2)
    # the Jacobian refresh is what makes moderate steps converge without halving
    frozen = dataclasses.replace(stepper, max_refresh=0, max_halvings=0)
    refreshed = dataclasses.replace(stepper, max_halvings=0)
    assert np.isnan(frozen.step(cubic_damping, 0.0, q0, v0, 0.01)[1][0])
    v_ie = refreshed.step(cubic_damping, 0.0, q0, v0, 0.01)[1][0]
    assert abs(v_ie - v0[0] + 0.01 * 100.0 * v_ie**3) < 1e-9  # the implicit Euler equation


def test_batched_equals_single_even_where_members_halve():
    stepper = integrators.get("sdirk2")
    v0 = np.array([[10.0], [0.1], [-3.0]])
    qb, vb = stepper.step(cubic_damping, 0.0, np.zeros((3, 1)), v0, 1.0)
    for i in range(3):
        q1, v1 = stepper.step(cubic_damping, 0.0, np.zeros(1), v0[i], 1.0)
        np.testing.assert_array_equal(q1, qb[i])
        np.testing.assert_array_equal(v1, vb[i])


def test_newton_failure_is_reported_as_divergence():
    """No step size rescues a NaN right-hand side: NaN state, flagged by simulate."""
    tr = simulate(
        Planar2R(),
        [0.0, 0.0],
        [0.0, 0.0],
        0.05,
        dt=0.01,
        integrator="sdirk2",
        u=lambda t, q, v: np.where(t > 0.02, np.nan, 0.0) * np.ones(2),
    )
    assert tr.diverged and np.all(np.isfinite(tr.q))


STIFF = {"b1": 400.0, "b2": 400.0}


def test_stiff_friction_rk4_limit_versus_implicit_at_ten_times_the_step():
    """Planar2R with b1 = b2 = 400 N m s/rad: the fast mode is -4.4e3 1/s at the start state,
    so RK4's real-axis limit is 2.785 / 4.4e3 = 6.3e-4 s. RK4 diverges at 1e-3 s; the
    L-stable methods run at 6.3e-3 s (10x the limit) and 1e-2 s with errors below 1e-5 rad."""
    model = Planar2R(**STIFF)
    q0, v0, u = np.array([-1.0, 0.5]), np.array([1.0, -2.0]), np.array([30.0, 5.0])
    lam = np.linalg.eigvals(np.linalg.solve(model.mass_matrix(q0), 400.0 * np.eye(2)))
    h_rk4 = 2.785 / np.max(lam)
    assert simulate(model, q0, v0, 0.5, dt=1e-3, integrator="rk4", u=u).diverged
    assert not simulate(model, q0, v0, 0.5, dt=0.5 * h_rk4, integrator="rk4", u=u).diverged
    ref = simulate(model, q0, v0, 1.0, dt=1.0, integrator="radau", u=u, rtol=1e-12, atol=1e-12)
    for name in IMPLICIT:
        for dt in (10 * h_rk4, 1e-2):
            tr = simulate(model, q0, v0, 1.0, dt=dt, integrator=name, u=u)
            assert not tr.diverged
            # measured at 1e-2: 7.8e-6 (implicit Euler), 2.6e-7 (sdirk2), 2.1e-7 (sdirk3)
            assert np.max(np.abs(tr.q[-1] - ref.q[-1])) < 1e-5, name


def test_stiff_env_reports_rk4_divergence_and_runs_implicit():
    """The same claim through gym.make: divergence is in info, never a NaN observation."""
    env = gym.make("mbs_envs/Planar2R-v0", params=STIFF, integrator="rk4")
    env.reset(seed=0)
    obs, _, term, _, info = env.step(np.ones(2, np.float32))
    for _ in range(20):
        if term:
            break
        obs, _, term, _, info = env.step(np.ones(2, np.float32))
    assert term and info["diverged"] and np.all(np.isfinite(obs))
    env = gym.make("mbs_envs/Planar2R-v0", params=STIFF, integrator="sdirk2")
    env.reset(seed=0)
    for _ in range(100):
        obs, _, term, _, info = env.step(np.ones(2, np.float32))
        assert not term and not info["diverged"] and np.all(np.isfinite(obs))


def test_names_are_listed_and_take_no_options():
    for name in IMPLICIT:
        assert name in integrators.available()
        with pytest.raises(ValueError, match="no options"):
            integrators.get(name, rtol=1e-3)


def test_adaptive_solves_count_their_steps_and_evaluations():
    stepper = integrators.get("radau", rtol=1e-8, atol=1e-8)
    tr = simulate(
        Planar2R(b1=400.0, b2=400.0), [-1.0, 0.5], [1.0, -2.0], 0.2, dt=0.2, integrator=stepper, u=np.array([30.0, 5.0])
    )
    assert not tr.diverged
    c = stepper.counters
    assert 0 < c["steps"] < c["evaluations"] and c["jacobians"] >= 1
