"""Starts drawn ahead (:mod:`mbs_envs.envs.lookahead`): the vector env's autoresets take starts drawn in
batches, and nothing observable changes. Checked against an independent reference, one single env per
member reset by hand as Gymnasium's next-step autoreset does, through random sequences of the calls that
could make an early draw wrong: episodes ending, resets with and without seeds and masks, reset options,
settings changed mid-run, deep copies and pickles; and against ``draw_ahead=False`` for starts the task
refuses (the same step raises the same error and leaves the same state)."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import gymnasium.utils.seeding
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import mbs_envs
from mbs_envs.envs.lookahead import NONE, READY

from ..budget import examples

IDS = list(mbs_envs.ENV_IDS)
KW = {"mbs_envs/SerialChain-v0": {"n_links": 4}, "mbs_envs/SpatialChain-v0": {"n_links": 3}}
N = 5
EPISODE = 6  # short episodes: many autoresets


def start_setting(env) -> tuple[str, list]:
    """A setting the starts depend on, and values to set it to."""
    if "start_noise" in env.settings():
        return "start_noise", [0.02, 0.05, env.start_noise]
    return "lean_limit", [0.5, 0.55, env.lean_limit]  # the disk: ends episodes sooner or later (its starts' check)


def consistent(ahead) -> None:
    assert ahead.n_none == int(np.count_nonzero(ahead.status == NONE))
    assert all((b is not None) == (s == READY) for b, s in zip(ahead.before, ahead.status))


ops = st.lists(
    st.sampled_from(["step"] * 8 + ["seed", "mask", "seed mask", "options", "setting", "deepcopy", "pickle"]),
    min_size=10,
    max_size=60,
)


@pytest.mark.parametrize("env_id", IDS)
@settings(deadline=None, max_examples=examples(9), suppress_health_check=list(HealthCheck))
@given(calls=ops, seed=st.integers(0, 2**31))
def test_autoresets_from_starts_drawn_ahead_are_the_single_envs_resets(env_id, calls, seed):
    kw = KW.get(env_id, {})
    venv = gym.make_vec(
        env_id, num_envs=N, vectorization_mode="vector_entry_point", max_episode_steps=EPISODE, **kw
    ).unwrapped
    singles = [gym.make(env_id, max_episode_steps=EPISODE, **kw) for _ in range(N)]
    rng = np.random.default_rng(seed)
    obs, _ = venv.reset(seed=seed)
    ref = np.stack([e.reset(seed=seed + i)[0] for i, e in enumerate(singles)])
    done = np.zeros(N, bool)
    name, values = start_setting(singles[0].unwrapped)
    resets = 0
    for call in calls:
        if call == "step":
            a = rng.uniform(-1.2, 1.2, venv.action_space.shape)
            obs, r, term, trunc, _ = venv.step(a)
            out = [e.reset() + (0.0, False, False) if done[i] else e.step(a[i]) for i, e in enumerate(singles)]
            resets += int(done.sum())
            ref = np.stack([o[0] for o in out])
            r_ref = np.array([o[1] if not done[i] else 0.0 for i, o in enumerate(out)])
            t_ref = np.array([o[2] if not done[i] else False for i, o in enumerate(out)])
            done = term | trunc
            np.testing.assert_allclose(r, r_ref, rtol=0, atol=1e-12)
            assert np.array_equal(term, t_ref)
        elif call == "seed":
            s = int(rng.integers(0, 2**31))
            obs, _ = venv.reset(seed=s)
            ref = np.stack([e.reset(seed=s + i)[0] for i, e in enumerate(singles)])
            done[:] = False
        elif call == "seed mask":  # every member gets a new generator, the masked ones are reset: the others run on
            s, mask = int(rng.integers(0, 2**31)), rng.random(N) < 0.5
            obs, _ = venv.reset(seed=s, options={"reset_mask": mask})
            for i, e in enumerate(singles):
                if mask[i]:
                    ref[i] = e.reset(seed=s + i)[0]
                else:  # what reset(seed=s + i) seeds, for its next reset
                    e.unwrapped.np_random = gym.utils.seeding.np_random(s + i)[0]
            done[mask] = False
        elif call in ("mask", "options"):
            mask = rng.random(N) < 0.5
            options = {"reset_mask": mask}
            if call == "options":  # a start given for those members: no start is drawn for them
                options["q"] = singles[0].unwrapped.sample_start({}, np.random.default_rng(seed))[1]
            obs, _ = venv.reset(options=options)
            for i in np.flatnonzero(mask):
                ref[i] = singles[i].reset(options={k: x for k, x in options.items() if k != "reset_mask"})[0]
            done[mask] = False
        elif call == "setting":
            value = values[int(rng.integers(len(values)))]
            venv.set_attr(name, value)
            for e in singles:
                e.unwrapped.set_setting(name, value)
        else:
            venv = copy.deepcopy(venv) if call == "deepcopy" else pickle.loads(pickle.dumps(venv))
        np.testing.assert_allclose(obs, ref, rtol=0, atol=1e-12)
        consistent(venv._ahead)
    assert venv._ahead.taken == resets  # every autoreset took a start drawn ahead (none is refused here)


@pytest.mark.parametrize("env_id", ["mbs_envs/RollingDisk-v0", "mbs_envs/Planar2R-v0", "mbs_envs/Acrobot-v1"])
def test_most_autoresets_are_served_from_batches_and_equal_drawing_at_the_reset(env_id):
    """A long run with many episode ends: ``draw_ahead`` True and False give the same observations, every
    autoreset takes a start drawn ahead, and those are drawn in batches of many members."""
    make = lambda ahead: gym.make_vec(env_id, num_envs=64, vectorization_mode="vector_entry_point", max_episode_steps=7,  # noqa: E731
                                      full_info=False, draw_ahead=ahead).unwrapped  # fmt: skip
    fast, slow = make(True), make(False)
    fills = []
    fill = type(fast._ahead).fill
    fast._ahead.fill = lambda venv, members: (fills.append(len(members)), fill(fast._ahead, venv, members))[1]
    assert np.array_equal(fast.reset(seed=3)[0], slow.reset(seed=3)[0])
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(120):
        a = rng.uniform(-1, 1, fast.action_space.shape)
        of, rf, tf, uf, _ = fast.step(a)
        os_, rs, ts, us, _ = slow.step(a)
        assert np.array_equal(of, os_) and np.array_equal(rf, rs) and np.array_equal(tf, ts) and np.array_equal(uf, us)
        ends += int((tf | uf).sum())
    assert fast._ahead.taken == ends - int((tf | uf).sum()) > 100  # every autoreset (the last step's are still to come)
    assert np.mean(fills) >= 16, fills  # drawn in batches


def logical_states(venv) -> list:
    """The members' generator states as without the lookahead (a member with a start ahead: from before its draws)."""
    ahead = venv._ahead
    return [ahead.before[i] if ahead.status[i] == READY else g.bit_generator.state for i, g in enumerate(venv._rngs)]


