"""Adversarial input, generated: every class of docs/reliability.md's promises under inputs beyond the documented ones.

- constructor keywords of every id drawn from wrong types and out-of-range values:
  a clear ``ValueError`` or a working env, nothing else;
- the same values through ``set_attr`` on the SB3 adapter;
- model parameters (wrong types, arrays, huge, tiny, negative, NaN);
- reset start states near singular and beyond-limit configurations: ``ValueError``
  that changes nothing, or an observation inside ``observation_space``;
- every integrator under runaway inputs on every scene: the step returns within
  the test's own wall-clock bound, flags divergence, never NaN.

Each generated class records how many cases it ran in ``CASES`` (printed after the module with ``-s``).
"""

from __future__ import annotations

import collections
import signal
import time

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mbs_envs
from mbs_envs import integrators
from mbs_envs.envs import registry as scenes
from mbs_envs.models.fourbar import FourBar
from mbs_envs.models.planar2r import Planar2R
from mbs_envs.models.rolling_disk import RollingDisk
from mbs_envs.models.serial_chain import SerialChain
from mbs_envs.dynamics.simulate import simulate
from tests.budget import examples

CASES: collections.Counter = collections.Counter()


@pytest.fixture(scope="module", autouse=True)
def _report_case_counts(request):
    """After the module: how many generated cases each class ran (visible with ``-s``)."""
    yield
    print("\ngenerated adversarial cases:", dict(CASES))


IDS = list(mbs_envs.ENV_IDS)
#: the joint-tracking scenes (start_noise, reward_weights and compiled are their keywords)
TRACKING_IDS = [i for i in IDS if i != "mbs_envs/RollingDisk-v0"]

#: values a user may pass by mistake, beyond the documented types and ranges
WILD = st.one_of(
    st.sampled_from(
        [
            "0.01",
            "x",
            "",
            b"1",
            None,
            True,
            False,
            1j,
            [1, 2],
            (0.1,),
            {"a": 1},
            {1, 2},
            object(),
            np.datetime64("2020-01-01"),
            np.array([np.nan]),
            np.array("1.0"),
        ]
    ),  # fmt: skip
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**20), 10**20),
    st.lists(st.floats(-1e3, 1e3), min_size=0, max_size=4),
)

#: constructor keywords of every id (the scene-specific ones only where they exist)
KEYWORDS = {
    "dt": IDS, "substeps": IDS, "divergence_limit": IDS, "torque_limit": IDS, "integrator": IDS, "rtol": IDS,
    "start_noise": TRACKING_IDS, "reward_weights": TRACKING_IDS, "params": IDS, "compiled": TRACKING_IDS,
    "lean_limit": ["mbs_envs/RollingDisk-v0"], "residual_limit": ["mbs_envs/FourBar-v0"], "branch": ["mbs_envs/FourBar-v0"],
    "n_links": ["mbs_envs/SerialChain-v0"], "stabilization": ["mbs_envs/FourBar-v0", "mbs_envs/RollingDisk-v0"],
}  # fmt: skip
PAIRS = [(env_id, key) for key, ids in KEYWORDS.items() for env_id in ids]


def _usable(env: gym.Env) -> None:
    """A constructed env must reset and step to finite observations inside its space (or flag divergence)."""
    obs, _ = env.reset(seed=0)
    assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample() * 0)
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(pair=st.sampled_from(PAIRS), value=WILD)
def test_constructor_keywords_give_a_working_env_or_a_value_error(pair, value):
    env_id, key = pair
    CASES["constructor keywords"] += 1
    try:
        env = gym.make(env_id, **{key: value}, disable_env_checker=True)
    except ValueError as err:
        message = str(err)
        assert (
            key in message
            or key in ("params", "integrator", "rtol", "stabilization", "compiled")
            or "params" in message
        ), message
        return
    _usable(env)


@pytest.mark.parametrize(
    "dt",
    [5e-324, pytest.param(2.2250738585e-313, marks=pytest.mark.slow), pytest.param(1e-300, marks=pytest.mark.slow)],
)
def test_every_scene_takes_a_subnormal_or_tiny_dt(dt):
    """Found by the test above in two runs (1 / dt overflowed render_fps, and the disk's trail length):
    a valid dt this small builds, resets and steps every scene (deterministic here)."""
    for env_id in IDS:
        _usable(gym.make(env_id, dt=dt, disable_env_checker=True))


SETTABLE = {
    "dt": WILD,
    "substeps": WILD,
    "start_noise": WILD,
    "reward_weights": WILD,
    "divergence_limit": WILD,
    "u_max": WILD,
}


