"""The compiled path (mbs_envs.dynamics.compiled) against the numpy path it must reproduce.

The two share the formulas (written once) but not the code that runs them:
the numpy path solves ``M a = rhs`` by Cholesky over whole arrays and steps
through :class:`~mbs_envs.dynamics.integrators.ExplicitRK` and the env's task methods;
the compiled one uses Cramer's rule per member and its own vectorizable sincos
(mbs_envs.dynamics.trig, 1 ulp) inside one fused kernel. They may differ by rounding
only: per step, 1e-12.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs  # noqa: F401  (registers the ids)
from mbs_envs import integrators
from mbs_envs.dynamics.compiled import advance_compiled, batch_theta, compiled_stepping
from mbs_envs.envs.actions import validate_action
from mbs_envs.models import FourBar, Planar2R, RollingDisk
from mbs_envs.dynamics.simulate import advance

ID = "mbs_envs/Planar2R-v0"


def random_model(rng, batch=None):
    """A Planar2R with random inertias and friction (per-member parameters with ``batch``)."""
    draw = {k: rng.uniform(0.3, 2.0, batch) for k in ("m1", "m2", "l1", "l2", "r1", "r2")}
    draw.update({k: rng.uniform(0.0, 0.5, batch) for k in ("I1", "I2", "b1", "b2", "f1", "f2")})
    if batch is None:
        return Planar2R(**draw)
    return Planar2R().with_params(Planar2R().params.batched(**draw))


def run_kernels(model, q, v, tau):
    """The model's compiled kernels on rows ``(B, 2)`` (they take columns), as rows."""
    acc, energy = model.kernels
    theta = batch_theta(model, q.shape[0])
    a, E = np.empty((2, q.shape[0])), np.empty(q.shape[0])
    acc(q.T.copy(), v.T.copy(), tau.T.copy(), theta, a)
    energy(q.T.copy(), v.T.copy(), theta, E)
    return a.T, E


def test_acceleration_and_energy_kernels_equal_the_numpy_model():
    rng = np.random.default_rng(0)
    B = 200
    model = random_model(rng, B)
    q = rng.uniform(-4, 4, (B, 2))
    v = rng.uniform(-6, 6, (B, 2))
    tau = rng.uniform(-30, 30, (B, 2))
    a, E = run_kernels(model, q, v, tau)
    a_np = model.forward_dynamics(q, v, tau)
    scale = np.max(np.abs(a_np), axis=-1, keepdims=True)
    assert np.max(np.abs(a - a_np) / scale) < 1e-12
    np.testing.assert_allclose(E, model.energy(q, v), rtol=1e-12, atol=1e-12)


def test_kernels_take_libm_for_angles_outside_the_fast_sincos_range():
    """Members with huge or non-finite angles go through the scalar libm pass; the others are unaffected."""
    rng = np.random.default_rng(3)
    model = random_model(rng)
    q = rng.uniform(-4, 4, (9, 2))
    # one huge angle, the other zero: then numpy's cos(th1 + th2) is libm's of the huge one, exactly
    q[2], q[3], q[4] = (3e6, 0.0), (0.0, -1e20), (1e20, 0.0)  # the fast sincos is off by 1e29 at 1e20
    q[5, 0], q[6, 1] = np.nan, np.inf
    v, tau = rng.uniform(-6, 6, (9, 2)), rng.uniform(-30, 30, (9, 2))
    a, E = run_kernels(model, q, v, tau)
    with np.errstate(invalid="ignore"):
        a_np, E_np = model.forward_dynamics(q, v, tau), model.energy(q, v)
    ok = np.isfinite(q).all(axis=-1)
    scale = np.max(np.abs(a_np[ok]), axis=-1, keepdims=True)
    assert np.max(np.abs(a - a_np)[ok] / scale) < 1e-12
    np.testing.assert_allclose(E[ok], E_np[ok], rtol=1e-12, atol=1e-12)
    assert np.all(np.isnan(a[~ok])) and np.all(np.isnan(E[~ok]))


def test_one_member_kernel_path_equals_the_batched_passes_bit_for_bit():
    """A single member takes straight-line scalar code; it must give exactly what its column of a batch gets,
    also where the angle is out of the fast sincos range or not finite (libm in both)."""
    rng = np.random.default_rng(4)
    B = 12
    model = random_model(rng, B)
    q = rng.uniform(-4, 4, (B, 2))
    q[2], q[3], q[4, 1] = (3e6, 0.0), (0.0, -1e20), np.nan
    v, tau = rng.uniform(-6, 6, (B, 2)), rng.uniform(-30, 30, (B, 2))
    a, _ = run_kernels(model, q, v, tau)
    acc = model.kernels[0]
    theta = batch_theta(model, B)
    for b in range(B):
        a1 = np.empty((2, 1))
        acc(q[b, :, None].copy(), v[b, :, None].copy(), tau[b, :, None].copy(), theta[:, b : b + 1].copy(), a1)
        np.testing.assert_array_equal(a1[:, 0], a[b])


