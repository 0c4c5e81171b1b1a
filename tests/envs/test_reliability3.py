"""Reliability, third round (issue 34): each class of defect, with generated variants beyond its reproduction.

Every registered id; the single env, the batched vector env and the SB3 adapter; the compiled and
the numpy paths where a class touches the step. Each class counts the cases it ran in ``CASES``
(printed after the module with ``-s``; docs/reliability.md quotes them).

1. ``model`` is fixed at construction (assignment and ``set_attr`` refused; no crash, no silent swap);
2. copies and pickles of a vector env mid-episode step exactly as the original;
3. a refused call (bad options, bad seeds, bad masks, bad actions) leaves state and generators as they were;
4. one seed rule: ``None`` or an int >= 0, for single, vector (per member) and SB3 ``seed()``;
5. on a next-step autoreset the reset members' ``info`` is their reset's, as ``SyncVectorEnv`` gives it,
   and their (ignored) action may be NaN;
6. finite observations give finite actions from every controller; NaN observations are refused; the disk
   task without gravity is refused;
7. array settings are read-only; every setting is validated on assignment and through ``set_attr``;
   names that are not settings are refused;
8. one numeric parser: strings, booleans, complex numbers, masked entries, mappings refused everywhere;
9. clear exceptions: tensors, dicts, ``simulate`` beyond its storage budget, a step before the first reset;
10. the work budget: settings whose step or batch exceeds it are refused at ``make`` (and at ``set_attr``).
"""

from __future__ import annotations

import collections
import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mbs_envs
from mbs_envs.dynamics.simulate import MAX_STORED_VALUES, simulate
from mbs_envs.envs import budget as envbase
from mbs_envs.envs.registry import SCENES
from mbs_envs.envs.sb3 import make_sb3_vec_env
from mbs_envs.models.planar2r import Planar2R
from mbs_envs.models.serial_chain import SerialChain
from mbs_envs.studies.evaluation import make_controller
from tests.budget import examples

CASES: collections.Counter = collections.Counter()
IDS = list(mbs_envs.ENV_IDS)
KW = {"mbs_envs/SerialChain-v0": {"n_links": 4}}
FAST = settings(deadline=None, suppress_health_check=list(HealthCheck))


@pytest.fixture(scope="module", autouse=True)
def _report_case_counts():
    yield
    print("\nissue 34 generated cases:", dict(CASES))


def make(env_id: str, **kw) -> gym.Env:
    return gym.make(env_id, **{**KW.get(env_id, {}), **kw})


def make_vec(env_id: str, n: int = 3, **kw):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **{**KW.get(env_id, {}), **kw})


def three_routes(env_id: str) -> tuple:
    """The single env (unwrapped), the batched vector env and the SB3 adapter of ``env_id``, each reset."""
    single = make(env_id).unwrapped
    single.reset(seed=0)
    venv = make_vec(env_id)
    venv.reset(seed=0)
    sb3 = make_sb3_vec_env(env_id, n_envs=2, seed=0, **KW.get(env_id, {}))
    sb3.reset()
    return single, venv, sb3


def snapshot(env) -> tuple:
    """Everything a refused call must leave as it was: state, time, and the generators' states."""
    u = env.unwrapped
    rngs = [g.bit_generator.state for g in u._rngs] if hasattr(u, "_rngs") else [u.np_random.bit_generator.state]
    return (np.array(u._q, copy=True), np.array(u._v, copy=True), np.array(u._t, copy=True), repr(rngs))


def same(a: tuple, b: tuple) -> bool:
    return all(np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(a, b))


# -- 1. the model is fixed -----------------------------------------------------------------------

OTHER_MODELS = [Planar2R(), SerialChain(n_links=2), SerialChain(n_links=4), SerialChain(n_links=40), None, "model"]


