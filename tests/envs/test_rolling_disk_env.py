"""RollingDisk-v0 through the API, and its controllers."""

from __future__ import annotations


import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401
from mbs_envs.controllers import LQR, NoControl, SteeringPD
from mbs_envs.controllers.disk import linearize

ENV_ID = "mbs_envs/RollingDisk-v0"


def test_states_stay_on_the_constraints_and_info_is_complete():
    env = gym.make(ENV_ID)
    env.reset(seed=1)
    for _ in range(100):
        *_, info = env.step(np.zeros(2, np.float32))
    model = env.unwrapped.model
    q, v = env.unwrapped.q, env.unwrapped.v
    assert info["constraint_residual"] <= 1e-12
    np.testing.assert_allclose(model.constraint_jacobian(q) @ v, 0, atol=1e-10)
    for key in ("energy", "lean", "fell", "tracking_error", "spin_error", "diverged", "u"):
        assert key in info


def test_exact_start_state_is_projected_onto_the_rolling_constraints():
    env = gym.make(ENV_ID)
    model = env.unwrapped.model
    q = np.array([0.5, -0.2, 0.2, 0.3, 0.1, 0.0])  # z off the ground on purpose
    v = np.array([0.0, 0.0, 0.0, 0.2, 0.0, 5.0])  # centre velocity not rolling
    env.reset(seed=0, options={"q": q, "v": v})
    qp, vp = env.unwrapped.q, env.unwrapped.v
    assert abs(model.constraint_residual(qp)[0]) <= 1e-12
    np.testing.assert_allclose(model.constraint_jacobian(qp) @ vp, 0, atol=1e-12)


def test_falling_past_the_lean_limit_terminates():
    env = gym.make(ENV_ID, lean_limit=0.3)
    model = env.unwrapped.model
    q, v = model.rolling_state(lean=0.2, dspin=0.1)  # far below the critical spin
    env.reset(seed=0, options={"q": q, "v": v})
    for _ in range(500):
        obs, r, term, trunc, info = env.step(np.zeros(2, np.float32))
        if term:
            break
    assert term and info["fell"] and not info["diverged"]
    assert np.all(np.isfinite(obs))


def test_near_flat_is_reported_as_divergence_never_nan():
    """With the lean limit near flat, a falling disk stops at the Euler-angle margin with a flag."""
    env = gym.make(ENV_ID, lean_limit=1.52)
    q, v = env.unwrapped.model.rolling_state(lean=1.2, dspin=0.0)
    env.reset(seed=0, options={"q": q, "v": v})
    for _ in range(300):
        obs, r, term, trunc, info = env.step(np.zeros(2, np.float32))
        assert np.all(np.isfinite(obs)) and np.isfinite(r)
        if term:
            break
    assert term and (info["diverged"] or info["fell"])


def test_bad_spin_ref_option():
    with pytest.raises(ValueError, match="spin_ref"):
        gym.make(ENV_ID).reset(seed=0, options={"spin_ref": np.nan})


@pytest.mark.parametrize(
    "kwargs, match",
    [({"lean_limit": 2.0}, "lean_limit"), ({"stabilization": "x"}, "stabilization"), ({"params": {"r": 0.0}}, "r")],
)
def test_bad_construction(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make(ENV_ID, **kwargs)


def test_linearize_matches_a_known_linear_system():
    A0 = np.array([[0.0, 1.0], [-4.0, -0.5]])
    B0 = np.array([[0.0], [2.0]])
    A, B = linearize(lambda x, u: x @ A0.T + u @ B0.T, np.array([0.3, -0.1]), np.array([0.2]))
    np.testing.assert_allclose(A, A0, atol=1e-9)
    np.testing.assert_allclose(B, B0, atol=1e-9)


def test_lqr_gain_stabilizes_the_linearization_below_the_critical_spin():
    env = gym.make(ENV_ID)
    lqr = LQR(env)
    W = 0.5 * env.unwrapped.model.critical_spin
    A, B = lqr.system(W)
    assert np.max(np.linalg.eigvals(A).real) > 1.0  # upright rolling is unstable here
    Aa, Ba = lqr.augmented(W)  # with the heading integral; W between grid points: an interpolated gain
    closed = Aa - Ba @ lqr.gain(W)
    assert np.max(np.linalg.eigvals(closed).real) < 0


def test_lqr_keeps_the_disk_up_where_the_passive_disk_falls():
    env = gym.make(ENV_ID)
    model = env.unwrapped.model
    results = {}
    for C in (NoControl, SteeringPD, LQR):
        controller = C(env)
        W = 0.45 * model.critical_spin
        q, v = model.rolling_state(lean=0.05, dspin=W)
        obs, _ = env.reset(seed=0, options={"q": q, "v": v, "spin_ref": W})
        assert obs[7] == pytest.approx(W)
        steps = 0
        for steps in range(1, 401):
            obs, _, term, trunc, info = env.step(controller.predict(obs)[0])
            if term:
                break
        results[C.__name__] = (term, steps)
    assert results["NoControl"][0]  # falls
    assert not results["LQR"][0]  # stays up for 4 s


def test_controller_predict_batched():
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    for C in (NoControl, SteeringPD, LQR):
        a, _ = C(env).predict(np.stack([obs, obs]))
        assert a.shape == (2, 2) and a.dtype == np.float32