@settings(max_examples=examples(60), deadline=None, suppress_health_check=list(HealthCheck))
@given(key=st.sampled_from(sorted(SETTABLE)), value=WILD)
def test_set_attr_on_the_sb3_adapter_validates_like_the_constructor(key, value):
    from mbs_envs.envs.sb3 import make_sb3_vec_env

    CASES["set_attr"] += 1
    venv = make_sb3_vec_env("mbs_envs/Planar2R-v0", n_envs=2, seed=0)
    venv.reset()
    before = venv.get_attr(key)[0]
    try:
        venv.set_attr(key, value)
    except ValueError:
        after = venv.get_attr(key)[0]
        assert np.array_equal(np.asarray(after), np.asarray(before))  # a refused value changes nothing
        return
    obs, reward, done, info = venv.step(np.zeros((2, 2)))
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))


MODELS = {Planar2R: ["m1", "l1", "r1", "I1", "g", "b1", "f1", "v_s"], FourBar: ["l0", "l1", "l2", "m2", "I3", "g"],
          RollingDisk: ["m", "r", "g", "b_roll"], SerialChain: ["m", "l", "r", "I", "g", "armature", "b", "v_s"]}  # fmt: skip
PARAM_VALUES = st.one_of(WILD, st.sampled_from([0.0, -1.0, 1e-6, 1e6, 1e12, 1e13, 1e200, -1e200, 5e-324]))


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(model=st.sampled_from(sorted(MODELS, key=lambda c: c.__name__)), data=st.data())
def test_model_parameters_are_validated_by_name(model, data):
    CASES["model parameters"] += 1
    name = data.draw(st.sampled_from(MODELS[model]))
    value = data.draw(PARAM_VALUES)
    try:
        m = model(**{name: value})
    except ValueError as err:
        assert name in str(err) or "parameters" in str(err), str(err)
        return
    assert np.isfinite(np.asarray(getattr(m.params, name), float)).all()


def _near_singular_states(env_id: str) -> st.SearchStrategy:
    """Start states around each scene's singular and beyond-limit configurations."""
    env = gym.make(env_id).unwrapped
    nq, nv = env.model.nq, env.model.nv
    big = st.sampled_from(
        [0.0, 1.0, -np.pi / 2, np.pi / 2, np.pi, 1e7, 1e8, 1e8 * (1 + 1e-15), 1e9, 1e300, np.nan, -np.inf]
    )
    small = st.floats(-4, 4)
    entry = st.one_of(small, big)
    q = st.lists(entry, min_size=nq, max_size=nq)
    v = st.one_of(st.none(), st.lists(entry, min_size=nv, max_size=nv))
    return st.tuples(q, v)


@pytest.mark.parametrize("env_id", IDS)
def test_reset_from_wild_states_refuses_or_starts_inside_the_space(env_id):
    env = gym.make(env_id)
    env.reset(seed=1)
    base = env.unwrapped

    @settings(max_examples=examples(60), deadline=None, suppress_health_check=list(HealthCheck))
    @given(state=_near_singular_states(env_id))
    def run(state):
        CASES["reset start states"] += 1
        q, v = state
        keep = base.q, base.v, base.t
        options = {"q": q} if v is None else {"q": q, "v": v}
        try:
            obs, info = env.reset(options=options)
        except ValueError:
            np.testing.assert_array_equal(base.q, keep[0])  # refused: nothing changed
            np.testing.assert_array_equal(base.v, keep[1])
            assert base.t == keep[2]
            return
        assert np.all(np.isfinite(obs)) and env.observation_space.contains(obs), obs
        obs, reward, *_ = env.step(np.ones(env.action_space.shape))
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)

    run()


@pytest.mark.parametrize("env_id", IDS)
def test_vector_reset_refusing_a_start_changes_no_member(env_id):
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    venv.step(np.zeros(venv.action_space.shape))
    q, v, t = venv.unwrapped._q.copy(), venv.unwrapped._v.copy(), venv.unwrapped._t.copy()
    nq = venv.unwrapped.model.nq
    with pytest.raises(ValueError, match="start state"):
        venv.reset(options={"q": np.full(nq, 1e9)})
    np.testing.assert_array_equal(venv.unwrapped._q, q)
    np.testing.assert_array_equal(venv.unwrapped._v, v)
    np.testing.assert_array_equal(venv.unwrapped._t, t)


class _Timeout(Exception):
    pass


def _alarm(*_):
    raise _Timeout


#: wall-clock bound [s] on one diverging step (after a first runaway episode, which may compile)
STEP_BOUND = 2.0