@pytest.mark.parametrize("name", sorted(integrators.TABLEAUX))
def test_compiled_advance_equals_numpy_advance_for_every_explicit_tableau(name):
    rng = np.random.default_rng(1)
    model = random_model(rng, 64)
    stepper = integrators.get(name)
    tab = compiled_stepping(model, stepper)
    q, v = rng.uniform(-3, 3, (64, 2)), rng.uniform(-4, 4, (64, 2))
    u = rng.uniform(-20, 20, (64, 2))
    qc, vc = advance_compiled(model, tab, q, v, u, 0.01, 3)
    qn, vn = advance(model, stepper, 0.0, q, v, 0.01, 3, u, compiled=False)
    np.testing.assert_allclose(qc, qn, rtol=0, atol=1e-12)
    qa, va = advance(model, stepper, 0.0, q, v, 0.01, 3, u)  # routed to the compiled kernels
    np.testing.assert_array_equal(qa, qc)
    np.testing.assert_array_equal(va, vc)
    np.testing.assert_allclose(vc, vn, rtol=0, atol=1e-12)
    # the arguments are not touched
    q2, v2 = advance_compiled(model, tab, q, v, u, 0.01, 3)
    np.testing.assert_array_equal(q2, qc)


@pytest.mark.parametrize("u", [None, np.array([3.0, -2.0]), "callable"])
def test_simulate_runs_compiled_where_it_can_and_equals_the_numpy_path(u):
    """A held input takes the kernels, a callable the numpy path; both give the same trajectory."""
    model = random_model(np.random.default_rng(5))
    if isinstance(u, str):
        u = lambda t, q, v: np.stack([np.full(v.shape[:-1], np.sin(t)), -v[..., 0]], axis=-1)  # noqa: E731
    q0, v0 = np.array([[1.0, -0.5], [2.5, 0.3]]), np.array([[0.0, 2.0], [-3.0, 1.0]])
    fast = mbs_envs.simulate(model, q0, v0, 2.0, dt=0.01, u=u)
    slow = mbs_envs.simulate(model, q0, v0, 2.0, dt=0.01, u=u, compiled=False)
    # per step the paths agree to 1e-12 (above); over 200 steps the rounding differences
    # (1-ulp sincos) grow along the trajectory: measured max 1.2e-12 on v, 9e-14 on q
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(fast.v, slow.v, rtol=0, atol=1e-11)
    if callable(u):
        np.testing.assert_array_equal(fast.q, slow.q)


def test_simulate_reports_a_compiled_blow_up_like_the_numpy_path():
    model = Planar2R(g=1e6)  # the state leaves |x| <= 1e6 within a few steps
    runs = [mbs_envs.simulate(model, [1.0, 0.0], [0.0, 0.0], 1.0, dt=0.05, compiled=c) for c in (True, False)]
    assert runs[0].diverged and runs[1].diverged
    np.testing.assert_array_equal(runs[0].q, runs[1].q)  # held at the same last finite state
    assert np.all(np.isfinite(runs[0].q))


def test_the_compiled_path_applies_exactly_where_it_is_exact():
    assert gym.make(ID).unwrapped.compiled is not None
    assert gym.make(ID, integrator="midpoint").unwrapped.compiled is not None
    for kwargs in ({"compiled": False}, {"integrator": "sdirk2"}, {"integrator": "rk45"}):
        assert gym.make(ID, **kwargs).unwrapped.compiled is None, kwargs
    # a constrained model: compiled with the projection after every step (its default), not otherwise
    assert gym.make("mbs_envs/FourBar-v0").unwrapped.compiled is not None
    for kind in ("baumgarte", "none"):
        assert gym.make("mbs_envs/FourBar-v0", stabilization=kind).unwrapped.compiled is None, kind
    assert compiled_stepping(FourBar(), integrators.get("rk4")) is None
    assert compiled_stepping(FourBar(), integrators.get("rk4"), FourBar().stabilization("projection")) is not None


def fourbar_case(rng, B):
    model = FourBar(b1=0.1, b3=0.05, f2=0.2)
    q0, v0 = model.consistent_state(rng.uniform(-np.pi, np.pi, B), rng.uniform(-5, 5, B))
    u = rng.uniform(-8, 8, (B, 1))
    return model, q0, v0, u


def disk_case(rng, B):
    model = RollingDisk(b_roll=0.01, b_pivot=0.02)
    states = [model.rolling_state(*rng.uniform(-3, 3, 1), *rng.uniform(-1.2, 1.2, 1), *rng.uniform(-3, 3, 1),
                                  *rng.uniform(-2, 2, 2), *rng.uniform(-30, 30, 1)) for _ in range(B)]  # fmt: skip
    q0, v0 = (np.array(x) for x in zip(*states))
    return model, q0, v0, rng.uniform(-1, 1, (B, 2))


