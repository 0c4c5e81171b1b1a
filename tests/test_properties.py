"""Property tests over random parameters and states, for every model (Hypothesis).

- ``M(q)`` symmetric positive definite;
- ``inverse_dynamics(forward_dynamics(u)) == u`` where the model is fully actuated;
- along the motion ``dE/dt = input power - friction power`` (ideal constraints do no work);
- the constrained accelerations satisfy ``Psi a + dPsi v = 0``;
- batched evaluation equals member-by-member evaluation.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mbs_envs.models import FourBar, Planar2R, RollingDisk, SerialChain

SEEDS = st.integers(0, 2**32 - 1)
SETTINGS = settings(max_examples=40, deadline=None)


def planar2r(rng):
    m = rng.uniform(0.1, 10, 2)
    l = rng.uniform(0.1, 3, 2)  # noqa: E741
    return Planar2R(
        m1=m[0], m2=m[1], l1=l[0], l2=l[1], r1=l[0] * rng.uniform(0, 1), r2=l[1] * rng.uniform(0, 1),
        I1=m[0] * l[0] ** 2 * rng.uniform(0.01, 0.2), I2=m[1] * l[1] ** 2 * rng.uniform(0.01, 0.2),
        b1=rng.uniform(0, 2), b2=rng.uniform(0, 2), f1=rng.uniform(0, 1), f2=rng.uniform(0, 1), v_s=rng.uniform(0.05, 1),
    )  # fmt: skip


def chain(rng):
    n = int(rng.integers(1, 13))
    m, l = rng.uniform(0.05, 5, n), rng.uniform(0.05, 2, n)  # noqa: E741
    return SerialChain(n_links=n, m=m, l=l, r=l * rng.uniform(0, 1, n), I=m * l**2 * rng.uniform(0.01, 0.2, n),
                       armature=rng.uniform(0, 0.1, n), b=rng.uniform(0, 1, n), f=rng.uniform(0, 0.5, n), v_s=0.2)  # fmt: skip


def fourbar(rng):
    s = rng.uniform(0.2, 5, 3)
    return FourBar(m1=0.3 * s[0], m2=1.0 * s[1], m3=0.8 * s[2], b1=rng.uniform(0, 1), f1=rng.uniform(0, 0.5), v_s=0.2)


def disk(rng):
    return RollingDisk(m=rng.uniform(0.1, 10), r=rng.uniform(0.05, 1))


def serial_state(model, rng, batch=()):
    n = model.nq
    return (
        rng.uniform(-np.pi, np.pi, batch + (n,)),
        rng.uniform(-5, 5, batch + (n,)),
        rng.uniform(-20, 20, batch + (model.nu,)),
    )


def constrained_state(model, rng):
    if isinstance(model, FourBar):
        q, v = model.consistent_state(rng.uniform(-np.pi, np.pi), rng.uniform(-5, 5))
    else:
        W = model.critical_spin
        q, v = model.rolling_state(heading=rng.uniform(-3, 3), lean=rng.uniform(-1, 1), spin=rng.uniform(-3, 3),
                                   dheading=rng.uniform(-2, 2), dlean=rng.uniform(-2, 2), dspin=rng.uniform(-3, 3) * W)  # fmt: skip
    u = rng.uniform(-2, 2, model.nu)
    return q, v, u


MAKERS = {"planar2r": planar2r, "chain": chain, "fourbar": fourbar, "disk": disk}


def model_and_state(name, seed):
    rng = np.random.default_rng(seed)
    model = MAKERS[name](rng)
    q, v, u = constrained_state(model, rng) if model.constrained else serial_state(model, rng)
    return model, q, v, u


@SETTINGS
@given(st.sampled_from(list(MAKERS)), SEEDS)
def test_mass_matrix_symmetric_positive_definite(name, seed):
    model, q, _, _ = model_and_state(name, seed)
    M = model.mass_matrix(q)
    scale = np.max(np.abs(M))
    np.testing.assert_allclose(M, M.T, rtol=0, atol=1e-12 * scale)
    assert np.min(np.linalg.eigvalsh(M)) > 0


@SETTINGS
@given(st.sampled_from(["planar2r", "chain"]), SEEDS)
def test_inverse_dynamics_inverts_forward_dynamics(name, seed):
    """Fully actuated: u -> a -> u. Tolerance: round-off amplified by cond(M) (below 1e6 here)."""
    model, q, v, u = model_and_state(name, seed)
    a = model.forward_dynamics(q, v, u)
    scale = max(np.max(np.abs(u)), np.max(np.abs(model.bias(q, v))), 1.0)
    np.testing.assert_allclose(model.inverse_dynamics(q, v, a), u, rtol=0, atol=1e-9 * scale)


@SETTINGS
@given(st.sampled_from(list(MAKERS)), SEEDS)
def test_energy_rate_is_input_power_minus_friction_power(name, seed):
    """dE/dt by a central difference along (v, a): O(eps^2) truncation, O(1e-16 |E| / eps) round-off."""
    model, q, v, u = model_and_state(name, seed)
    a = model.forward_dynamics(q, v, u)
    eps = 1e-6
    dE = (model.energy(q + eps * v, v + eps * a) - model.energy(q - eps * v, v - eps * a)) / (2 * eps)
    expected = model.input_power(v, u) - model.friction_power(v)
    power_scale = (
        float(np.abs(v) @ np.abs(model.mass_matrix(q) @ a))
        + abs(float(model.input_power(v, u)))
        + abs(float(model.friction_power(v)))
    )
    scale = abs(float(model.energy(q, v))) + power_scale + 1.0
    # measured worst over 200 draws per model: 9.5e-10 of scale (the disk); 1e-7 leaves 100x
    assert abs(float(dE) - float(expected)) < 1e-7 * scale


@SETTINGS
@given(st.sampled_from(["fourbar", "disk"]), SEEDS)
def test_constrained_accelerations_satisfy_the_constraints(name, seed):
    model, q, v, u = model_and_state(name, seed)
    a = model.forward_dynamics(q, v, u)
    residual = model.constraint_jacobian(q) @ a + model.constraint_bias(q, v)
    scale = max(float(np.max(np.abs(model.constraint_bias(q, v)))), float(np.max(np.abs(a))), 1.0)
    np.testing.assert_allclose(residual, 0.0, atol=1e-10 * scale)


@SETTINGS
@given(st.sampled_from(list(MAKERS)), SEEDS)
def test_batched_evaluation_equals_member_by_member(name, seed):
    rng = np.random.default_rng(seed)
    model = MAKERS[name](rng)
    states = [constrained_state(model, rng) if model.constrained else serial_state(model, rng) for _ in range(3)]
    Q, V, U = (np.stack([s[k] for s in states]) for k in range(3))
    A = model.forward_dynamics(Q, V, U)
    E = model.energy(Q, V)
    for i, (q, v, u) in enumerate(states):
        a = model.forward_dynamics(q, v, u)
        np.testing.assert_allclose(A[i], a, rtol=1e-13, atol=1e-13 * max(1.0, float(np.max(np.abs(a)))))
        assert E[i] == np.float64(model.energy(q, v)) or abs(E[i] - model.energy(q, v)) <= 1e-13 * abs(E[i])
