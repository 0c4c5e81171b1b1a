"""Integrators: measured convergence orders, closed forms, names and options."""

from __future__ import annotations

import numpy as np
import pytest

from mbs_envs import integrators, simulate
from mbs_envs.models import Planar2R

Q0 = np.array([-1.0, 0.8])
V0 = np.array([0.5, -1.0])


def observed_order(name: str, dts: list[float], t_final: float = 1.0) -> float:
    """Least-squares slope of log(error at t_final) against log(dt)."""
    model = Planar2R(b1=0.1, f2=0.05, v_s=0.5)
    ref = simulate(model, Q0, V0, t_final, dt=t_final, integrator="dop853", rtol=1e-13, atol=1e-13)
    x_ref = np.r_[ref.q[-1], ref.v[-1]]
    errors = []
    for dt in dts:
        tr = simulate(model, Q0, V0, t_final, dt=dt, integrator=name)
        errors.append(np.linalg.norm(np.r_[tr.q[-1], tr.v[-1]] - x_ref))
    return float(np.polyfit(np.log(dts), np.log(errors), 1)[0])


@pytest.mark.parametrize(
    "name, dts",
    [
        ("euler", [2e-3, 1e-3, 5e-4, 2.5e-4]),
        ("semi_implicit_euler", [2e-3, 1e-3, 5e-4, 2.5e-4]),
        ("midpoint", [1e-2, 5e-3, 2.5e-3, 1.25e-3]),
        ("rk4", [1e-2, 5e-3, 2.5e-3, 1.25e-3]),  # asymptotic range (error ratios 17.6 -> 16.4)
    ],
)
def test_convergence_order(name, dts):
    p = observed_order(name, dts)
    assert abs(p - integrators.get(name).order) < 0.15, p


def harmonic(t, q, v):
    return -q


@pytest.mark.parametrize("name", ["euler", "semi_implicit_euler", "midpoint", "rk4"])
def test_one_step_against_taylor_series(name):
    """One step on q'' = -q from (1, 0): the error is O(h^(p+1)) with the right constant order."""
    stepper = integrators.get(name)
    errs = []
    for h in (0.1, 0.05):
        q, v = stepper.step(harmonic, 0.0, np.array([1.0]), np.array([0.0]), h)
        errs.append(np.hypot(q[0] - np.cos(h), v[0] + np.sin(h)))
    assert np.log2(errs[0] / errs[1]) == pytest.approx(stepper.order + 1, abs=0.2)


def test_semi_implicit_euler_is_the_symplectic_variant():
    """v+ = v + h a(q, v), q+ = q + h v+: area preserving on the oscillator (det = 1)."""
    stepper = integrators.get("semi_implicit_euler")
    h = 0.1
    q, v = stepper.step(harmonic, 0.0, np.array([1.0, 0.0]), np.array([0.0, 1.0]), h)
    np.testing.assert_allclose(v, [-h, 1.0], atol=1e-15)
    np.testing.assert_allclose(q, [1.0 - h * h, h], atol=1e-15)
    assert np.linalg.det(np.array([[q[0], q[1]], [v[0], v[1]]])) == pytest.approx(1.0, abs=1e-14)


@pytest.mark.parametrize("name", ["rk45", "dop853", "radau", "bdf", "lsoda"])
def test_scipy_methods_reach_their_tolerance(name):
    tr = simulate(Planar2R(), Q0, V0, 1.0, dt=0.1, integrator=name, rtol=1e-9, atol=1e-11)
    ref = simulate(Planar2R(), Q0, V0, 1.0, dt=0.1, integrator="dop853", rtol=1e-13, atol=1e-13)
    assert tr.t.shape == (11,)
    assert np.max(np.abs(tr.q - ref.q)) < 1e-6


def test_available_names_and_errors():
    names = integrators.available()
    for name in ("euler", "semi_implicit_euler", "rk4", "rk45", "dop853", "radau", "bdf", "lsoda"):
        assert name in names
    with pytest.raises(ValueError, match="unknown integrator 'rk5'"):
        integrators.get("rk5")
    with pytest.raises(ValueError, match="takes no options"):
        integrators.get("rk4", rtol=1e-6)
    with pytest.raises(ValueError, match="rtol"):
        integrators.get("radau", rtol=-1.0)
    with pytest.raises(ValueError, match="rtol and atol only"):
        integrators.get("bdf", first_step=0.1)


def test_tableaux_are_consistent():
    """Row sums equal c (for plain methods); weights sum to one."""
    for name, tab in integrators.TABLEAUX.items():
        assert sum(tab.b_v) == pytest.approx(1.0), name
        assert sum(tab.b_q) == pytest.approx(1.0), name
        if tab.A_q == tab.A_v:
            np.testing.assert_allclose(np.sum(tab.A_v, axis=1), tab.c, err_msg=name)