@pytest.mark.parametrize("case", [fourbar_case, disk_case], ids=["fourbar", "disk"])
def test_constrained_kernels_equal_the_numpy_model(case):
    """Forward dynamics, energy, projection and multipliers, at random states (also off the constraints)."""
    import importlib

    rng = np.random.default_rng(7)
    B = 100
    model, q0, v0, u = case(rng, B)
    module = importlib.import_module(type(model).__module__)
    q, v = rng.uniform(-3, 3, q0.shape), rng.uniform(-5, 5, v0.shape)
    if isinstance(model, RollingDisk):
        q[:, 4] = rng.uniform(-1.4, 1.4, B)  # away from the flat singularity
    tau = model.generalized_input(u)
    theta = batch_theta(model, B)
    acc, energy = model.kernels
    a, E = np.empty(q.T.shape), np.empty(B)
    acc(q.T.copy(), v.T.copy(), tau.T.copy(), theta, a)
    energy(q.T.copy(), v.T.copy(), theta, E)
    a_np = model.forward_dynamics(q, v, u)
    assert np.max(np.abs(a.T - a_np) / np.max(np.abs(a_np), axis=-1, keepdims=True)) < 1e-12
    np.testing.assert_allclose(E, model.energy(q, v), rtol=1e-12, atol=1e-12)
    # near-consistent states (as after a step) projected by both paths
    q0, v0 = q0 + rng.normal(0, 1e-3, q0.shape), v0 + rng.normal(0, 1e-2, v0.shape)
    qc, vc = q0.T.copy(), v0.T.copy()
    module.project_kernel(qc, vc, theta, 1e-12)
    qn, vn = model.project(q0, v0, 1e-12)
    np.testing.assert_allclose(qc.T, qn, rtol=0, atol=1e-12)
    np.testing.assert_allclose(vc.T, vn, rtol=0, atol=1e-12 * np.max(np.abs(vn)))
    res, lam = np.empty(B), np.empty((B, model.nc))
    module.constraint_info_kernel(qn.T.copy(), vn.T.copy(), tau.T.copy(), theta, res, lam)
    lam_np = model.multipliers(qn, vn, u)
    assert np.max(np.abs(lam - lam_np)) < 1e-12 * np.max(np.abs(lam_np))
    np.testing.assert_allclose(res, np.max(np.abs(model.constraint_residual(qn)), axis=-1), rtol=0, atol=1e-15)


@pytest.mark.parametrize("case", [fourbar_case, disk_case], ids=["fourbar", "disk"])
def test_the_models_compiled_projection_and_multipliers_take_any_leading_shape(case):
    """``project_compiled`` and ``multipliers(compiled=True)`` (what a compiled env's reset uses, so that
    it needs no numpy-path kernel) equal the numpy methods for one state, rows and a (2, 3) grid of
    states, float32 input included; a NaN member stays NaN and leaves the others alone."""
    rng = np.random.default_rng(3)
    model, q0, v0, u = case(rng, 6)
    q0, v0 = q0 + rng.normal(0, 1e-3, q0.shape), v0 + rng.normal(0, 1e-2, v0.shape)
    q0[5, 0] = np.nan
    for shape in [(), (6,), (2, 3)]:
        n = int(np.prod(shape))
        q, v, uu = (x[: max(n, 1)].reshape(shape + x.shape[1:]) for x in (q0, v0, u))
        for dtype in (np.float64, np.float32):
            qc, vc = model.project_compiled(q.astype(dtype), v.astype(dtype))
            with np.errstate(all="ignore"):
                qn, vn = model.project(q.astype(dtype), v.astype(dtype))
            assert qc.shape == q.shape and vc.shape == v.shape and qc.dtype == np.float64
            np.testing.assert_allclose(qc, qn, rtol=0, atol=1e-12)
            np.testing.assert_allclose(vc, vn, rtol=0, atol=1e-12 * np.nanmax(np.abs(vn)))
        lam = model.multipliers(qn, vn, uu, compiled=True)
        with np.errstate(all="ignore"):
            lam_np = model.multipliers(qn, vn, uu)
        assert lam.shape == lam_np.shape == shape + (model.nc,)
        np.testing.assert_allclose(lam, lam_np, rtol=0, atol=1e-12 * np.nanmax(np.abs(lam_np)))
    assert np.isnan(qc[1, 2, 0]) and np.all(np.isfinite(qc[:1])) and np.all(np.isfinite(qc[1, :2]))


