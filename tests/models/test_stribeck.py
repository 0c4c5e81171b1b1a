"""The Stribeck option of the joint friction: its shape, that it leaves the default law bit for bit,
and that the compiled path computes it as the numpy path does."""

from __future__ import annotations

import numpy as np
import pytest

from mbs_envs.models import FourBar, Planar2R
from mbs_envs.models.base import friction_law, smoothed_friction
from mbs_envs.simulate import simulate


def test_without_an_excess_the_law_is_the_coulomb_one_bit_for_bit():
    v = np.random.default_rng(0).normal(scale=0.05, size=(50, 2))
    b, f = np.array([0.1, 0.2]), np.array([1.0, 0.5])
    np.testing.assert_array_equal(smoothed_friction(v, b, f, 1e-3, np.zeros(2), 0.05), friction_law(v, b, f, 1e-3))
    np.testing.assert_array_equal(Planar2R(f1=1.0, v_st=0.5).friction(v), Planar2R(f1=1.0).friction(v))


def test_the_static_peak_and_its_fading():
    """``F -> f + df`` for ``v_s << v << v_st``, ``F -> b v + f`` for ``v >> v_st``; odd; its slope at rest."""
    m = Planar2R(f1=1.0, f2=0.0, df1=0.5, df2=0.3, v_s=1e-4, v_st=0.1)
    F = m.friction(np.array([[1e-2, 1e-2], [10.0, 10.0], [-1e-2, -1e-2]]))
    assert F[0, 0] == pytest.approx(1.0 + 0.5 * np.exp(-0.01), rel=1e-12)  # tanh(100) = 1 in floating point
    assert F[0, 1] == pytest.approx(0.3 * np.exp(-0.01), rel=1e-12)  # a Stribeck peak without Coulomb friction
    assert F[1, 0] == pytest.approx(1.0, rel=1e-12) and abs(F[1, 1]) < 1e-40
    np.testing.assert_array_equal(F[2], -F[0])
    # smooth through rest: the slope there is b + (f + df) / v_s (what the joint-implicit step linearizes)
    m = Planar2R(b1=0.2, f1=1.0, f2=0.0, df1=0.5, df2=0.3, v_s=1e-2, v_st=0.1)
    slope = m.friction_slope(np.zeros(2))
    np.testing.assert_allclose(slope, [0.2 + 1.5 / 1e-2, 0.3 / 1e-2], rtol=1e-6)


@pytest.mark.parametrize("model, start", [
    (Planar2R(f1=1.0, f2=0.5, df1=1.0, df2=0.7, v_st=0.05, v_s=1e-3, b1=0.1), None),
    (FourBar(f1=0.3, df1=0.3, df3=0.2, v_st=0.05, v_s=1e-3), (0.2, 1.0)),
])  # fmt: skip
def test_compiled_path_equals_numpy_path_with_stribeck_friction(model, start):
    q0, v0 = (np.array([-1.0, 0.5]), np.array([0.3, -0.2])) if start is None else model.consistent_state(*start)
    u = 0.5 * np.ones(model.nu)
    a = simulate(model, q0, v0, 0.2, dt=1e-3, integrator="rk4", u=u, compiled=True)
    b = simulate(model, q0, v0, 0.2, dt=1e-3, integrator="rk4", u=u, compiled=False)
    assert not a.diverged
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-12)


def test_a_negative_excess_is_refused():
    with pytest.raises(ValueError, match="df1"):
        Planar2R(df1=-1.0)
    with pytest.raises(ValueError, match="v_st"):
        FourBar(v_st=0.0)