@pytest.mark.parametrize("env_id", IDS)
def test_1_the_model_cannot_be_swapped_by_any_route(env_id):
    single, venv, sb3 = three_routes(env_id)
    for other in OTHER_MODELS + [single.model]:
        for route in ("single", "vector attribute", "vector set_attr", "sb3 set_attr"):
            CASES["1 model swap"] += 1
            target = {"single": single, "vector attribute": venv.unwrapped}.get(route)
            before = single.model if route == "single" else venv.unwrapped.model
            with pytest.raises(ValueError, match="model"):
                if target is not None:
                    target.model = other
                elif route == "vector set_attr":
                    venv.unwrapped.set_attr("model", other)
                else:
                    sb3.set_attr("model", other)
            assert (single.model if route == "single" else venv.unwrapped.model) is before
    single.step(np.zeros(single.action_space.shape))
    venv.step(np.zeros(venv.action_space.shape))
    sb3.step(np.zeros((2,) + sb3.action_space.shape))


# -- 2. copies of vector envs --------------------------------------------------------------------


@settings(FAST, max_examples=examples(40))
@given(env_id=st.sampled_from(IDS), compiled=st.booleans(), steps=st.integers(0, 12), how=st.sampled_from(["deepcopy", "pickle"]),
       seed=st.integers(0, 2**31))  # fmt: skip
def test_2_copies_of_a_vector_env_mid_episode_step_as_the_original(env_id, compiled, steps, how, seed):
    CASES["2 vector copies"] += 1
    v = (
        make_vec(env_id, compiled=compiled, max_episode_steps=5)
        if env_id != "mbs_envs/RollingDisk-v0"
        else make_vec(env_id, max_episode_steps=5)
    )
    v.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        v.step(rng.uniform(-1, 1, v.action_space.shape))
    w = copy.deepcopy(v) if how == "deepcopy" else pickle.loads(pickle.dumps(v))
    for k in range(8):
        a = rng.uniform(-1, 1, v.action_space.shape)
        ov, rv, *_ = v.step(a)
        ow, rw, *_ = w.step(a)
        np.testing.assert_array_equal(ov, ow)
        np.testing.assert_array_equal(rv, rw)
        if k == 3:
            np.testing.assert_array_equal(v.reset(seed=seed + 1)[0], w.reset(seed=seed + 1)[0])


# -- 3. refusals change nothing ------------------------------------------------------------------

BAD_OPTIONS = [{"q": [1e9] * 8}, {"q": "x"}, {"bogus": 1}, {"v": [np.nan] * 8}, {"q": {0: 1}}, {"reset_mask": "yes"}]


@pytest.mark.parametrize("env_id", IDS)
def test_3_refused_resets_leave_state_and_generators_as_they_were(env_id):
    nq = make(env_id).unwrapped.model.nq
    bad_options = [dict(o) for o in BAD_OPTIONS]
    for o in bad_options:
        for k in ("q", "v"):
            if isinstance(o.get(k), list):
                o[k] = o[k][:nq]
    for kind in ("single", "vector"):
        for options in bad_options:
            for seed in (None, 5, [1, 2, 3], 1.5, -1):
                env, twin = (make(env_id), make(env_id)) if kind == "single" else (make_vec(env_id), make_vec(env_id))
                env.reset(seed=0)
                twin.reset(seed=0)
                if kind == "single" and "reset_mask" in options:
                    options = {"q": "x"}
                before = snapshot(env)
                CASES["3 refused reset"] += 1
                with pytest.raises(ValueError):
                    env.reset(seed=seed, options=options)
                assert same(snapshot(env), before)
                a = np.zeros(env.action_space.shape)
                np.testing.assert_array_equal(env.step(a)[0], twin.step(a)[0])
                np.testing.assert_array_equal(env.reset()[0], twin.reset()[0])  # the generator was untouched