def test_constrained_kernels_hand_singular_and_broken_members_to_the_general_path():
    """Members the closed-form batch solve must not take (a change point of the parallelogram, where the
    complement's condition number is 3e15; a flat disk, whose M is singular; a NaN crank angle) get the
    numpy path's answers (pseudo-inverse, NaN); the members beside them are unaffected."""
    from mbs_envs.models import fourbar, rolling_disk

    rng = np.random.default_rng(11)
    cases = []
    para = FourBar(l0=1.0, l1=0.4, l2=1.0, l3=0.4)  # parallelogram: Psi loses rank at th1 = 0
    q = np.stack([para.assemble(x) for x in (0.0, 0.7, -1.2, 0.0)])
    q[3, 0] = np.nan
    cases.append((para, fourbar, q, rng.uniform(-2, 2, (4, 3)), rng.uniform(-3, 3, (4, 1))))
    disk = RollingDisk()
    q = np.array([disk.rolling_state(lean=x)[0] for x in (0.2, 0.0, -0.4, 0.1)])
    q[1, 4] = np.pi / 2  # flat: N is singular
    q[3, 5] = np.nan
    cases.append((disk, rolling_disk, q, rng.uniform(-2, 2, (4, 6)), rng.uniform(-1, 1, (4, 2))))
    for model, module, q, v, u in cases:
        theta, tau = batch_theta(model, 4), model.generalized_input(u)
        a = np.empty(q.T.shape)
        model.kernels[0](q.T.copy(), v.T.copy(), tau.T.copy(), theta, a)
        with np.errstate(all="ignore"):
            a_np = model.forward_dynamics(q, v, u)
        np.testing.assert_array_equal(np.isnan(a.T), np.isnan(a_np))
        ok = np.isfinite(a_np)
        np.testing.assert_allclose(a.T[ok], a_np[ok], rtol=0, atol=1e-12 * np.max(np.abs(a_np[ok])))
        res, lam = np.empty(4), np.empty((4, model.nc))
        module.constraint_info_kernel(q.T.copy(), v.T.copy(), tau.T.copy(), theta, res, lam)
        with np.errstate(all="ignore"):
            lam_np = model.multipliers(q, v, u)
        np.testing.assert_array_equal(np.isnan(lam), np.isnan(lam_np))
        ok = np.isfinite(lam_np)
        np.testing.assert_allclose(lam[ok], lam_np[ok], rtol=0, atol=1e-12 * np.max(np.abs(lam_np[ok])))


@pytest.mark.parametrize("case", [fourbar_case, disk_case], ids=["fourbar", "disk"])
def test_constrained_compiled_advance_equals_the_numpy_advance_with_projection(case):
    model, q, v, u = case(np.random.default_rng(8), 32)
    stepper, stab = integrators.get("rk4"), model.stabilization("projection")
    tab = compiled_stepping(model, stepper, stab)
    qc, vc = advance_compiled(model, tab, q, v, u, 0.01, 2, stab)
    qn, vn = advance(model, stepper, 0.0, q, v, 0.01, 2, u, stab, compiled=False)
    np.testing.assert_allclose(qc, qn, rtol=0, atol=1e-12)
    np.testing.assert_allclose(vc, vn, rtol=0, atol=1e-12 * np.max(np.abs(vn)))
    assert np.max(np.abs(model.constraint_residual(qc))) <= 1e-12
    qa, va = advance(model, stepper, 0.0, q, v, 0.01, 2, u, stab)  # routed to the kernels
    np.testing.assert_array_equal(qa, qc)


def step_both(fast, slow, action):
    """One step of each env from the same state; returns both results."""
    fast.unwrapped._q[:] = slow.unwrapped._q  # in place: the compiled step works on these arrays
    fast.unwrapped._v[:] = slow.unwrapped._v
    return fast.step(action), slow.step(action)


@pytest.mark.parametrize(
    "env_id, kwargs",
    [
        (ID, {}),
        (ID, {"params": {"b1": 0.5, "f2": 1.0}, "substeps": 3}),
        (ID, {"integrator": "euler"}),
        ("mbs_envs/FourBar-v0", {}),
        ("mbs_envs/FourBar-v0", {"params": {"b1": 0.2, "f3": 0.1}, "substeps": 2, "integrator": "midpoint"}),
        ("mbs_envs/RollingDisk-v0", {}),
        ("mbs_envs/RollingDisk-v0", {"params": {"b_roll": 0.01}, "substeps": 3, "lean_limit": 1.2}),
    ],
)
def test_compiled_env_steps_equal_the_numpy_path(env_id, kwargs):
    fast, slow = gym.make(env_id, **kwargs), gym.make(env_id, compiled=False, **kwargs)
    assert fast.unwrapped.compiled is not None and slow.unwrapped.compiled is None
    for seed in range(3):
        of, inf_f = fast.reset(seed=seed)
        os_, inf_s = slow.reset(seed=seed)
        np.testing.assert_array_equal(of, os_)
        rng = np.random.default_rng(seed)
        for _ in range(100):
            a = rng.uniform(-1.3, 1.3, fast.action_space.shape)  # includes saturated actions
            (of, rf, tf, trf, inf_f), (os_, rs, ts, trs, inf_s) = step_both(fast, slow, a)
            np.testing.assert_allclose(of, os_, rtol=0, atol=1e-12)
            assert rf == pytest.approx(rs, rel=1e-12, abs=1e-12)
            assert (tf, trf) == (ts, trs)
            assert set(inf_f) == set(inf_s)
            for k in inf_s:
                np.testing.assert_allclose(inf_f[k], inf_s[k], rtol=1e-12, atol=1e-12, err_msg=k)
                assert type(inf_f[k]) is type(inf_s[k]), k


