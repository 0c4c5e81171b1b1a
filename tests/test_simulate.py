"""simulate(): invariants, inputs, batches, divergence, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from mbs_envs import simulate
from mbs_envs.models import Planar2R

Q0 = np.array([0.3, 1.2])
V0 = np.array([2.0, -3.0])


def test_energy_conserved_without_input_or_friction():
    model = Planar2R()
    E0 = model.energy(Q0, V0)
    drift = {}
    for dt in (1e-3, 5e-4):
        tr = simulate(model, Q0, V0, 10.0, dt=dt, integrator="rk4")
        drift[dt] = np.max(np.abs(model.energy(tr.q, tr.v) - E0))
    # measured: 3.9e-7 J at dt = 1e-3 (E0 = 11.7 J), 15x smaller at half the step (order 4)
    assert drift[1e-3] < 1e-6
    assert drift[1e-3] / drift[5e-4] > 12.0
    tr = simulate(model, Q0, V0, 10.0, dt=0.5, integrator="dop853", rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(model.energy(tr.q, tr.v) - E0)) / abs(E0) < 1e-9


def test_semi_implicit_euler_energy_stays_bounded_where_euler_drifts():
    model = Planar2R()
    q0, v0 = np.array([-1.3, 0.2]), np.zeros(2)
    E0 = model.energy(q0, v0)
    err = {}
    for name in ("euler", "semi_implicit_euler"):
        tr = simulate(model, q0, v0, 20.0, dt=1e-3, integrator=name)
        err[name] = np.max(np.abs(model.energy(tr.q, tr.v) - E0))
    # measured over 50 s: 4.4e-3 J (bounded, oscillating) against 0.63 J (growing)
    assert err["semi_implicit_euler"] < 0.05 * err["euler"]


def test_work_energy_balance_with_input_and_friction():
    """E(T) - E(0) = int (v.u - v.F(v)) dt along the simulated motion (Simpson's rule on the step grid)."""
    from scipy.integrate import simpson

    model = Planar2R(b1=0.5, b2=0.3, f1=0.2, v_s=0.1)

    def u(t, q, v):
        return np.array([3.0 * np.sin(2 * t), -2.0 + 0 * t])

    tr = simulate(model, Q0, V0, 3.0, dt=5e-4, integrator="rk4", u=u)
    P = np.array([model.input_power(v, u(t, q, v)) - model.friction_power(v) for t, q, v in zip(tr.t, tr.q, tr.v)])
    work = simpson(P, x=tr.t)
    dE = model.energy(tr.q[-1], tr.v[-1]) - model.energy(Q0, V0)
    # RK4 and Simpson are both O(dt^4): measured 1.3e-9, 8.3e-11, 5.5e-12 at dt = 1e-3, 5e-4, 2.5e-4
    # (16x per halving); the bound leaves 12x margin at 5e-4 (the trapezoid's error was 3.5e-6 here)
    assert dE == pytest.approx(work, abs=1e-9)


def test_constant_and_callable_inputs_agree():
    model = Planar2R()
    a = simulate(model, Q0, V0, 1.0, dt=1e-2, u=np.array([1.0, -2.0]), compiled=False)
    b = simulate(model, Q0, V0, 1.0, dt=1e-2, u=lambda t, q, v: np.array([1.0, -2.0]))
    np.testing.assert_array_equal(a.q, b.q)
    # a held input runs compiled by default: the same stages, equal to rounding
    c = simulate(model, Q0, V0, 1.0, dt=1e-2, u=np.array([1.0, -2.0]))
    np.testing.assert_allclose(c.q, a.q, rtol=0, atol=1e-12)


def test_batch_matches_individual_runs():
    model = Planar2R()
    q0 = np.array([[0.1, 0.2], [1.0, -1.0], [-2.0, 0.5]])
    v0 = np.array([[0.0, 0.0], [1.0, 1.0], [-1.0, 2.0]])
    tr = simulate(model, q0, v0, 0.5, dt=1e-2)
    assert tr.q.shape == (51, 3, 2) and tr.t.shape == (51,) and tr.diverged.shape == (3,)
    for i in range(3):
        one = simulate(model, q0[i], v0[i], 0.5, dt=1e-2)
        np.testing.assert_allclose(tr.q[:, i], one.q, rtol=1e-14, atol=1e-14)


def test_grid_ends_exactly_at_t_final():
    tr = simulate(Planar2R(), Q0, V0, 0.105, dt=0.01)
    assert tr.t[-1] == 0.105 and len(tr.t) == 12


def test_divergence_is_reported_and_states_stay_finite():
    """Explicit Euler with a huge input and step blows up; the flag is set, no NaN returned."""
    model = Planar2R()
    tr = simulate(model, Q0, V0, 50.0, dt=0.5, integrator="euler", u=np.array([1e6, -1e6]))
    assert tr.diverged.all()
    assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v))
    # a batch where only one member blows up: the other is untouched
    u = np.array([[0.0, 0.0], [1e6, -1e6]])
    tr = simulate(
        model,
        np.stack([Q0, Q0]),
        np.stack([V0, V0]),
        2.0,
        dt=0.01,
        integrator="euler",
        u=u,
        divergence_limit=1e6,
    )
    assert tr.diverged.tolist() == [False, True]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"t_final": 0.0}, "t_final"),
        ({"dt": -1.0}, "dt"),
        ({"dt": float("nan")}, "dt"),
        ({"integrator": "nope"}, "unknown integrator"),
        ({"u": np.array([1.0])}, "u"),
        ({"u": np.array([np.nan, 0.0])}, "u must be finite"),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    args = {"t_final": 1.0, "dt": 0.01}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        simulate(Planar2R(), Q0, V0, **args)


def test_bad_initial_state_raises():
    with pytest.raises(ValueError, match="q0"):
        simulate(Planar2R(), [0.0], V0, 1.0)
    with pytest.raises(ValueError, match="finite"):
        simulate(Planar2R(), [np.nan, 0.0], V0, 1.0)