@pytest.mark.parametrize("env_id", IDS)
def test_3_a_vector_seed_list_with_one_bad_seed_reseeds_no_member(env_id):
    for bad in ([0, -1, 2], [0, 1.0, 2], [0, "1", 2], [0, 1], [0, 1, 2, 3], [None, True, 2]):
        CASES["3 refused seed list"] += 1
        v, twin = make_vec(env_id), make_vec(env_id)
        v.reset(seed=10)
        twin.reset(seed=10)
        with pytest.raises(ValueError, match="seed"):
            v.reset(seed=bad)
        np.testing.assert_array_equal(v.reset()[0], twin.reset()[0])


# -- 4. one seed rule ----------------------------------------------------------------------------

BAD_SEEDS = st.one_of(
    st.floats(allow_nan=True),
    st.integers(max_value=-1),
    st.text(max_size=3),
    st.booleans(),
    st.just(2**128),
    st.sampled_from([np.float64(1.0), np.bool_(True), 1j, b"1", object()]),
)


@settings(FAST, max_examples=examples(80))
@given(env_id=st.sampled_from(IDS), bad=BAD_SEEDS)
def test_4_a_bad_seed_is_a_value_error_naming_seed_everywhere(env_id, bad):
    CASES["4 bad seeds"] += 1
    with pytest.raises(ValueError, match="seed"):
        make(env_id).reset(seed=bad)
    v = make_vec(env_id)
    with pytest.raises(ValueError, match="seed"):
        v.reset(seed=bad)
    with pytest.raises(ValueError, match="seed"):
        v.reset(seed=[0, bad, 2])
    with pytest.raises(ValueError, match="seed"):
        make_sb3_vec_env(env_id, n_envs=2, **KW.get(env_id, {})).seed(bad)


@pytest.mark.parametrize("seed", [0, np.int64(7), np.uint32(9), 2**70, 2**128 - 5])
def test_4_good_seeds_give_member_i_the_single_env_seeded_seed_plus_i(seed):
    CASES["4 good seeds"] += 1
    v = make_vec("mbs_envs/Planar2R-v0")
    obs, _ = v.reset(seed=seed)
    for i in range(3):
        np.testing.assert_array_equal(obs[i], make("mbs_envs/Planar2R-v0").reset(seed=int(seed) + i)[0])


# -- 5. autoreset info ---------------------------------------------------------------------------


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("env_id", IDS)
def test_5_next_step_autoreset_info_equals_sync_vector_env(env_id, compiled):
    kw = {} if env_id == "mbs_envs/RollingDisk-v0" else {"compiled": compiled}
    n, steps = 3, 4
    ours = make_vec(env_id, n, max_episode_steps=steps, **kw)
    sync = gym.vector.SyncVectorEnv([lambda: make(env_id, max_episode_steps=steps, **kw)] * n)
    ours.reset(seed=3)
    sync.reset(seed=3)
    rng = np.random.default_rng(0)
    for k in range(3 * steps + 2):
        a = rng.uniform(-1, 1, ours.action_space.shape)
        o1, r1, te1, tr1, i1 = ours.step(a)
        o2, r2, te2, tr2, i2 = sync.step(a)
        np.testing.assert_allclose(o1, o2, rtol=0, atol=1e-5)
        for key in [key for key in i2 if not key.startswith("_")]:
            CASES["5 autoreset info entries"] += 1
            m = i2["_" + key]
            np.testing.assert_array_equal(i1["_" + key], m, err_msg=key)
            np.testing.assert_allclose(np.asarray(i1[key], float)[m], np.asarray(i2[key], float)[m], rtol=1e-9, atol=1e-9,
                                       err_msg=f"{key} at step {k}")  # fmt: skip


@pytest.mark.parametrize("env_id", IDS)
def test_5_the_ignored_action_of_a_member_being_reset_may_be_nan(env_id):
    v = make_vec(env_id, 2, max_episode_steps=1)
    v.reset(seed=0)
    v.step(np.zeros(v.action_space.shape))
    a = np.full(v.action_space.shape, np.nan)
    CASES["5 nan action on reset"] += 1
    obs, *_ = v.step(a)  # both members are being reset: their actions are ignored
    assert np.all(np.isfinite(obs))
    with pytest.raises(ValueError, match="finite"):
        v.step(a)  # now they act: refused