def test_compiled_divergence_is_reported_like_the_numpy_path():
    kwargs = {"params": {"b1": 400.0, "b2": 400.0}}
    fast, slow = gym.make(ID, **kwargs), gym.make(ID, compiled=False, **kwargs)
    wild = {"q": [0.0, 0.0], "v": [1e6, -1e6]}  # RK4 blows up on the stiff friction
    fast.reset(seed=0, options=wild)
    slow.reset(seed=0, options=wild)
    (of, rf, tf, _, inf_f), (os_, rs, ts, _, inf_s) = step_both(fast, slow, np.zeros(2))
    assert inf_f["diverged"] and inf_s["diverged"] and tf and ts
    assert np.all(np.isfinite(of)) and np.isfinite(rf)
    np.testing.assert_array_equal(of, os_)  # both keep the last finite state
    np.testing.assert_array_equal(fast.unwrapped.q, wild["q"])


def test_fourbar_compiled_step_reports_an_opened_loop_like_the_numpy_path():
    """A residual limit below what a step leaves: both paths flag divergence and keep the state."""
    kwargs = {"residual_limit": 1e-8, "stabilization": "projection"}
    fast = gym.make("mbs_envs/FourBar-v0", **kwargs)
    slow = gym.make("mbs_envs/FourBar-v0", compiled=False, **kwargs)
    fast.reset(seed=1)
    slow.reset(seed=1)
    fast.unwrapped.stabilization = slow.unwrapped.stabilization = fast.unwrapped.model.stabilization(
        "projection", tol=1e-3
    )
    q_before = slow.unwrapped.q
    (of, rf, tf, _, inf_f), (os_, rs, ts, _, inf_s) = step_both(fast, slow, np.ones(1))
    assert inf_f["diverged"] and inf_s["diverged"] and tf and ts
    np.testing.assert_array_equal(fast.unwrapped.q, q_before)
    np.testing.assert_allclose(of, os_, rtol=0, atol=1e-12)


def test_disk_compiled_step_reports_the_flat_singularity_like_the_numpy_path():
    """A disk pushed to fall flat: both paths end the episode as diverged at the same step, state kept."""
    kwargs = {"lean_limit": RollingDisk.flat_lean - 1e-3}
    fast, slow = (
        gym.make("mbs_envs/RollingDisk-v0", **kwargs),
        gym.make("mbs_envs/RollingDisk-v0", compiled=False, **kwargs),
    )
    start = {"q": [0, 0, 0.3 * np.cos(1.4), 0, 1.4, 0], "v": [0, 0, 0, 0, 3.0, 0]}
    fast.reset(seed=0, options=start)
    slow.reset(seed=0, options=start)
    for k in range(200):
        (of, rf, tf, _, inf_f), (os_, rs, ts, _, inf_s) = step_both(fast, slow, np.zeros(2))
        assert (tf, inf_f["diverged"]) == (ts, inf_s["diverged"])
        np.testing.assert_allclose(of, os_, rtol=0, atol=1e-12)
        if ts:
            break
    assert inf_f["diverged"] and 0 < k < 199
    assert abs(fast.unwrapped.q[4]) <= RollingDisk.flat_lean


def test_compiled_vector_env_with_per_member_parameters_equals_the_numpy_vector_env():
    kw = {"num_envs": 5, "vectorization_mode": "vector_entry_point", "randomize": {"m2": 0.3, "l1": 0.2, "b2": 0.5}}
    fast = gym.make_vec(ID, params={"b2": 0.4}, **kw)
    slow = gym.make_vec(ID, params={"b2": 0.4}, compiled=False, **kw)
    np.testing.assert_array_equal(fast.reset(seed=2)[0], slow.reset(seed=2)[0])
    rng = np.random.default_rng(0)
    for _ in range(50):
        fast.unwrapped._q[:] = slow.unwrapped._q
        fast.unwrapped._v[:] = slow.unwrapped._v
        a = rng.uniform(-1, 1, (5, 2))
        of, rf, tf, trf, inf_f = fast.step(a)
        os_, rs, ts, trs, inf_s = slow.step(a)
        np.testing.assert_allclose(of, os_, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rf, rs, rtol=1e-12, atol=1e-12)
        for k in ("energy", "tracking_error", "q_ref", "reward_tracking", "u"):
            np.testing.assert_allclose(inf_f[k], inf_s[k], rtol=1e-12, atol=1e-12, err_msg=k)
        assert set(inf_f) == set(inf_s)


def test_action_validation_fast_path_keeps_its_guarantees():
    a = np.array([0.5, -3.0])
    np.testing.assert_array_equal(validate_action(a, 2), [0.5, -1.0])
    np.testing.assert_array_equal(a, [0.5, -3.0])  # the caller's array is not clipped in place
    np.testing.assert_array_equal(validate_action(np.float32([2.0, 0.25]), 2), [1.0, 0.25])
    for bad in (np.array([np.nan, 0.0]), np.array([0.0, -np.inf])):
        with pytest.raises(ValueError, match="finite"):
            validate_action(bad, 2)
    with pytest.raises(ValueError, match=r"members \[1\]"):
        validate_action(np.array([[0.0, 0.0], [np.inf, 0.0]]), 2, num_envs=2)


