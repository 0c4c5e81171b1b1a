"""Models derived from a Lagrangian (issue 36, item 1-2 for unconstrained mechanisms): the 2R arm re-derived
through ``mbs_envs.models.symbolic`` against the hand-written ``Planar2R``; the compiled path against the numpy
one; the disk cache; refusals by name."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from mbs_envs.dynamics.integrators import get
from mbs_envs.dynamics.simulate import advance, simulate
from mbs_envs.models import Planar2R
from mbs_envs.models import symbolic

t = dynamicsymbols._t
NAMES = ("m1", "m2", "l1", "l2", "r1", "r2", "I1", "I2", "g", "b1", "b2")


def arm_lagrangian():
    """The 2R arm of docs/physics.md §3 written as a student would: centres of mass, then T and V."""
    q1, q2 = dynamicsymbols("q1 q2")
    m1, m2, l1, l2, r1, r2, I1, I2, g = sp.symbols("m1 m2 l1 l2 r1 r2 I1 I2 g")
    x1, y1 = r1 * sp.cos(q1), r1 * sp.sin(q1)
    x2, y2 = l1 * sp.cos(q1) + r2 * sp.cos(q1 + q2), l1 * sp.sin(q1) + r2 * sp.sin(q1 + q2)
    d = lambda e: e.diff(t)  # noqa: E731
    T = (
        m1 * (d(x1) ** 2 + d(y1) ** 2) + I1 * d(q1) ** 2 + m2 * (d(x2) ** 2 + d(y2) ** 2) + I2 * (d(q1) + d(q2)) ** 2
    ) / 2
    V = g * (m1 * y1 + m2 * y2)
    return (q1, q2), T, V


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    (q1, q2), T, V = arm_lagrangian()
    hand = Planar2R(m1=1.3, m2=0.7, l1=0.9, l2=1.1, r1=0.4, r2=0.6, I1=0.08, I2=0.05, b1=0.2, b2=0.1)
    params = {k: getattr(hand.params, k) for k in NAMES}
    d = symbolic.cached_derivation(
        "Arm2R", (q1, q2), T, V, params, damping={q1: "b1", q2: "b2"}, cache=tmp_path_factory.mktemp("derived")
    )
    return symbolic.model_class(d)(), hand


def rel(x, y):
    return float(np.max(np.abs(np.asarray(x) - np.asarray(y))) / max(1.0, float(np.max(np.abs(y)))))


def test_the_derived_arm_is_the_hand_written_one(pair):
    derived, hand = pair
    rng = np.random.default_rng(0)
    q, v, u = rng.normal(size=(3, 200, 2)) * np.array([3.0, 5.0, 10.0])[:, None, None]
    for name in ("mass_matrix", "gravity", "potential_energy"):
        assert rel(getattr(derived, name)(q), getattr(hand, name)(q)) < 1e-12, name
    for name in ("coriolis", "bias", "kinetic_energy", "energy", "friction"):
        args = (v,) if name == "friction" else (q, v)
        assert rel(getattr(derived, name)(*args), getattr(hand, name)(*args)) < 1e-12, name
    assert rel(derived.forward_dynamics(q, v, u), hand.forward_dynamics(q, v, u)) < 1e-12
    a = hand.forward_dynamics(q, v, u)
    assert rel(derived.inverse_dynamics(q, v, a), u) < 1e-11


def test_the_compiled_step_equals_the_numpy_one_and_the_episodes_the_hand_written(pair):
    derived, hand = pair
    rng = np.random.default_rng(1)
    q, v, u = rng.normal(size=(3, 6, 2))
    fast = advance(derived, get("rk4"), 0.0, q, v, 0.05, 5, u=u, compiled=True)
    slow = advance(derived, get("rk4"), 0.0, q, v, 0.05, 5, u=u, compiled=False)
    assert rel(fast[0], slow[0]) < 1e-12 and rel(fast[1], slow[1]) < 1e-12
    a = simulate(derived, [0.3, -0.4], [0.0, 1.0], 1.0, dt=0.01, integrator="rk4", u=np.array([0.5, -0.2]))
    b = simulate(hand, [0.3, -0.4], [0.0, 1.0], 1.0, dt=0.01, integrator="rk4", u=np.array([0.5, -0.2]))
    assert rel(a.q, b.q) < 1e-10 and rel(a.v, b.v) < 1e-10


def test_the_derivation_is_cached_on_disk_and_the_model_pickles(tmp_path, monkeypatch):
    (q1, q2), T, V = arm_lagrangian()
    params = {k: getattr(Planar2R().params, k) for k in NAMES}
    first = symbolic.cached_derivation("Arm2R", (q1, q2), T, V, params, cache=tmp_path)
    assert len(list(tmp_path.glob("derivation_*.pkl"))) == 1

    def refuse(*args, **kwargs):
        raise AssertionError("derived again although cached")

    monkeypatch.setattr(symbolic.cache, "derive_equations", refuse)
    again = symbolic.cached_derivation("Arm2R", (q1, q2), T, V, params, cache=tmp_path)
    assert again.M == first.M and again.Cv == first.Cv and again.params == first.params
    with pytest.raises(AssertionError, match="derived again"):  # other parameters are another Lagrangian's key
        symbolic.cached_derivation("Arm2R", (q1, q2), T, V, {**params, "g": 1.62}, cache=tmp_path)
    model = symbolic.model_class(first)({"m2": 2.0})
    copy = pickle.loads(pickle.dumps(model))
    assert type(copy).__name__ == "Arm2R" and copy.params.m2 == 2.0
    q = np.array([0.2, -0.7])
    np.testing.assert_array_equal(copy.mass_matrix(q), model.mass_matrix(q))


def test_the_generated_source_is_kept_beside_the_derivation_for_this_version_of_the_package(tmp_path, monkeypatch):
    """A warm process reads the generated code instead of printing the equations again (SymPy's printing), and a
    source kept by another version of the package (another stamp) is not used: it is generated again."""
    (q1, q2), T, V = arm_lagrangian()
    params = {k: getattr(Planar2R().params, k) for k in NAMES}
    d = symbolic.cached_derivation("Arm2R", (q1, q2), T, V, params, cache=tmp_path)
    source = symbolic.source_of(d)
    assert source == symbolic.generate_source(d)
    kept = list(tmp_path.glob("derivation_*.source"))
    assert len(kept) == 1 and symbolic.cache.package_stamp()[:16] in kept[0].name
    head, _, body = kept[0].read_text().partition("\n")
    assert body == source and head == symbolic.cache._source_stamp(source)  # the source under its checksum

    def refuse(*args, **kwargs):
        raise AssertionError("printed again although kept")

    monkeypatch.setattr(symbolic.cache, "generate_source", refuse)
    again = symbolic.cached_derivation("Arm2R", (q1, q2), T, V, params, cache=tmp_path)  # a new process's derivation
    assert symbolic.source_of(again) == source
    monkeypatch.setattr(symbolic.cache, "package_stamp", lambda: "0" * 40)  # another version of the package
    other = symbolic.cached_derivation("Arm2R", (q1, q2), T, V, params, cache=tmp_path)
    with pytest.raises(AssertionError, match="printed again"):
        symbolic.source_of(other)


def test_malformed_lagrangians_are_refused_by_name():
    (q1, q2), T, V = arm_lagrangian()
    params = {k: 1.0 for k in NAMES}
    x = dynamicsymbols("x")
    with pytest.raises(ValueError, match="x.*missing from T"):
        symbolic.derive_equations("Bad", (q1, q2, x), T, V, params)
    with pytest.raises(ValueError, match=r"without a value in params: \['k'\]"):
        symbolic.derive_equations("Bad", (q1, q2), T, V + sp.Symbol("k") * q1, params)
    with pytest.raises(ValueError, match="quadratic in the rates"):
        symbolic.derive_equations("Bad", (q1, q2), T + q1.diff(t) ** 4, V, params)
    with pytest.raises(ValueError, match="actuation"):
        symbolic.derive_equations("Bad", (q1, q2), T, V, params, actuation=np.ones((3, 1)))
    with pytest.raises(ValueError, match="params: 'q0'"):
        symbolic.derive_equations("Bad", (q1, q2), T, V, {**params, "q0": 1.0})
    with pytest.raises(ValueError, match="damping: parameter 'c'"):
        symbolic.derive_equations("Bad", (q1, q2), T, V, params, damping={q1: "c"})
    with pytest.raises(ValueError, match="name"):
        symbolic.derive_equations("not a name", (q1, q2), T, V, params)


def test_a_registered_env_from_the_derived_arm_gives_planar2r_v0s_episodes(pair):
    """The derived arm registered as an id (``mbs_envs.envs.derived.register``) with Planar2R-v0's torque limits,
    reference ranges and steps: the same observations and rewards as ``Planar2R-v0`` on the same seed and actions
    (single env and batched, to 1e-10), and a drawing from the points the user names."""
    import gymnasium as gym

    from mbs_envs.envs import derived as derived_env
    from mbs_envs.envs.planar2r import Planar2REnv

    model, hand = pair
    (q1, q2), _, _ = arm_lagrangian()
    p = hand.params
    points = [(0, 0), (p.l1 * sp.cos(q1), p.l1 * sp.sin(q1)),
              (p.l1 * sp.cos(q1) + p.l2 * sp.cos(q1 + q2), p.l1 * sp.sin(q1) + p.l2 * sp.sin(q1 + q2))]  # fmt: skip
    centre = (Planar2REnv.center_low + Planar2REnv.center_high) / 2
    derived_env.register("mbs_envs_test/Arm2R-v0", model, torque_limit=(40.0, 20.0), posture=centre,
                         spread=(Planar2REnv.center_high - Planar2REnv.center_low) / 2, amplitude=Planar2REnv.max_amplitude,
                         substeps=2, coordinates=(q1, q2), points=points)  # fmt: skip
    params = {k: getattr(p, k) for k in NAMES}
    ours = gym.make("mbs_envs_test/Arm2R-v0", render_mode="rgb_array")
    theirs = gym.make("mbs_envs/Planar2R-v0", params=params)
    assert ours.unwrapped.compiled is not None  # the engine's compiled step on the generated kernels
    a = np.random.default_rng(3).uniform(-1, 1, (100, 2)).astype(np.float32)
    o1, _ = ours.reset(seed=5)
    o2, _ = theirs.reset(seed=5)
    np.testing.assert_allclose(o1, o2, rtol=0, atol=1e-6)  # float32 observations
    for k in range(100):
        o1, r1, *_ = ours.step(a[k])
        o2, r2, *_ = theirs.step(a[k])
        assert abs(r1 - r2) <= 1e-10 * max(1.0, abs(r2))
    np.testing.assert_allclose(ours.unwrapped.q, theirs.unwrapped.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(
        ours.unwrapped.draw_points(ours.unwrapped.q), hand.joint_positions(ours.unwrapped.q), atol=1e-12
    )
    assert ours.render().shape == (500, 500, 3)
    venv = gym.make_vec("mbs_envs_test/Arm2R-v0", num_envs=3, vectorization_mode="vector_entry_point")
    vo, _ = venv.reset(seed=[5, 6, 7])
    o1, _ = ours.reset(seed=5)
    np.testing.assert_array_equal(vo[0], o1)
    assert pickle.loads(pickle.dumps(ours.unwrapped)).model.params == ours.unwrapped.model.params
    with pytest.raises(ValueError, match="model must be a model from"):
        derived_env.register("mbs_envs_test/Bad-v0", hand, torque_limit=1.0, posture=(0.0, 0.0))


# -- constrained mechanisms: the four-bar (loop closure) and the rolling disk (non-holonomic) -------------------


def fourbar_lagrangian():
    """The four-bar of docs/physics.md §4 as a student writes it: the 2R arm (crank, coupler) and the rocker, T and V,
    and the loop closed at B by two holonomic constraints."""
    th1, ph2, ph1 = dynamicsymbols("th1 ph2 ph1")
    l0, l1, l2, l3, m1, m2, m3, r1, r2, r3, I1, I2, I3, g = sp.symbols("l0 l1 l2 l3 m1 m2 m3 r1 r2 r3 I1 I2 I3 g")
    x1, y1 = r1 * sp.cos(th1), r1 * sp.sin(th1)
    x2, y2 = l1 * sp.cos(th1) + r2 * sp.cos(th1 + ph2), l1 * sp.sin(th1) + r2 * sp.sin(th1 + ph2)
    d = lambda e: e.diff(t)  # noqa: E731
    T = (m1 * (d(x1) ** 2 + d(y1) ** 2) + I1 * d(th1) ** 2 + m2 * (d(x2) ** 2 + d(y2) ** 2) + I2 * (d(th1) + d(ph2)) ** 2
         + (I3 + m3 * r3**2) * d(ph1) ** 2) / 2  # fmt: skip
    V = g * (m1 * y1 + m2 * y2 + m3 * r3 * sp.sin(ph1))
    phi = [
        l1 * sp.cos(th1) + l2 * sp.cos(th1 + ph2) - l0 - l3 * sp.cos(ph1),
        l1 * sp.sin(th1) + l2 * sp.sin(th1 + ph2) - l3 * sp.sin(ph1),
    ]
    return (th1, ph2, ph1), T, V, phi


def disk_lagrangian():
    """The rolling disk of docs/physics.md §5 through ``sympy.physics.mechanics`` frames: heading and lean frame ``L``
    (``Body`` ZXY), the disk ``D`` spinning about ``L.y``; T from the centre's velocity and ``w . I . w``; rolling is
    the contact point's velocity ``v + w x (-r L.z)`` being zero: its vertical row holonomic (``z = r cos th2``), the
    horizontal ones not."""
    from sympy.physics.mechanics import ReferenceFrame, inertia

    x, y, z, th1, th2, th3 = dynamicsymbols("x y z th1 th2 th3")
    m, r, g = sp.symbols("m r g")
    N = ReferenceFrame("N")
    L = N.orientnew("L", "Body", (th1, th2, 0), "ZXY")
    D = L.orientnew("D", "Axis", (th3, L.y))
    w = D.ang_vel_in(N)
    vc = x.diff(t) * N.x + y.diff(t) * N.y + z.diff(t) * N.z
    T = m * vc.dot(vc) / 2 + w.dot(inertia(D, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4).dot(w)) / 2
    contact = vc + w.cross(-r * L.z)
    return (x, y, z, th1, th2, th3), T, m * g * z, [z - r * sp.cos(th2)], [contact.dot(N.x), contact.dot(N.y)]


FOURBAR = ("l0", "l1", "l2", "l3", "m1", "m2", "m3", "r1", "r2", "r3", "I1", "I2", "I3", "g", "b1", "b2", "b3")


@pytest.fixture(scope="module")
def fourbars(tmp_path_factory):
    from mbs_envs.models import FourBar

    (th1, ph2, ph1), T, V, phi = fourbar_lagrangian()
    hand = FourBar(b1=0.1, b2=0.05, b3=0.02)
    params = {k: getattr(hand.params, k) for k in FOURBAR}
    d = symbolic.cached_derivation("FourBarD", (th1, ph2, ph1), T, V, params, [[1.0], [0.0], [0.0]], {th1: "b1", ph2: "b2", ph1: "b3"},
                                   tmp_path_factory.mktemp("derived"), constraints=phi, independent=[th1])  # fmt: skip
    return symbolic.model_class(d)(), hand


@pytest.fixture(scope="module")
def disks(tmp_path_factory):
    from mbs_envs.models import RollingDisk

    q, T, V, phi, rolling = disk_lagrangian()
    hand = RollingDisk(b_roll=0.01, b_pivot=0.02)
    params = {k: getattr(hand.params, k) for k in ("m", "r", "g", "b_roll", "b_pivot")}
    d = symbolic.cached_derivation("DiskD", q, T, V, params, hand.actuation, {q[5]: "b_roll", q[3]: "b_pivot"}, tmp_path_factory.mktemp("derived"),
                                   constraints=phi, velocity_constraints=rolling, independent=q[3:])  # fmt: skip
    return symbolic.model_class(d)(), hand


#: the disk's rows: derived (z: holonomic first; x, y) -> hand-written (x, y, z)
DISK_ROWS = [1, 2, 0]


@pytest.mark.parametrize("which", ["fourbar", "disk"])
def test_the_derived_constrained_mechanisms_are_the_hand_written_ones(which, fourbars, disks):
    """Mass matrix, bias, gravity, energy, phi, Psi, Psi_dot v, forward dynamics and multipliers on random (not
    necessarily consistent) states to 1e-12 relative; the disk's rows reordered (holonomic first). The disk's lean
    stays within 1.2 rad: at +-pi/2 its Euler angles are singular (M's heading-spin block has determinant
    A C cos^2(lean); the model's ``singular`` flags it), and there both models' accelerations are rounding amplified
    by 1 / cos^2 (7e-3 apart at cos = 0.002)."""
    derived, hand = fourbars if which == "fourbar" else disks
    rows = list(range(hand.nc)) if which == "fourbar" else DISK_ROWS
    rng = np.random.default_rng(4)
    q, v = rng.normal(size=(2, 300, hand.nq)) * np.array([2.0, 3.0])[:, None, None]
    if which == "disk":
        q[:, 4] = rng.uniform(-1.2, 1.2, 300)
    u = rng.normal(size=(300, hand.nu))
    for name in ("mass_matrix", "gravity", "potential_energy", "constraint_residual"):
        assert rel(getattr(derived, name)(q), getattr(hand, name)(q)) < 1e-12, name
    for name in ("bias", "coriolis", "kinetic_energy"):
        assert rel(getattr(derived, name)(q, v), getattr(hand, name)(q, v)) < 1e-12, name
    assert rel(derived.constraint_jacobian(q)[..., rows, :], hand.constraint_jacobian(q)) < 1e-12
    assert rel(derived.constraint_bias(q, v)[..., rows], hand.constraint_bias(q, v)) < 1e-12
    assert rel(derived.forward_dynamics(q, v, u), hand.forward_dynamics(q, v, u)) < 1e-12
    assert rel(derived.multipliers(q, v, u)[..., rows], hand.multipliers(q, v, u)) < 1e-12
    qc, vc = hand.moving_state()
    lam = derived.multipliers(qc, vc, u[:5], compiled=True)  # the compiled kernel the env steps report
    assert rel(lam[..., rows], hand.multipliers(qc, vc, u[:5])) < 1e-12


@pytest.mark.parametrize(
    "which", ["fourbar", pytest.param("disk", marks=pytest.mark.slow)]
)  # the disk's compile: slow set
def test_derived_constrained_episodes_are_the_hand_written_ones_and_hold_the_constraints(which, fourbars, disks):
    """Simulations (RK4 with projection, compiled and numpy) equal the hand-written model's to 1e-10; over 1e4
    steps the projection keeps |phi| and |Psi v| below 1e-10."""
    derived, hand = fourbars if which == "fourbar" else disks
    q0, v0 = hand.moving_state()  # the disk rolling at twice its critical spin, leaning 0.1 rad
    u = (
        np.array([0.3]) if which == "fourbar" else np.array([0.01, 0.0])
    )  # a steering torque of 0.3 N m would topple the disk
    rng = np.random.default_rng(2)
    qb, vb = hand.moving_state()
    qb, vb = hand.project(qb + rng.normal(0, 0.01, (4, hand.nq)), vb + rng.normal(0, 0.1, (4, hand.nv)))
    fast = advance(derived, get("rk4"), 0.0, qb, vb, 0.05, 5, u=u, stabilization=derived.stabilization(), compiled=True)
    slow = advance(
        derived, get("rk4"), 0.0, qb, vb, 0.05, 5, u=u, stabilization=derived.stabilization(), compiled=False
    )
    assert rel(fast[0], slow[0]) < 1e-12 and rel(fast[1], slow[1]) < 1e-12
    a = simulate(derived, q0, v0, 2.0, dt=0.01, integrator="rk4", u=u)
    b = simulate(hand, q0, v0, 2.0, dt=0.01, integrator="rk4", u=u)
    assert not a.diverged and rel(a.q, b.q) < 1e-10 and rel(a.v, b.v) < 1e-10
    if which == "disk":  # 100 s of rolling: without resistance (which would slow the spin below critical and topple it)
        derived, u = type(derived)({"b_roll": 0.0, "b_pivot": 0.0}), np.zeros(2)
    long = simulate(derived, q0, v0, 100.0, dt=0.01, integrator="rk4", u=u)
    assert len(long.t) == 10_001 and not long.diverged
    assert float(np.max(derived.constraint_violation(long.q, long.v))) < 1e-10


def test_constrained_lagrangians_that_are_malformed_are_refused_by_name():
    (th1, ph2, ph1), T, V, phi = fourbar_lagrangian()
    params = {k: 1.0 for k in FOURBAR[:14]}
    params.update(l1=0.3, l3=0.8)
    with pytest.raises(ValueError, match=r"constraints\[1\].*not a function of the coordinates alone.*rates"):
        symbolic.derive_equations(
            "Bad", (th1, ph2, ph1), T, V, params, constraints=[phi[0], th1.diff(t) - 1], independent=[th1]
        )
    with pytest.raises(ValueError, match=r"constraints\[0\].*holds none of"):
        symbolic.derive_equations(
            "Bad", (th1, ph2, ph1), T, V, params, constraints=[sp.Symbol("l0") - 1], independent=[th1, ph2]
        )
    with pytest.raises(ValueError, match=r"velocity_constraints\[0\].*linear and homogeneous"):
        symbolic.derive_equations(
            "Bad", (th1, ph2, ph1), T, V, params, velocity_constraints=[th1.diff(t) ** 2], independent=[th1, ph2]
        )
    with pytest.raises(ValueError, match=r"constraints\[0\].*without a value in params: \['k'\]"):
        symbolic.derive_equations(
            "Bad", (th1, ph2, ph1), T, V, params, constraints=[phi[0] * sp.Symbol("k")], independent=[th1, ph2]
        )
    with pytest.raises(ValueError, match="independent: a constrained mechanism names"):
        symbolic.derive_equations("Bad", (th1, ph2, ph1), T, V, params, constraints=phi)
    with pytest.raises(ValueError, match="independent: 2 coordinates given"):
        symbolic.derive_equations("Bad", (th1, ph2, ph1), T, V, params, constraints=phi, independent=[th1, ph2])
    with pytest.raises(ValueError, match="dependent, or do not fix"):  # the same closure twice
        symbolic.derive_equations(
            "Bad", (th1, ph2, ph1), T, V, params, constraints=[phi[0], 2 * phi[0]], independent=[th1]
        )
    x, y = dynamicsymbols("x y")
    with pytest.raises(ValueError, match="mass matrix of Bad is singular"):  # two rates that only ever appear summed
        symbolic.derive_equations("Bad", (x, y), sp.Symbol("m") * (x.diff(t) + y.diff(t)) ** 2 / 2, 0, {"m": 1.0})


@pytest.mark.slow  # compiles the derived four-bar's env step (the default run has the 2R arm's env episodes)
def test_the_derived_four_bar_as_an_env_gives_fourbar_v0s_episodes(fourbars):
    """The re-derived four-bar registered with FourBar-v0's torque limit and reference ranges (the crank on a rippled
    spin, starts assembled from the open branch): the same observations, rewards and multipliers as
    ``mbs_envs/FourBar-v0`` on the same seeds and actions, single and batched, to 1e-10 (angles modulo 2 pi: the
    derived starts are continued from the guess, the hand-written ones in [-pi, pi))."""
    import gymnasium as gym

    from mbs_envs.envs import derived as derived_env
    from mbs_envs.models import FourBar

    model, _ = fourbars
    hand = FourBar()
    derived_env.register("mbs_envs_test/FourBarD-v0", type(model)({k: getattr(hand.params, k) for k in FOURBAR}), torque_limit=8.0,
                         posture=[0.0], spread=np.pi, amplitude=0.5, rate=(1.0, 4.0), guess=hand.assemble(0.0))  # fmt: skip
    ours, theirs = gym.make("mbs_envs_test/FourBarD-v0"), gym.make("mbs_envs/FourBar-v0")
    assert ours.unwrapped.compiled is not None
    actions = np.random.default_rng(0).uniform(-1, 1, (200, 1)).astype(np.float32)
    for seed in (3, 4):
        o1, _ = ours.reset(seed=seed)
        o2, _ = theirs.reset(seed=seed)
        np.testing.assert_allclose(o1, o2, rtol=0, atol=1e-6)  # float32
        for a in actions:
            o1, r1, *_, i1 = ours.step(a)
            o2, r2, *_, i2 = theirs.step(a)
            assert abs(r1 - r2) <= 1e-10 * max(1.0, abs(r2))
        dq = ours.unwrapped.q - theirs.unwrapped.q
        assert np.max(np.abs((dq + np.pi) % (2 * np.pi) - np.pi)) < 1e-10
        assert rel(i1["multipliers"], i2["multipliers"]) < 1e-10
    v1 = gym.make_vec("mbs_envs_test/FourBarD-v0", num_envs=3, vectorization_mode="vector_entry_point")
    v2 = gym.make_vec("mbs_envs/FourBar-v0", num_envs=3, vectorization_mode="vector_entry_point")
    o1, _ = v1.reset(seed=[3, 4, 5])
    o2, _ = v2.reset(seed=[3, 4, 5])
    for a in actions[:50]:
        o1, r1, *_ = v1.step(np.repeat(a[None], 3, axis=0))
        o2, r2, *_ = v2.step(np.repeat(a[None], 3, axis=0))
    np.testing.assert_allclose(o1, o2, rtol=0, atol=1e-5)
    np.testing.assert_allclose(r1, r2, rtol=1e-10, atol=1e-12)


def test_parameters_named_like_the_generated_codes_locals_are_their_own():
    """A pendulum on a cart whose parameters are called ``b``, ``A``, ``S``, ``C``, ``g`` and ``B`` (the generated
    kernels' loop variable and work arrays, before they named parameters ``_p<k>``): the compiled step equals the
    numpy one and the closed form ``M``."""
    x, th = dynamicsymbols("x th")
    b, A, S, C, g, B = sp.symbols("b A S C g B")
    bob = sp.Matrix([x + S * sp.sin(th), -S * sp.cos(th)])
    T = (A * x.diff(t) ** 2 + C * bob.diff(t).dot(bob.diff(t))) / 2
    params = {"b": 0.3, "A": 1.5, "S": 0.7, "C": 0.4, "g": 9.81, "B": 0.2}
    d = symbolic.derive_equations("Clash", (x, th), T, g * C * bob[1], params, damping={x: "b", th: "B"})
    model = symbolic.model_class(d)()
    q = np.array([[0.1, 0.5], [-0.3, 2.0]])
    np.testing.assert_allclose(
        model.mass_matrix(q)[0], [[1.9, 0.4 * 0.7 * np.cos(0.5)], [0.4 * 0.7 * np.cos(0.5), 0.4 * 0.49]], rtol=1e-14
    )
    v, u = np.array([[1.0, -2.0], [0.5, 0.3]]), np.array([[1.0, 0.2], [-0.5, 0.0]])
    fast = advance(model, get("rk4"), 0.0, q, v, 0.05, 5, u=u, compiled=True)
    slow = advance(model, get("rk4"), 0.0, q, v, 0.05, 5, u=u, compiled=False)
    assert rel(fast[0], slow[0]) < 1e-12 and rel(fast[1], slow[1]) < 1e-12


# -- friction laws: Coulomb and Stribeck as expressions in the rates ---------------------------------------------


def coulomb_stribeck(w, f, df):
    """``f tanh(w / v_s) + df exp(-(w / v_st)^2) tanh(w / v_s)``: the hand-written models' law, as a user writes it."""
    v_s, v_st = sp.symbols("v_s v_st")
    return f * sp.tanh(w / v_s) + df * sp.exp(-((w / v_st) ** 2)) * sp.tanh(w / v_s)


def test_a_coulomb_and_stribeck_friction_law_derives_as_the_hand_written_one(tmp_path):
    """The 2R arm with ``friction={q_i: law}`` next to its viscous ``damping``: friction, forward dynamics and inverse
    dynamics equal Planar2R's Coulomb + Stribeck law to 1e-12 (rates near the smoothing speed, where the law is
    steep, and far beyond it), the compiled step the numpy one to 1e-12, the episodes the hand-written ones to 1e-10
    (the four-bar's crank friction likewise through the constrained path: the slow set)."""
    (q1, q2), T, V = arm_lagrangian()
    f1, f2, df1, df2 = sp.symbols("f1 f2 df1 df2")
    hand = Planar2R(m1=1.3, m2=0.7, l1=0.9, l2=1.1, r1=0.4, r2=0.6, I1=0.08, I2=0.05, b1=0.2, b2=0.1, f1=0.5, f2=0.3,
                    df1=0.4, df2=0.2, v_s=0.01, v_st=0.1)  # fmt: skip
    params = {k: getattr(hand.params, k) for k in NAMES + ("f1", "f2", "df1", "df2", "v_s", "v_st")}
    law = {q1: coulomb_stribeck(q1.diff(t), f1, df1), q2: coulomb_stribeck(q2.diff(t), f2, df2)}
    d = symbolic.cached_derivation(
        "Arm2RF", (q1, q2), T, V, params, damping={q1: "b1", q2: "b2"}, friction=law, cache=tmp_path
    )
    derived = symbolic.model_class(d)()
    rng = np.random.default_rng(7)
    q, u = rng.normal(size=(2, 300, 2)) * np.array([3.0, 10.0])[:, None, None]
    v = rng.normal(size=(300, 2)) * np.where(np.arange(300) < 150, 0.02, 5.0)[:, None]
    assert rel(derived.friction(v), hand.friction(v)) < 1e-12
    assert rel(derived.bias(q, v), hand.bias(q, v)) < 1e-12
    assert rel(derived.forward_dynamics(q, v, u), hand.forward_dynamics(q, v, u)) < 1e-12
    assert rel(derived.inverse_dynamics(q, v, hand.forward_dynamics(q, v, u)), u) < 1e-11
    fast = advance(derived, get("rk4"), 0.0, q[:6], v[:6], 0.05, 50, u=u[:6], compiled=True)
    slow = advance(derived, get("rk4"), 0.0, q[:6], v[:6], 0.05, 50, u=u[:6], compiled=False)
    assert rel(fast[0], slow[0]) < 1e-12 and rel(fast[1], slow[1]) < 1e-12
    a = simulate(derived, [0.3, -0.4], [0.0, 1.0], 1.0, dt=0.001, integrator="rk4", u=np.array([0.5, -0.2]))
    b = simulate(hand, [0.3, -0.4], [0.0, 1.0], 1.0, dt=0.001, integrator="rk4", u=np.array([0.5, -0.2]))
    assert rel(a.q, b.q) < 1e-10 and rel(a.v, b.v) < 1e-10


@pytest.mark.slow  # another generated module to compile (about 15 s cold): the default run has the arm's law above
def test_a_friction_law_on_a_closed_loop_derives_as_the_hand_written_one(tmp_path):
    """The four-bar's crank with FourBar's Coulomb + Stribeck law: forward dynamics and multipliers to 1e-12, episodes
    to 1e-10, through the constrained path."""
    from mbs_envs.models import FourBar

    f1, df1 = sp.symbols("f1 df1")
    rng = np.random.default_rng(8)
    (th1, ph2, ph1), T4, V4, phi = fourbar_lagrangian()
    hand4 = FourBar(b1=0.1, f1=0.3, df1=0.2)
    params4 = {k: getattr(hand4.params, k) for k in FOURBAR + ("f1", "df1", "v_s", "v_st")}
    d4 = symbolic.cached_derivation("FourBarF", (th1, ph2, ph1), T4, V4, params4, [[1.0], [0.0], [0.0]], {th1: "b1", ph2: "b2", ph1: "b3"},
                                    tmp_path, constraints=phi, independent=[th1], friction={th1: coulomb_stribeck(th1.diff(t), f1, df1)})  # fmt: skip
    derived4 = symbolic.model_class(d4)()
    q0, v0 = hand4.moving_state()
    qs = np.repeat(q0[None], 4, axis=0)
    vs = v0[None] * np.array([0.01, 0.1, 1.0, 3.0])[:, None]
    us = rng.normal(size=(4, 1))
    assert rel(derived4.forward_dynamics(qs, vs, us), hand4.forward_dynamics(qs, vs, us)) < 1e-12
    assert rel(derived4.multipliers(qs, vs, us, compiled=True), hand4.multipliers(qs, vs, us)) < 1e-12
    a = simulate(derived4, q0, v0, 0.5, dt=0.001, integrator="rk4", u=np.array([0.3]))
    b = simulate(hand4, q0, v0, 0.5, dt=0.001, integrator="rk4", u=np.array([0.3]))
    assert rel(a.q, b.q) < 1e-10 and rel(a.v, b.v) < 1e-10


def test_friction_laws_that_are_malformed_are_refused_by_name():
    (q1, q2), T, V = arm_lagrangian()
    params = {k: 1.0 for k in NAMES}
    x = dynamicsymbols("x")
    with pytest.raises(ValueError, match=r"friction: x\(t\) is not a coordinate"):
        symbolic.derive_equations("Bad", (q1, q2), T, V, params, friction={x: x.diff(t)})
    with pytest.raises(
        ValueError, match=r"the law of q1\(t\) is not a function of the rates alone: it holds \['q2\(t\)'\]"
    ):
        symbolic.derive_equations("Bad", (q1, q2), T, V, params, friction={q1: sp.sin(q2) * q1.diff(t)})
    with pytest.raises(ValueError, match=r"uses symbols without a value in params: \['mu'\]"):
        symbolic.derive_equations("Bad", (q1, q2), T, V, params, friction={q1: sp.Symbol("mu") * sp.tanh(q1.diff(t))})
    with pytest.raises(ValueError, match="friction must be a mapping"):
        symbolic.derive_equations("Bad", (q1, q2), T, V, params, friction=[q1.diff(t)])


def test_the_light_dynamicsymbols_are_sympys():
    """symbolic.dynamicsymbols returns what sympy.physics.mechanics' does (equal, the same srepr: the same cache key)."""
    for names in ("th", "x th", "q1, q2, q3"):
        ours, theirs = symbolic.dynamicsymbols(names), dynamicsymbols(names)
        assert ours == theirs and sp.srepr(ours) == sp.srepr(theirs)
    assert symbolic.time_symbol() == dynamicsymbols._t
    th = symbolic.dynamicsymbols("th")
    assert th.diff(symbolic.time_symbol()) == dynamicsymbols("th", 1)


def test_a_warm_process_makes_a_derived_scene_without_sympy_physics():
    """A derived scene's first make, reset and step with the derivation cached: sympy.physics (0.1 s of imports)
    is not loaded; only a derivation (a cache miss) imports it."""
    import subprocess
    import sys

    import gymnasium as gym

    gym.make("mbs_envs/CartPoleSwingUp-v0")  # the derivation is in this run's cache now
    code = ("import sys, gymnasium as gym, mbs_envs\n"
            "env = gym.make('mbs_envs/CartPoleSwingUp-v0'); env.reset(seed=0); env.step(env.action_space.sample())\n"
            "print(sorted(m for m in sys.modules if m.startswith('sympy.physics')))")  # fmt: skip
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().splitlines()[-1] == "[]"