# -- 6. non-finite values ------------------------------------------------------------------------

CONTROLLERS = [(sc.id, dict(sc.kwargs), name, spec) for sc in SCENES for name, spec in sc.controllers.items()]


@settings(FAST, max_examples=examples(120))
@given(case=st.sampled_from(CONTROLLERS), data=st.data())
def test_6_finite_observations_give_finite_actions_and_nan_is_refused(case, data):
    env_id, kw, _, spec = case
    env = gym.make(env_id, **kw)
    controller = make_controller(spec, env)
    dim = env.observation_space.shape[0]
    obs = np.array(data.draw(st.lists(st.one_of(st.floats(-1e300, 1e300), st.sampled_from([0.0, 1e30, -1e30, 5e-324])),
                                      min_size=dim, max_size=dim)))  # fmt: skip
    CASES["6 controller observations"] += 1
    if data.draw(st.booleans()):  # float32 observations, as the envs give them (inside float32's range)
        obs = np.clip(obs, -3e38, 3e38).astype(np.float32)
    action, _ = controller.predict(obs)
    assert np.all(np.isfinite(action)) and np.all(np.abs(action) <= 1)
    obs[data.draw(st.integers(0, dim - 1))] = data.draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    with pytest.raises(ValueError, match="observation"):
        controller.predict(obs)


@pytest.mark.parametrize("g", [0.0, -9.81, 1e-320, 1e-300])
def test_6_the_disk_task_without_gravity_is_refused(g):
    CASES["6 disk gravity"] += 1
    with pytest.raises(ValueError, match="g"):
        gym.make("mbs_envs/RollingDisk-v0", params={"g": g})


# -- 7. settings ---------------------------------------------------------------------------------

WILD = [np.nan, np.inf, -1.0, 0.0, "0.01", None, True, 1j, [1.0, 2.0, 3.0, 4.0, 5.0], {"a": 1}, 1e300, -(10**30)]


@pytest.mark.parametrize("env_id", IDS)
def test_7_every_setting_is_validated_by_every_route(env_id):
    single, venv, sb3 = three_routes(env_id)
    names = single.settings()
    assert {"dt", "substeps", "u_max"} <= set(names)
    for name in names:
        for value in WILD:
            for route in ("attribute", "vector set_attr", "sb3 set_attr"):
                env = (
                    single
                    if route == "attribute"
                    else venv.unwrapped.env
                    if route == "vector set_attr"
                    else sb3.venv.venv.env
                )
                before = copy.deepcopy(getattr(env, name))
                try:
                    if route == "attribute":
                        setattr(env, name, value)
                    elif route == "vector set_attr":
                        venv.unwrapped.set_attr(name, value)
                    else:
                        sb3.set_attr(name, value)
                except ValueError:
                    CASES["7 refused settings"] += 1
                    after = getattr(env, name)
                    assert type(after) is type(before) and np.array_equal(
                        np.asarray(after, dtype=object), np.asarray(before, dtype=object)
                    )
                    continue
                CASES["7 accepted settings"] += 1
                setattr(env, name, before)  # accepted: a valid value (e.g. 1e300 for a limit); put it back
    for env in (single, venv.unwrapped.env):
        for name in names:
            value = getattr(env, name)
            if isinstance(value, np.ndarray):
                CASES["7 read-only arrays"] += 1
                with pytest.raises(ValueError, match="read-only"):
                    value[...] = -40.0
    for name in (
        "max_episode_steps",
        "n_links",
        "dtt",
        "model",
        "divergence_limit",
        "integrator",
        "_q",
        "np_random",
        3,
    ):
        CASES["7 names that are not settings"] += 1
        with pytest.raises(ValueError):
            venv.unwrapped.set_attr(name, 5)
        with pytest.raises(ValueError):
            sb3.set_attr(name, 5)
    single.step(np.zeros(single.action_space.shape))
    venv.step(np.zeros(venv.action_space.shape))