def refuse_when(threshold: float):
    """A task that refuses the starts whose first coordinate exceeds ``threshold`` (as a task refuses a
    start it cannot begin from: ``ValueError`` from its check)."""

    def check(self, q0, v0, task, given):
        bad = np.asarray(q0)[..., 0] > threshold
        if np.any(bad):
            raise ValueError(f"a sampled start state (q = {np.asarray(q0)[np.argmax(bad)].tolist()}) is refused")
        return type(self)._check_start(self, q0, v0, task, given)

    return check


@pytest.mark.parametrize("env_id", ["mbs_envs/Planar2R-v0", "mbs_envs/Acrobot-v1"])
def test_a_start_the_task_refuses_raises_at_the_same_step_as_without_drawing_ahead(env_id):
    envs = [gym.make_vec(env_id, num_envs=6, vectorization_mode="vector_entry_point", max_episode_steps=4, draw_ahead=ahead).unwrapped
            for ahead in (True, False)]  # fmt: skip
    for venv in envs:
        venv.reset(seed=1)
    q_first = [venv.q[:, 0].copy() for venv in envs]
    assert np.array_equal(*q_first)
    threshold = float(
        np.quantile(
            np.concatenate([envs[0].env.sample_start({}, np.random.default_rng(s))[1][:1] for s in range(40)]), 0.8
        )
    )
    for venv in envs:  # from now on, about a fifth of the starts are refused
        venv.env._check_start = refuse_when(threshold).__get__(venv.env)
    rng = np.random.default_rng(5)
    raised = [0, 0]
    for _ in range(40):
        a = rng.uniform(-1, 1, envs[0].action_space.shape)
        results = []
        for k, venv in enumerate(envs):
            try:
                results.append(venv.step(a)[0])
            except ValueError as e:
                raised[k] += 1
                results.append(str(e))
        assert type(results[0]) is type(results[1])
        if isinstance(results[0], str):
            assert results[0] == results[1]
        else:
            assert np.array_equal(results[0], results[1])
        assert np.array_equal(envs[0]._qc, envs[1]._qc) and np.array_equal(envs[0]._t, envs[1]._t)
        assert logical_states(envs[0]) == logical_states(envs[1])
        consistent(envs[0]._ahead)
    assert raised[0] == raised[1] > 0