@pytest.mark.parametrize("integrator", integrators.available())
def test_runaway_under_every_integrator_is_flagged_in_bounded_time(integrator):
    """Torque limits of 1e200 and full actions: each scene's step returns within STEP_BOUND, flags, never NaN."""
    old = signal.signal(signal.SIGALRM, _alarm)
    try:
        for env_id in IDS:
            if not integrators.applies(integrator, scenes.load(scenes.scene(env_id).model)()):
                with pytest.raises(ValueError, match="unconstrained models"):  # refused at make, clearly
                    gym.make(env_id, integrator=integrator)
                continue
            env = gym.make(env_id, integrator=integrator, torque_limit=1e200)
            env.reset(seed=0)
            # Untimed first: a step and a runaway episode may compile kernels (the step's, and the
            # constrained scenes' general member path, compiled on first need: see
            # mbs_envs.models.fourbar.general_acceleration).
            signal.alarm(120)
            env.step(np.zeros(env.action_space.shape))
            for _ in range(3):
                if env.step(np.ones(env.action_space.shape))[2]:
                    break
            env.reset(seed=0)
            for _ in range(3):
                CASES["runaway steps"] += 1
                signal.alarm(int(STEP_BOUND) + 1)  # the test's own timeout
                t0 = time.perf_counter()
                obs, reward, terminated, truncated, info = env.step(np.ones(env.action_space.shape))
                elapsed = time.perf_counter() - t0
                signal.alarm(0)
                assert elapsed < STEP_BOUND, (env_id, elapsed)
                assert np.all(np.isfinite(obs)) and np.isfinite(reward)
                if terminated:
                    assert info["diverged"], (env_id, info)
                    break
            else:
                pytest.fail(f"{env_id} with {integrator}: a 1e200 N m torque did not diverge")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize("integrator", integrators.available())
def test_simulate_with_a_nan_input_returns_flagged(integrator):
    """A callable input that returns NaN (scipy's step control loops forever on it) ends flagged, in bounded time."""
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(20)
    try:
        CASES["nan input"] += 1
        tr = simulate(Planar2R(), [-1.0, 0.5], [0.0, 0.0], 0.05, dt=0.005, integrator=integrator,
                      u=lambda t, q, v: np.array([np.nan, 0.0]), compiled=False)  # fmt: skip
        assert tr.diverged
        assert np.all(np.isfinite(tr.q)) and np.all(np.isfinite(tr.v))
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize("value", [np.nan, -1.0, 0.0, np.inf, "1e8", None])
def test_simulate_refuses_a_bad_divergence_limit(value):
    with pytest.raises(ValueError, match="divergence_limit"):
        simulate(Planar2R(), [0.0, 0.0], [0.0, 0.0], 0.01, divergence_limit=value)


@pytest.mark.parametrize("integrator", ["rk4", "rk45", "radau"])
def test_simulate_refuses_a_start_beyond_the_limit_alike_for_every_method(integrator):
    with pytest.raises(ValueError, match="initial state is beyond divergence_limit"):
        simulate(Planar2R(), [1e9, 0.0], [0.0, 0.0], 0.01, integrator=integrator)


# -- the reproductions of issue 17, one line each ------------------------------------


def test_disk_flat_start_is_refused_not_nan():
    env = gym.make("mbs_envs/RollingDisk-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="start state given in options"):
        env.reset(seed=0, options={"q": [0, 0, 0, 0, np.pi / 2, 0]})
    obs, reward, *_ = env.step([0, 0])  # the episode before is intact
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)


def test_fourbar_whose_crank_cannot_turn_is_refused_at_construction():
    with pytest.raises(ValueError, match="crank cannot turn fully"):
        gym.make("mbs_envs/FourBar-v0", params={"l1": 0.9})


@pytest.mark.parametrize(
    "kwargs, match", [({"divergence_limit": 1.0}, "divergence_limit"), ({"params": {"g": 1e300}}, "'g'")]
)
@pytest.mark.parametrize("env_id", ["mbs_envs/Planar2R-v0", "mbs_envs/RollingDisk-v0"])
def test_settings_that_would_start_outside_the_space_are_refused(env_id, kwargs, match):
    if "params" in kwargs and env_id.endswith("Planar2R-v0"):
        kwargs = {"params": {"g": 1e300}}
    with pytest.raises(ValueError, match=match):
        gym.make(env_id, **kwargs)


def test_controllers_refuse_envs_they_do_not_fit():
    from mbs_envs.controllers import LQR, ComputedTorque

    with pytest.raises(ValueError, match="LQR acts on RollingDiskEnv"):
        LQR(gym.make("mbs_envs/Planar2R-v0"))
    with pytest.raises(ValueError, match="ComputedTorque acts on JointTrackingEnv"):
        ComputedTorque(gym.make("mbs_envs/RollingDisk-v0"))
    with pytest.raises(ValueError, match="kp"):
        ComputedTorque(gym.make("mbs_envs/Planar2R-v0"), kp=np.nan)


@pytest.mark.parametrize(
    "env_id", ["mbs_envs/Planar2R-v0", "mbs_envs/FourBar-v0", "mbs_envs/RollingDisk-v0", "mbs_envs/SerialChain-v0"]
)
def test_a_ready_params_instance_works_for_every_id(env_id):
    env = gym.make(env_id)
    params = env.unwrapped.model.params
    _usable(gym.make(env_id, params=params))