def test_kernels_are_stamped_with_the_whole_package_so_no_stale_binding_survives_an_edit():
    """numba alone re-checks only a function's own file; a scene's step kernel embeds its model's
    kernels, so the package's kernels are stamped with a hash of all its sources (mbs_envs.dynamics.jit)."""
    from mbs_envs.envs import planar2r
    from mbs_envs.dynamics.jit import package_stamp

    locator = planar2r.step_kernel._cache._impl.locator
    assert type(locator).__name__.startswith("MbsEnvs")
    assert locator.get_source_stamp() == package_stamp() and len(package_stamp()) == 40
    import numba

    @numba.njit(cache=True)
    def outside(x):  # pragma: no cover - compiled; a function outside the package keeps numba's locators
        return x

    assert not type(outside._cache._impl.locator).__name__.startswith("MbsEnvs")


COLD = """
import gymnasium as gym
import mbs_envs
from mbs_envs.dynamics import constraints
from mbs_envs.models import fourbar, rolling_disk
for env_id in ("mbs_envs/FourBar-v0", "mbs_envs/RollingDisk-v0"):
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    envs = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    envs.reset(seed=0)
    envs.step(envs.action_space.sample())
kernels = [constraints._schur_kernel, constraints.schur_member]
kernels += [getattr(m, "general_" + k) for m in (fourbar, rolling_disk) for k in ("acceleration", "projection", "constraint_info")]
print(sum(len(k.signatures) for k in kernels))
"""