@pytest.mark.parametrize("value", ["False", "True", 0, 1, None, np.array(True), 1.0])
def test_7_compiled_is_a_bool(value):
    CASES["7 compiled"] += 1
    with pytest.raises(ValueError, match="compiled"):
        gym.make("mbs_envs/Planar2R-v0", compiled=value)


def test_7_per_member_values_of_a_shared_setting_are_refused():
    v = make_vec("mbs_envs/Planar2R-v0")
    v.unwrapped.set_attr("dt", [0.02] * 3)
    assert v.unwrapped.env.dt == 0.02
    with pytest.raises(ValueError, match="share"):
        v.unwrapped.set_attr("dt", [0.02, 0.03, 0.02])
    assert v.unwrapped.get_attr("dt") == (0.02,) * 3


# -- 8. numeric inputs ---------------------------------------------------------------------------

NOT_REALS = [["1", "0.5"], [True, False], [1 + 2j, 0.0], np.ma.array([1.0, 2.0], mask=[True, False]), {0: 1}, [None, 1.0],
             np.array(["a", "b"]), [b"1", b"2"], [[1.0], [2.0, 3.0]], object(), {1.0, 2.0}]  # fmt: skip


@pytest.mark.parametrize("value", NOT_REALS, ids=range(len(NOT_REALS)))
def test_8_non_real_states_are_refused_naming_the_argument(value):
    env = make("mbs_envs/Planar2R-v0")
    env.reset(seed=0)
    before = snapshot(env)
    for key in ("q", "v"):
        CASES["8 reset options"] += 1
        with pytest.raises(ValueError, match=key):
            env.reset(options={key: value})
        assert same(snapshot(env), before)
    model = Planar2R()
    for name, call in (("q0", lambda: simulate(model, value, [0.0, 0.0], 0.01)), ("v0", lambda: simulate(model, [0.0, 0.0], value, 0.01)),
                       ("u", lambda: simulate(model, [0.0, 0.0], [0.0, 0.0], 0.01, u=lambda t, q, v: value))):  # fmt: skip
        CASES["8 simulate"] += 1
        with pytest.raises(ValueError, match=name):
            call()


@pytest.mark.parametrize("mask", [["a", ""], [np.nan, 0.0], [0.5, 1.0], "yes", [True], [[True, False]], None])
def test_8_reset_masks_are_booleans(mask):
    v = make_vec("mbs_envs/Planar2R-v0", 2)
    v.reset(seed=0)
    before = snapshot(v)
    CASES["8 reset masks"] += 1
    if mask is None:
        v.reset(options={"reset_mask": mask})  # None: every member (the option left out)
        return
    with pytest.raises(ValueError, match="reset_mask"):
        v.reset(options={"reset_mask": mask})
    assert same(snapshot(v), before)


def test_8_a_masked_array_without_masked_entries_is_its_data():
    env = make("mbs_envs/Planar2R-v0")
    obs, _ = env.reset(options={"q": np.ma.array([0.1, 0.2])})
    np.testing.assert_array_equal(env.unwrapped.q, [0.1, 0.2])


# -- 9. exceptions that say what is wrong --------------------------------------------------------


def test_9_tensors_that_require_grad_are_refused_clearly():
    torch = pytest.importorskip("torch", reason="the rl extra (torch) is not installed")
    CASES["9 tensors"] += 1
    with pytest.raises(ValueError, match="q"):
        make("mbs_envs/Planar2R-v0").reset(options={"q": torch.zeros(2, requires_grad=True)})


