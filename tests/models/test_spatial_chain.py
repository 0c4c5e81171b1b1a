"""SpatialChain (issue 35) against independent references.

- Pinocchio (``pin``): CRBA, RNEA, ABA, kinetic and potential energy on random chains (random unit
  axes, offsets, centres of mass, full inertia tensors, armature) for N = 1, 2, 7, 50, 500, to 1e-11
  relative; skipped with the reason when ``pin`` is not installed.
- The planar special case: all axes along z, offsets and centres along x, gravity along -y is the
  planar :class:`SerialChain` (prefix-sum algorithms, shared with no kernel here) to 1e-12.
- A SymPy Lagrangian (``T`` and ``V`` from rotation matrices, Lagrange's equations by
  differentiation) for N = 2 and 3 at random states, to 1e-12.
- ABA against the CRBA path (Cholesky of ``M``); batched against member-by-member; energy
  conservation of free motion at RK4's order.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from mbs_envs.dynamics.simulate import simulate
from mbs_envs.models.serial_chain import SerialChain
from mbs_envs.models.spatial_chain import SpatialChain
from mbs_envs.studies.benchmarking import pinocchio_spatial_chain


def random_chain(n: int, rng: np.random.Generator, armature: bool = True) -> SpatialChain:
    """A chain with everything random: axes, offsets, centres, masses, full inertia tensors, armature, gravity."""
    A = rng.normal(size=(n, 3, 3))
    inertia = np.einsum("nij,nkj->nik", A, A) * 0.05 + 0.01 * np.eye(3)  # symmetric positive definite, full
    return SpatialChain(n_links=n, m=rng.uniform(0.2, 2.0, n), l=rng.uniform(0.2, 1.0, n), axis=rng.normal(size=(n, 3)),
                        offset=rng.normal(size=(n, 3)) * 0.5, com=rng.normal(size=(n, 3)) * 0.2, inertia=inertia,
                        g_vec=rng.normal(size=3) * 5, armature=rng.uniform(0, 0.1, n) if armature else 0.0)  # fmt: skip


def rel(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(x) - np.asarray(y))) / max(1.0, float(np.max(np.abs(y)))))


# -- Pinocchio ------------------------------------------------------------------------------------


def pinocchio_model(chain: SpatialChain):
    pytest.importorskip("pinocchio", reason="Pinocchio (pip package 'pin', the bench extra) is not installed")
    return pinocchio_spatial_chain(chain)


@pytest.mark.parametrize(
    "n", [1, 2, 7, pytest.param(50, marks=pytest.mark.slow), pytest.param(500, marks=pytest.mark.slow)]
)  # 50, 500: the slow set (scripts/bench_chain.py checks N = 500 on every run)
@pytest.mark.parametrize("axes", ["random", "coordinate"])
def test_agrees_with_pinocchio(n, axes):
    """Random chains, with random joint axes (the full rotation) or coordinate axes of either sign (the frames'
    two-column turn, ``_coordinate_axis``)."""
    rng = np.random.default_rng(n)
    chain = random_chain(n, rng)
    if axes == "coordinate":
        axis = np.zeros((n, 3))
        axis[np.arange(n), rng.integers(0, 3, n)] = rng.choice([-1.0, 1.0], n)
        chain = SpatialChain(params=chain.params.replace(axis=axis))
    pin, model, data = pinocchio_model(chain)
    for _ in range(3):
        q, v, a = rng.normal(size=(3, n)) * 2
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert rel(chain.mass_matrix(q), M) < 1e-11
        assert rel(chain.rnea(q, v, a), pin.rnea(model, data, q, v, a)) < 1e-11
        assert rel(chain.aba(q, v, a), pin.aba(model, data, q, v, a)) < 1e-11
        # Pinocchio's kinetic energy leaves the armature out
        T_arm = 0.5 * np.sum(chain.params.armature * v**2)
        assert abs(chain.kinetic_energy(q, v) - T_arm - pin.computeKineticEnergy(model, data, q, v)) < 1e-11 * max(
            1.0, abs(float(chain.kinetic_energy(q, v)))
        )
        V = pin.computePotentialEnergy(model, data, q)
        assert abs(chain.potential_energy(q) - V) < 1e-11 * max(1.0, abs(V))


# -- the planar special case ------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 5, 30])
def test_parallel_z_axes_reproduce_the_planar_chain(n):
    rng = np.random.default_rng(100 + n)
    m, l = rng.uniform(0.5, 2, n), rng.uniform(0.3, 1, n)
    r, I = l * rng.uniform(0.2, 0.8, n), m * l**2 / 12 * rng.uniform(0.5, 2, n)  # noqa: E741
    arm, b = rng.uniform(0, 0.1, n), rng.uniform(0, 0.3, n)
    planar = SerialChain(n_links=n, m=m, l=l, r=r, I=I, armature=arm, b=b, g=9.81)
    inertia = np.zeros((n, 3, 3))
    inertia[:, 0, 0], inertia[:, 1, 1], inertia[:, 2, 2] = 0.3, 0.2, I  # only I_zz acts in the plane
    offset = np.zeros((n, 3))
    offset[1:, 0] = l[:-1]
    spatial = SpatialChain(n_links=n, m=m, l=l, axis=np.tile([0.0, 0.0, 1.0], (n, 1)), offset=offset,
                           com=np.stack([r, 0 * r, 0 * r], 1), inertia=inertia, g_vec=(0.0, -9.81, 0.0), armature=arm, b=b)  # fmt: skip
    q, v, u = rng.normal(size=(3, 11, n))
    assert rel(spatial.mass_matrix(q), planar.mass_matrix(q)) < 1e-12
    assert rel(spatial.bias(q, v), planar.bias(q, v)) < 1e-12
    assert rel(spatial.inverse_dynamics(q, v, u), planar.inverse_dynamics(q, v, u)) < 1e-12
    assert rel(spatial.forward_dynamics(q, v, u), planar.forward_dynamics(q, v, u)) < 1e-12
    assert rel(spatial.energy(q, v), planar.energy(q, v)) < 1e-12
    assert rel(spatial.joint_positions(q)[..., :2], planar.joint_positions(q)) < 1e-12


# -- SymPy -----------------------------------------------------------------------------------------


def sympy_equations(chain: SpatialChain):
    """``(M, Cv, G)`` as functions of ``(q, dq)`` from T and V built with rotation matrices (no spatial algebra)."""
    p = chain.params
    n = chain.n_links
    q = list(sp.symbols(f"q1:{n + 1}"))
    dq = list(sp.symbols(f"dq1:{n + 1}"))
    R = sp.eye(3)
    pos = sp.zeros(3, 1)
    T, V = 0, 0
    for i in range(n):
        a = sp.Matrix(p.axis[i])
        ax = sp.Matrix([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        rot = sp.eye(3) + sp.sin(q[i]) * ax + (1 - sp.cos(q[i])) * ax * ax  # Rodrigues
        pos = pos + R * sp.Matrix(p.offset[i])
        R = R * rot
        c = pos + R * sp.Matrix(p.com[i])
        vc = c.jacobian(q) * sp.Matrix(dq)
        Rdot = sum((sp.diff(R, q[j]) * dq[j] for j in range(n)), sp.zeros(3, 3))
        W = R.T * Rdot  # body angular velocity, skew
        w = sp.Matrix([W[2, 1], W[0, 2], W[1, 0]])
        T += sp.Rational(1, 2) * p.m[i] * (vc.T * vc)[0] + sp.Rational(1, 2) * (w.T * sp.Matrix(p.inertia[i]) * w)[0]
        T += sp.Rational(1, 2) * p.armature[i] * dq[i] ** 2
        V += -p.m[i] * (sp.Matrix(p.g_vec).T * c)[0]
    ddq = list(sp.symbols(f"ddq1:{n + 1}"))
    L = T - V
    eqs = []  # Lagrange's equations, d/dt dL/d(dq_i) - dL/dq_i, by the chain rule (unexpanded: lambdify's cse keeps them small)
    for i in range(n):
        P = sp.diff(L, dq[i])
        eqs.append(sum(sp.diff(P, q[j]) * dq[j] + sp.diff(P, dq[j]) * ddq[j] for j in range(n)) - sp.diff(L, q[i]))
    M = sp.Matrix(n, n, lambda i, j: sp.diff(eqs[i], ddq[j]))
    G = sp.Matrix([sp.diff(V, qi) for qi in q])
    Cv = sp.Matrix([e.subs({x: 0 for x in ddq}) for e in eqs]) - G
    return [sp.lambdify([q, dq], X, "numpy", cse=True) for X in (M, Cv, G)]


@pytest.mark.parametrize("n", [2, pytest.param(3, marks=pytest.mark.slow)])  # N = 3: ~2 min of SymPy
def test_agrees_with_a_sympy_lagrangian(n):
    rng = np.random.default_rng(200 + n)
    chain = random_chain(n, rng)
    M_f, Cv_f, G_f = sympy_equations(chain)
    for _ in range(5):
        q, v = rng.normal(size=(2, n)) * 2
        assert rel(chain.mass_matrix(q), np.array(M_f(q, v), float)) < 1e-12
        assert rel(chain.coriolis(q, v), np.array(Cv_f(q, v), float).ravel()) < 1e-12
        assert rel(chain.gravity(q), np.array(G_f(q, v), float).ravel()) < 1e-12


# -- algorithms against each other; batches; energy --------------------------------------------------


@pytest.mark.parametrize("n", [1, 3, 20])
def test_aba_equals_the_mass_matrix_path_and_rnea_inverts_it(n):
    rng = np.random.default_rng(300 + n)
    chain = random_chain(n, rng)
    q, v, u = rng.normal(size=(3, 4, n))
    a = chain.forward_dynamics(q, v, u)
    assert rel(a, chain.forward_dynamics_crba(q, v, u)) < 1e-10  # a Cholesky solve of M: its condition number
    assert rel(chain.inverse_dynamics(q, v, a), u) < 1e-10


def test_batched_equals_member_by_member():
    rng = np.random.default_rng(4)
    chain = random_chain(6, rng)
    q, v, a = rng.normal(size=(3, 2, 5, 6))
    batch = chain.rnea(q, v, a), chain.mass_matrix(q), chain.aba(q, v, a), chain.energy(q, v)
    for i in range(2):
        for j in range(5):
            one = (
                chain.rnea(q[i, j], v[i, j], a[i, j]),
                chain.mass_matrix(q[i, j]),
                chain.aba(q[i, j], v[i, j], a[i, j]),
                chain.energy(q[i, j], v[i, j]),
            )
            for x, y in zip(batch, one):
                np.testing.assert_array_equal(x[i, j], y)


def test_compiled_path_equals_the_numpy_path_and_the_shifted_solve_is_M_plus_diag_d():
    """The env's compiled step (columns, one parameter column, damping inside the kernel) against the numpy
    path (ABA rows, damping by ``friction``): the same kernels in the same order, so equal bits; the shifted
    solve of the joint-implicit step against a dense solve of ``(M + diag d) a = tau - C v - G``."""
    from mbs_envs.dynamics.integrators import get
    from mbs_envs.dynamics.simulate import advance

    rng = np.random.default_rng(8)
    chain = random_chain(5, rng).with_params(random_chain(5, rng).params.replace(b=rng.uniform(0, 0.5, 5)))
    q, v, u = rng.normal(size=(3, 4, 5))
    fast = advance(chain, get("rk4"), 0.0, q, v, 0.02, 2, u=u, compiled=True)
    slow = advance(chain, get("rk4"), 0.0, q, v, 0.02, 2, u=u, compiled=False)
    np.testing.assert_array_equal(fast[0], slow[0])
    np.testing.assert_array_equal(fast[1], slow[1])
    np.testing.assert_allclose(
        chain.energy(q, v), chain.kinetic_energy(q, v) + chain.potential_energy(q), rtol=1e-14, atol=1e-14
    )
    d = rng.uniform(0, 1, (4, 5))
    M = chain.mass_matrix(q) + np.einsum("bi,ij->bij", d, np.eye(5))
    rhs = u - chain.rnea(q, v, np.zeros_like(v))
    assert rel(chain.shifted_forward_dynamics(q, v, u, d), np.linalg.solve(M, rhs[..., None])[..., 0]) < 1e-12


def test_free_motion_conserves_energy_at_rk4s_order():
    chain = random_chain(4, np.random.default_rng(5), armature=True)
    q0, v0 = np.full(4, 0.3), np.full(4, 0.5)
    E0 = chain.energy(q0, v0)
    drift = []
    for dt in (4e-3, 2e-3):
        tr = simulate(chain, q0, v0, 1.0, dt, "rk4")
        assert not tr.diverged
        drift.append(float(np.max(np.abs(chain.energy(tr.q, tr.v) - E0))))
    order = np.log2(drift[0] / drift[1])
    assert 3.5 < order < 4.6, (drift, order)  # RK4's global error: fourth order


@pytest.mark.parametrize("kwargs, match", [
    ({"axis": [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]}, "axis"),
    ({"inertia": [[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}, "symmetric"),
    ({"inertia": -np.eye(3)}, "semidefinite"),
    ({"m": -1.0}, "m"),
    ({"g_vec": [0.0, 9.81]}, "g_vec"),
    ({"com": [[0.0, 0.0, 0.0]] * 2, "inertia": np.zeros((3, 3))}, "inertia about its joint"),
    ({"n_links": 0}, "n_links"),
    ({"axis": "z"}, "axis"),
])  # fmt: skip
def test_bad_parameters_are_refused_by_name(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SpatialChain(**{"n_links": 2, **kwargs})


@pytest.mark.slow
def test_aba_and_rnea_scale_linearly():
    """O(N): t(500) / t(50) <= 12 for ABA and RNEA, single call and per member of a batch (medians; slow set,
    since timings on a loaded machine are noisy -- scripts/bench_chain.py gives the figures)."""
    from mbs_envs.studies.benchmarking import median_time

    rng = np.random.default_rng(0)
    times = {}
    for n in (50, 500):
        chain = SpatialChain(n_links=n)
        q, v, a = rng.normal(size=(3, n))
        Q, V, A = rng.normal(size=(3, 64, n))
        times[n] = [median_time(lambda: chain.aba(q, v, a), repeats=9), median_time(lambda: chain.rnea(q, v, a), repeats=9),
                    median_time(lambda: chain.aba(Q, V, A), repeats=5), median_time(lambda: chain.rnea(Q, V, A), repeats=5)]  # fmt: skip
    ratios = np.array(times[500]) / np.array(times[50])
    assert np.all(ratios <= 12), ratios


@pytest.mark.parametrize(
    "n, full", [(1, False), (2, False), (7, False), (10, False), (50, False), (2, True), (7, True)]
)
def test_tiled_aba_gives_each_member_the_bits_of_the_member_by_member_aba(n, full):
    """The vector env's kernel with shared parameters runs members in SIMD tiles (``aba_tiles``); each member's
    result is the member-by-member ``aba_into``'s bit for bit, for batches that fill tiles and leave a remainder, at states
    beyond the fast sine's range (its libm fallback) and with damping; with the default chain (joints about z and y,
    turning two columns of the frame; the rods' diagonal inertia tensors, a scaling) and with ``full`` ones (random
    axes and inertia tensors, the first link's axis -x and inertia diagonal, the last's axis -y)."""
    from mbs_envs.dynamics.compiled import batch_theta
    from mbs_envs.models.spatial_chain import TILE, acceleration_kernel, tiled_acceleration_kernel

    rng = np.random.default_rng(n)
    params = {"b": 0.3}
    if full:
        L = rng.normal(size=(n, 3, 3)) * 0.1
        params["inertia"] = L @ np.swapaxes(L, 1, 2) + 0.01 * np.eye(3)
        params["inertia"][0] = np.diag([0.01, 0.02, 0.03])
        params["axis"] = rng.normal(size=(n, 3))
        params["axis"][0], params["axis"][-1] = (-2.0, 0.0, 0.0), (0.0, -1.0, 0.0)
    chain = SpatialChain(n_links=n, params=params)
    theta = batch_theta(chain, 1)
    for B in (2, TILE, 2 * TILE + 5):
        q = rng.uniform(-4, 4, (n, B))
        q[0, 0] = 3e5  # beyond the SIMD sincos's range
        v, tau = rng.uniform(-3, 3, (n, B)), rng.uniform(-9, 9, (n, B))
        a = np.empty((n, B))
        tiled_acceleration_kernel(q, v, tau, theta, a)
        for k in range(B):
            one = np.empty((n, 1))
            acceleration_kernel(*(np.ascontiguousarray(x[:, k : k + 1]) for x in (q, v, tau)), theta, one)
            assert np.array_equal(a[:, k], one[:, 0]), (B, k)
        np.testing.assert_allclose(a, chain.forward_dynamics(q.T, v.T, tau.T).T, rtol=1e-9, atol=1e-9)


def test_member_kernels_keep_no_reference_counts_and_the_step_kernels_allocate_once_per_call():
    """The member kernels are compiled without numba's runtime (``_nrt=False``): they allocate nothing and count no
    references (the counts of their array views and arguments were half of a 10-link member's time,
    docs/performance.md), so a change that allocates in them fails to compile rather than slowing down. The
    acceleration and energy kernels allocate one buffer per call, for one member or several with their own
    parameters, and give the same bits whatever their buffer held before (nothing read before it is written)."""
    from numba import njit
    from numba.core.runtime import _nrt_python as nrt

    from mbs_envs.dynamics.compiled import batch_theta
    from mbs_envs.models import spatial_chain as sc
    from mbs_envs.models import spatial_recursions as sr

    for f in (sr.frames_into, sr.aba_into, sr.rnea_into, sr.crba_into, sr.energy_member, sc._acceleration_members,
              sc._energy_members):  # fmt: skip
        assert f.targetoptions.get("_nrt") is False, f.__name__

    @njit
    def repeat(k, q, v, tau, theta, a, E):  # the kernels called k times inside compiled code (no unboxing per call)
        for _ in range(k):
            sc.acceleration_kernel(q, v, tau, theta, a)
            sc.energy_kernel(q, v, theta, E)

    def allocations(k, *args):
        before = nrt.memsys_get_stats_alloc(), nrt.memsys_get_stats_free()
        repeat(k, *args)
        return nrt.memsys_get_stats_alloc() - before[0], nrt.memsys_get_stats_free() - before[1]

    rng = np.random.default_rng(3)
    model = random_chain(4, rng)
    for B, theta in (
        (1, batch_theta(model, 1)),
        (5, np.repeat(batch_theta(model, 1), 5, axis=1) * rng.uniform(0.9, 1.1, (1, 5))),
    ):
        q, v, tau = rng.normal(size=(3, 4, B))
        a, E = np.empty((4, B)), np.empty(B)
        repeat(1, q, v, tau, theta, a, E)  # compiled before counting
        a0, E0 = a.copy(), E.copy()
        was = nrt.memsys_stats_enabled()
        nrt.memsys_enable_stats()
        try:
            once, four = allocations(1, q, v, tau, theta, a, E), allocations(4, q, v, tau, theta, a, E)
        finally:
            if not was:
                nrt.memsys_disable_stats()
        assert (four[0] - once[0], four[1] - once[1]) == (6, 6), (
            B,
            once,
            four,
        )  # three more calls of each: one buffer each
        assert a.tobytes() == a0.tobytes() and E.tobytes() == E0.tobytes()
        for fill in (np.nan, -1e300, 0.0):  # the member loops on buffers holding anything: the same bits
            sc._acceleration_members(q, v, tau, theta, np.full(sc._member_size(4, 4), fill), a)
            sc._energy_members(q, v, theta, np.full(sc._member_size(4, 2), fill), E)
            assert a.tobytes() == a0.tobytes() and E.tobytes() == E0.tobytes(), fill