@pytest.mark.slow
def test_a_constrained_scenes_first_steps_compile_no_general_member_path(tmp_path):
    """With numba's cache empty (what a fresh install pays once), making, resetting and stepping the
    constrained scenes compiles none of the general member path (Cholesky, LAPACK, pseudo-inverse):
    the closed-form kernels call it from object mode, compiled only where a member needs it (issue 18's
    cold start; about 20 s of the first step). About 30 s."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", COLD], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split()[0] == "0", out.stdout


def test_chain_kernels_take_whole_tiles_by_simd_with_the_member_paths_bits():
    """SerialChain's acceleration and energy kernels run whole tiles of members with the member loop
    innermost (SIMD) and the rest one member at a time: every member's result has the same bits as
    the member path alone (a batch of one), with per-member parameters (the kernels' columns),
    Coulomb friction in some members only, an angle beyond the SIMD sincos's range, a NaN and
    signed zeros; and equals the numpy model to 1e-12."""
    from mbs_envs.models import SerialChain
    from mbs_envs.models import serial_recursions as sc

    rng = np.random.default_rng(12)
    N, B = 7, 2 * sc.TILE + 5
    model = SerialChain(n_links=N, b=0.1)
    q, v, tau = rng.uniform(-3, 3, (N, B)), rng.uniform(-4, 4, (N, B)), rng.uniform(-5, 5, (N, B))
    q[0, 3] = 1e7  # beyond SINCOS_RANGE: libm for that member
    q[2, sc.TILE + 1] = np.nan
    v[:, 7], tau[:, 7] = -0.0, -0.0
    shared = batch_theta(model, B)  # one column for every member
    assert shared.shape == (7 * N + 2, 1)
    a, E = np.empty((N, B)), np.empty(B)
    sc.acceleration_kernel(q, v, tau, shared, a)
    sc.energy_kernel(q, v, shared, E)
    a_np = model.forward_dynamics(q.T, v.T, tau.T)
    ok = np.all(np.isfinite(a_np), axis=-1)
    assert np.max(np.abs(a.T[ok] - a_np[ok]) / (1 + np.abs(a_np[ok]))) < 1e-12
    theta = np.repeat(shared, B, axis=1)  # the same, one column per member: the same bits
    a_cols, E_cols = np.empty((N, B)), np.empty(B)
    sc.acceleration_kernel(q, v, tau, theta, a_cols)
    sc.energy_kernel(q, v, theta, E_cols)
    assert a_cols.tobytes() == a.tobytes() and E_cols.tobytes() == E.tobytes()
    coulomb = batch_theta(SerialChain(n_links=N, b=0.1, f=0.2), B)  # the shared column through the tanh path
    sc.acceleration_kernel(q, v, tau, coulomb, a)
    sc.acceleration_kernel(q, v, tau, np.repeat(coulomb, B, axis=1), a_cols)
    assert a_cols.tobytes() == a.tobytes()
    theta[2 * N : 3 * N] = rng.uniform(0.1, 2.0, (N, B))  # m
    theta[4 * N : 5 * N] = rng.uniform(0.0, 0.1, (N, B))  # armature
    theta[5 * N : 6 * N] = rng.uniform(0.0, 0.3, (N, B))  # b
    for friction in ("viscous only", "some Coulomb"):
        if friction == "some Coulomb":
            theta[6 * N : 7 * N] = np.where(rng.random(B) < 0.3, rng.uniform(0, 0.5, (N, B)), 0.0)
        sc.acceleration_kernel(q, v, tau, theta, a)
        sc.energy_kernel(q, v, theta, E)
        for k in range(B):
            a1, E1 = np.empty((N, 1)), np.empty(1)
            th = np.ascontiguousarray(theta[:, k : k + 1])
            sc.acceleration_kernel(q[:, k : k + 1].copy(), v[:, k : k + 1].copy(), tau[:, k : k + 1].copy(), th, a1)
            sc.energy_kernel(q[:, k : k + 1].copy(), v[:, k : k + 1].copy(), th, E1)
            assert (
                np.array_equal(a[:, k].view(np.int64), a1[:, 0].view(np.int64))
                or np.isnan(a[:, k]).all()
                and np.isnan(a1).all()
            ), (friction, k)
            assert E[k].tobytes() == E1[0].tobytes() or np.isnan(E[k]) and np.isnan(E1[0]), (friction, k)


def test_aligned_copies_and_work_arrays_start_on_a_64_byte_boundary():
    """``compiled.aligned`` (numpy) and ``aligned_empty`` (compiled) give arrays on a cache-line
    boundary, of the requested size, the copy equal to its input (any layout and dtype)."""
    from numba import njit

    from mbs_envs.dynamics.compiled import ALIGN, aligned, aligned_empty

    @njit
    def address_and_size(n):
        x = aligned_empty(n)
        x[:] = 1.0
        return x.ctypes.data % ALIGN, x.size

    for n in (0, 1, 7, 8, 9, 1000):
        assert address_and_size(n) == (0, n)
    rng = np.random.default_rng(0)
    for x in (rng.normal(size=(3, 5)).T, np.arange(12, dtype=np.int32).reshape(3, 4)[:, ::2], np.zeros((0, 4)),
              rng.normal(size=(2, 3, 4)).astype(">f8")):  # fmt: skip
        y = aligned(x)
        assert (y.ctypes.data % ALIGN == 0 or y.size == 0) and y.flags.c_contiguous and y.dtype == np.float64
        np.testing.assert_array_equal(y, x)


def test_chain_acceleration_kernel_writes_any_output_layout():
    """The chain's acceleration kernel fills its output whatever its layout: contiguous, strided, and
    typed non-contiguous by numba while contiguous at run time (a slice in compiled code, which
    numba's ``ravel`` copies); every element is written (the output starts as a sentinel)."""
    from numba import njit

    from mbs_envs.models import SerialChain
    from mbs_envs.models import serial_recursions as sc

    N, B = 5, 2 * sc.TILE + 6
    theta = batch_theta(SerialChain(n_links=N), B)
    rng = np.random.default_rng(7)
    q, v, tau = rng.normal(size=(N, B)), rng.normal(size=(N, B)), rng.normal(size=(N, B))
    ref = np.empty((N, B))
    sc.acceleration_kernel(q, v, tau, theta, ref)

    @njit
    def through_a_slice(q, v, tau, theta, out):
        sc.acceleration_kernel(q, v, tau, theta, out[:, 0 : q.shape[1]])

    strided = np.full((N, 2 * B), 7.0)
    sc.acceleration_kernel(q, v, tau, theta, strided[:, ::2])
    sliced = np.full((N, B), 7.0)
    through_a_slice(q, v, tau, theta, sliced)
    np.testing.assert_array_equal(strided[:, ::2], ref)
    np.testing.assert_array_equal(strided[:, 1::2], 7.0)
    np.testing.assert_array_equal(sliced, ref)


@pytest.mark.parametrize("setting, value", [("dt", 0.02), ("substeps", 3), ("u_max", np.array([2.0, 1.0]))])
def test_a_setting_changed_after_steps_reaches_the_compiled_step(setting, value):
    """The step kernel's packed arguments are kept between steps (``StepDispatch.arguments``) and
    rebuilt when a setting changes: a changed ``dt``, ``substeps`` or ``u_max`` steps as an env
    built with it does (the cached arguments would step with the old one)."""
    changed = gym.make("mbs_envs/Planar2R-v0").unwrapped
    fresh = gym.make("mbs_envs/Planar2R-v0").unwrapped
    setattr(fresh, setting, value)
    a = np.array([0.7, -0.4])
    changed.reset(seed=4)
    changed.step(a)
    q, v, t = changed.q, changed.v, changed._t
    setattr(changed, setting, value)
    fresh.reset(seed=4, options={"q": q, "v": v})
    fresh._t, fresh._task = t, changed._task
    o1, r1, *_ = changed.step(a)
    o2, r2, *_ = fresh.step(a)
    assert changed.compiled is not None
    np.testing.assert_array_equal(o1, o2)
    assert r1 == r2


def test_a_member_loop_over_many_rows_vectorizes():
    """The disk's and four-bar's closed-form kernels loop over the members reading a dozen rows of four arrays
    and writing six rows and a flag: more runtime overlap checks than LLVM's default 128, so that such a loop
    ran scalar until ``mbs_envs.dynamics.jit`` raised the limit. The same shape of loop, compiled uncached
    (inspectable), must contain vector arithmetic."""
    import re

    from mbs_envs.dynamics.jit import njit

    @njit(cache=False)
    def loop(T, v, tau, theta, a, ok):  # pragma: no cover - compiled
        for b in range(v.shape[1]):
            s = theta[0, b] * T[0, b] + theta[1, b] * T[1, b]
            d = theta[2, b] * T[2, b] - theta[3, b] * T[3, b] + theta[4, b]
            x = (v[0, b] * s + v[1, b] * d + tau[0, b]) / d
            y = (v[2, b] * d - v[3, b] * s + tau[1, b]) / s
            z = (v[4, b] * s * d + v[5, b] + tau[2, b] * tau[3, b]) / (s + d)
            a[0, b], a[1, b], a[2, b] = x + tau[4, b], y + tau[5, b], z
            a[3, b], a[4, b], a[5, b] = x * y, y * z, z * x
            ok[b] = (d > 0.0) & (s > 0.0) & np.isfinite(x + y + z)

    B = 64
    rng = np.random.default_rng(0)
    T, v, tau, theta = rng.random((4, B)), rng.random((6, B)), rng.random((6, B)), rng.random((5, B))
    a, ok = np.empty((6, B)), np.empty(B, np.bool_)
    loop(T, v, tau, theta, a, ok)
    ir = loop.inspect_llvm(loop.signatures[0])
    assert re.search(r"fdiv[^\n]*<\d+ x double>", ir), "the member loop compiled to scalar code"


def test_direct_calls_the_overload_of_the_arguments_types_and_compiles_a_new_one():
    from mbs_envs.dynamics.jit import direct, njit

    @njit(cache=False)
    def axpy(a, x, y):
        for i in range(len(x)):
            y[i] += a * x[i]

    x, y = np.arange(4.0), np.ones(4)
    f = direct(axpy, (2.0, x, y))
    assert len(axpy.overloads) == 1 and f is direct(axpy, (3.0, x, np.zeros(4)))  # the same types: the same overload
    f(2.0, x, y)
    np.testing.assert_array_equal(y, 1 + 2 * x)
    g = direct(axpy, (2.0, x.astype(np.float32), y))  # another type: its own overload, compiled
    assert g is not f and len(axpy.overloads) == 2
    y32 = y.copy()
    g(2.0, x.astype(np.float32), y32)
    np.testing.assert_array_equal(y32, 1 + 4 * x)


def test_a_single_envs_direct_step_follows_its_settings_model_and_task_and_survives_copies():
    """The single env's step calls its kernel's overload directly (mbs_envs.dynamics.jit.direct), looked up again when an
    argument object changes: the episode after a setting, a parameter or the task changed, or after a pickle or a deep
    copy, is bit for bit a fresh env's with that setting, parameter or task; a vector env of one member (the same
    path) steps as the single env."""
    import copy
    import pickle

    def run(env, steps, seed=0):
        rng = np.random.default_rng(seed)
        out = []
        for _ in range(steps):
            obs, r, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
            out.append(np.r_[obs, r])
        return np.array(out)

    env = gym.make("mbs_envs/SerialChain-v0", n_links=3).unwrapped
    env.reset(seed=1)
    run(env, 5)
    first = env.dispatch._direct
    env.substeps = 2  # a setting: new stepper arguments
    fresh = gym.make("mbs_envs/SerialChain-v0", n_links=3).unwrapped
    fresh.substeps = 2
    fresh.reset(seed=1)
    run(fresh, 5)
    fresh._q[:], fresh._v[:], fresh._t = env._q, env._v, env._t
    np.testing.assert_array_equal(run(env, 20, seed=2), run(fresh, 20, seed=2))
    assert env.dispatch._direct is not first
    env.reset(seed=4)  # a new episode's task
    fresh.reset(seed=4)
    np.testing.assert_array_equal(run(env, 20), run(fresh, 20))
    before = env.dispatch._direct
    env.model.params = env.model.params.replace(m=np.array([0.5, 0.3, 0.2]))  # a parameter: new kernel parameters
    heavy = gym.make("mbs_envs/SerialChain-v0", n_links=3).unwrapped  # the same drives; its first step after the change
    heavy.substeps = 2
    heavy.reset(seed=4)
    heavy.model.params = env.model.params
    heavy._q[:], heavy._v[:], heavy._t, heavy._task = env._q, env._v, env._t, env._task
    np.testing.assert_array_equal(run(env, 20, seed=3), run(heavy, 20, seed=3))
    assert env.dispatch._direct is not before
    twin = pickle.loads(pickle.dumps(env))
    deep = copy.deepcopy(env)
    assert "_dispatch" not in twin.__dict__ and "_dispatch" not in deep.__dict__
    a, b, c = run(env, 30), run(twin, 30), run(deep, 30)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)
    single = gym.make("mbs_envs/SerialChain-v0", n_links=3).unwrapped
    one = gym.make_vec("mbs_envs/SerialChain-v0", num_envs=1, vectorization_mode="vector_entry_point", n_links=3)
    single.reset(seed=6)
    one.reset(seed=[6])
    rng = np.random.default_rng(7)
    for _ in range(50):
        act = rng.uniform(-1, 1, (1, 3)).astype(np.float32)
        o1, r1, *_ = single.step(act[0])
        o2, r2, *_ = one.step(act)
        np.testing.assert_array_equal(o1, o2[0])
        assert r1 == r2[0]