@pytest.mark.parametrize("t_final, dt", [(1e300, 1e-300), (1e15, 1.0), (1e6, 1e-6), (1.0, 5e-324)])
def test_9_simulate_beyond_its_storage_budget_is_a_value_error(t_final, dt):
    CASES["9 simulate budget"] += 1
    with pytest.raises(ValueError, match="budget"):
        simulate(Planar2R(), [0.0, 0.0], [0.0, 0.0], t_final, dt)
    assert MAX_STORED_VALUES == 2**28


@pytest.mark.parametrize("env_id", IDS)
def test_9_an_unwrapped_env_stepped_or_rendered_before_reset_says_so(env_id):
    CASES["9 before reset"] += 2
    env = make(env_id, render_mode="rgb_array").unwrapped
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(env.action_space.shape))
    with pytest.raises(gym.error.ResetNeeded):
        env.render()
    env.reset(seed=0)
    env.step(np.zeros(env.action_space.shape))


# -- 10. the work budget -------------------------------------------------------------------------


@settings(FAST, max_examples=examples(40))
@given(env_id=st.sampled_from(IDS), integrator=st.sampled_from(["rk4", "sdirk3", "implicit_euler", "midpoint"]),
       substeps=st.sampled_from([1, 10, 1000, 10**4, 10**5]))  # fmt: skip
def test_10_a_step_beyond_the_work_budget_is_refused_at_make(env_id, integrator, substeps):
    CASES["10 step budget"] += 1
    probe = make(env_id).unwrapped
    integ = mbs_envs.integrators.get(integrator)
    work = envbase.step_work(integ, substeps, probe.model.nv)
    if work > envbase.STEP_WORK_BUDGET:
        with pytest.raises(ValueError, match="budget"):
            make(env_id, integrator=integrator, substeps=substeps)
        if integrator == "rk4":  # a later assignment is checked too (the integrator is fixed at construction)
            with pytest.raises(ValueError, match="budget"):
                probe.substeps = substeps
            assert probe.substeps == 1
    else:
        make(env_id, integrator=integrator, substeps=substeps)


def test_10_a_batch_beyond_the_budget_is_refused_before_allocating():
    CASES["10 batch budget"] += 3
    with pytest.raises(ValueError, match="budget"):
        make_vec("mbs_envs/Planar2R-v0", envbase.MAX_MEMBERS + 1)
    with pytest.raises(ValueError, match="budget"):
        make_vec("mbs_envs/Planar2R-v0", 10**7)
    v = make_vec("mbs_envs/Planar2R-v0", 100_000)
    before = v.unwrapped.env.substeps
    with pytest.raises(ValueError, match="budget"):
        v.unwrapped.set_attr("substeps", 100_000)  # 1e5 members x 8e5: beyond the batch budget
    assert v.unwrapped.env.substeps == before


# -- the soak's adversarial part finds these classes ----------------------------------------------


def test_the_adversarial_soak_is_clean_now_and_finds_a_refusal_that_reseeds(monkeypatch):
    from mbs_envs.envs.vector import MBSVectorEnv
    from mbs_envs.studies.reliability import adversarial_soak

    clean = adversarial_soak("mbs_envs/Planar2R-v0", rounds=80, seed=1)
    assert clean["refused"] > 10
    assert (
        clean["accepted_bad"] == clean["changed_by_refusal"] == clean["disagreements"] == clean["other_exceptions"] == 0
    )
    original = MBSVectorEnv._member_generators

    def reseeds_first(self, seed):  # class 3 as it was: members reseeded before the seeds were all checked
        try:
            return original(self, seed)
        except ValueError:
            self._rngs[0] = np.random.default_rng(0)
            raise

    monkeypatch.setattr(MBSVectorEnv, "_member_generators", reseeds_first)
    broken = adversarial_soak("mbs_envs/Planar2R-v0", rounds=80, seed=1)
    assert broken["changed_by_refusal"] > 0