def test_draw_ahead_is_validated():
    with pytest.raises(ValueError, match="draw_ahead"):
        gym.make_vec("mbs_envs/Planar2R-v0", num_envs=2, vectorization_mode="vector_entry_point", draw_ahead="yes")


def test_a_large_batch_draws_ahead_at_most_a_bounded_number_of_starts_per_call(monkeypatch):
    """``StartsAhead.MOST`` bounds one call's draws (a batch of a million members must not draw a million starts at
    its first autoreset); the members an autoreset needs are always among them, and the starts stay the single envs'."""
    from mbs_envs.envs.lookahead import NONE, READY, StartsAhead

    monkeypatch.setattr(StartsAhead, "MOST", 8)
    monkeypatch.setattr(StartsAhead, "BATCH", 4)
    venv = gym.make_vec(
        "mbs_envs/Acrobot-v1", num_envs=40, vectorization_mode="vector_entry_point", max_episode_steps=3
    ).unwrapped
    venv.reset(seed=2)
    ahead = venv._ahead
    assert ahead.ready(venv, np.array([33])).all()  # needed, and 7 others
    assert np.count_nonzero(ahead.status == READY) == 8 and ahead.status[33] == READY
    ahead.top_up(venv)  # 32 without: at most 8 more
    assert np.count_nonzero(ahead.status == READY) == 16
    needed = np.arange(20, 40)  # more than MOST needed at once: all of them
    assert ahead.ready(venv, needed).all() and np.count_nonzero(ahead.status == NONE) == 40 - 16 - 19  # 33 was ready
    consistent(ahead)
    singles = [gym.make("mbs_envs/Acrobot-v1", max_episode_steps=3) for _ in range(40)]
    for i, e in enumerate(singles):
        e.reset(seed=2 + i)
    rng = np.random.default_rng(1)
    done = np.zeros(40, bool)
    for _ in range(10):  # every member truncates at once: each autoreset needs 40 starts
        a = rng.uniform(-1, 1, venv.action_space.shape)
        obs, _, term, trunc, _ = venv.step(a)
        ref = [e.reset()[0] if done[i] else e.step(a[i])[0] for i, e in enumerate(singles)]
        np.testing.assert_allclose(obs, np.stack(ref), rtol=0, atol=1e-12)
        done = term | trunc
        consistent(ahead)


@pytest.mark.parametrize(
    "kw", [{"randomize": {"m2": 0.3, "l1": 0.2}}, {"member_params": [{"m2": 0.8 + 0.1 * i} for i in range(6)]}]
)
def test_randomized_members_draw_their_parameters_ahead_with_their_starts(kw):
    """Domain randomization draws each member's parameters first at a reset (its start may depend on them): drawn
    ahead, the parameters come with the start, and the run equals the one that draws at the autoreset."""
    make = lambda ahead: gym.make_vec("mbs_envs/Planar2R-v0", num_envs=6, vectorization_mode="vector_entry_point",  # noqa: E731
                                      max_episode_steps=5, draw_ahead=ahead, **kw).unwrapped  # fmt: skip
    fast, slow = make(True), make(False)
    fast.reset(seed=9)
    slow.reset(seed=9)
    rng = np.random.default_rng(2)
    for _ in range(40):
        a = rng.uniform(-1, 1, fast.action_space.shape)
        assert np.array_equal(fast.step(a)[0], slow.step(a)[0])
        assert np.array_equal(fast.model.params.m2, slow.model.params.m2)
    assert fast._ahead.taken > 30
