"""Stateful fuzzing of every registered env (Hypothesis ``RuleBasedStateMachine``).

Random sequences of reset (with seeds), step (valid, out-of-range and invalid
actions), pickle and deepcopy round trips and close. Invariants: observations
and rewards are always finite; invalid actions raise ``ValueError`` and change
nothing; out-of-range actions act exactly like their saturation; and the whole
episode so far replays identically in a fresh env from its seed.

The batched vector env of every id has a machine of its own (issue 34): resets, steps with NaN
actions for the members being reset (ignored), deepcopy and pickle round trips mid-episode, valid
``set_attr``, and refused calls (bad options, seeds, masks, actions, ``set_attr`` of bad values or of
names that are not settings, a model swap), driven beside a twin that gets only the calls that must
act: after every rule the two agree bit for bit, and a refused call left state and generators as they were.
"""

from __future__ import annotations

import copy
import json
import pickle

import gymnasium as gym
import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule

import mbs_envs
from tests.budget import examples

KWARGS = {"mbs_envs/SerialChain-v0": {"n_links": 4}}


def machine_for(env_id: str):
    kwargs = KWARGS.get(env_id, {})
    nu = gym.make(env_id, **kwargs).action_space.shape[0]
    actions = st.lists(st.floats(-1, 1, allow_nan=False), min_size=nu, max_size=nu).map(np.array)
    wild = st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=nu, max_size=nu).map(np.array)

    class EnvMachine(RuleBasedStateMachine):
        @initialize(seed=st.integers(0, 2**31 - 1))
        def start(self, seed):
            self.env = gym.make(env_id, **kwargs)
            self.obs, _ = self.env.reset(seed=seed)
            self.seed, self.log, self.reward, self.done = seed, [], 0.0, False

        @rule(seed=st.integers(0, 2**31 - 1))
        def reset(self, seed):
            self.obs, _ = self.env.reset(seed=seed)
            self.seed, self.log, self.done = seed, [], False

        def _step(self, action):
            self.obs, self.reward, term, trunc, _ = self.env.step(action)
            self.log.append(np.clip(action, -1, 1))
            self.done = term or trunc

        @precondition(lambda self: not self.done)
        @rule(action=actions)
        def step(self, action):
            self._step(action)

        @precondition(lambda self: not self.done)
        @rule(action=wild)
        def step_out_of_range_saturates(self, action):
            twin = copy.deepcopy(self.env)
            expected = twin.step(np.clip(action, -1, 1))[0]
            self._step(action)
            np.testing.assert_array_equal(self.obs, expected)

        @precondition(lambda self: not self.done)
        @rule(kind=st.sampled_from(["nan", "inf", "short", "long", "text"]))
        def invalid_action_raises_and_changes_nothing(self, kind):
            base = self.env.unwrapped
            before = (base.q, base.v, base.t)
            bad = {"nan": np.full(nu, np.nan), "inf": np.full(nu, np.inf), "short": np.zeros(nu - 1) if nu > 1 else np.zeros((1, 2)),
                   "long": np.zeros(nu + 1), "text": ["a"] * nu}[kind]  # fmt: skip
            try:
                self.env.step(bad)
            except ValueError:
                pass
            else:
                raise AssertionError(f"action {kind} was accepted")
            np.testing.assert_array_equal(base.q, before[0])
            np.testing.assert_array_equal(base.v, before[1])
            assert base.t == before[2]

        @rule()
        def pickle_round_trip(self):
            self.env = pickle.loads(pickle.dumps(self.env))

        @rule()
        def deepcopy_round_trip(self):
            self.env = copy.deepcopy(self.env)

        @rule()
        def close_and_go_on(self):
            self.env.close()

        @invariant()
        def outputs_finite(self):
            assert np.all(np.isfinite(self.obs)) and np.isfinite(self.reward)

        @invariant()
        def episode_replays_identically(self):
            fresh = gym.make(env_id, **kwargs)
            obs, _ = fresh.reset(seed=self.seed)
            for a in self.log:
                obs = fresh.step(a)[0]
            np.testing.assert_array_equal(obs, self.obs)

    EnvMachine.TestCase.settings = settings(
        max_examples=examples(8), stateful_step_count=12, deadline=None, suppress_health_check=[HealthCheck.too_slow]
    )
    return EnvMachine


for _id in mbs_envs.ENV_IDS:
    _name = "Test" + _id.split("/")[-1].replace("-", "_")
    globals()[_name] = machine_for(_id).TestCase


# -- the batched vector env (issue 34): copies mid-episode, set_attr, refusals ------------------

#: calls that must be refused with ValueError and change nothing (vector env)
REFUSED = ["options q", "seed float", "seed list", "reset_mask", "action nan", "set_attr bad value", "set_attr not a setting",
           "model", "set_attr short list", "set_attr unequal list"]  # fmt: skip


def vector_machine_for(env_id: str):
    """A vector env driven beside a twin that gets only the calls that must act: after every rule both
    agree bit for bit (so a copy, a refused call or an ignored action that changed anything is found)."""
    kwargs = {**KWARGS.get(env_id, {}), "max_episode_steps": 6}
    n = 3
    probe = gym.make(env_id, **KWARGS.get(env_id, {})).unwrapped
    nu, nq = probe.action_space.shape[0], probe.model.nq
    settings_names = probe.settings()
    valid_dt = st.sampled_from([0.005, 0.01, 0.02])

    def make():
        return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs).unwrapped

    class VectorMachine(RuleBasedStateMachine):
        @initialize(seed=st.integers(0, 2**31 - 1))
        def start(self, seed):
            self.env, self.twin = make(), make()
            self.obs = self.env.reset(seed=seed)[0]
            self.obs_twin = self.twin.reset(seed=seed)[0]

        @rule(seed=st.integers(0, 2**31 - 1))
        def reset(self, seed):
            self.obs = self.env.reset(seed=seed)[0]
            self.obs_twin = self.twin.reset(seed=seed)[0]

        @rule(a=st.lists(st.floats(-2, 2), min_size=n * nu, max_size=n * nu), nan_on_reset=st.booleans())
        def step(self, a, nan_on_reset):
            a = np.array(a).reshape(n, nu)
            mine = a.copy()
            if nan_on_reset:
                mine[self.env._autoreset] = np.nan  # ignored: these members are being reset
            self.obs = self.env.step(mine)[0]
            self.obs_twin = self.twin.step(a)[0]

        @rule(how=st.sampled_from(["deepcopy", "pickle"]))
        def copy_mid_episode(self, how):
            self.env = copy.deepcopy(self.env) if how == "deepcopy" else pickle.loads(pickle.dumps(self.env))

        @rule(dt=valid_dt, per_member=st.booleans())
        def set_a_valid_setting(self, dt, per_member):
            """One value, or one per member (Gymnasium's rule): the same setting either way."""
            self.env.set_attr("dt", [dt] * n if per_member else dt)
            self.twin.set_attr("dt", dt)

        @rule(kind=st.sampled_from(REFUSED), name=st.sampled_from(settings_names),
              value=st.sampled_from([np.nan, -1.0, "1", None, 1j, [np.inf] * 9]))  # fmt: skip
        def refused_call_changes_nothing(self, kind, name, value):
            env = self.env
            before = (env._qc.copy(), env._vc.copy(), env._t.copy(), repr([g.bit_generator.state for g in env._rngs]),
                      {k: copy.deepcopy(getattr(env.env, k)) for k in settings_names})  # fmt: skip
            calls = {
                "options q": lambda: env.reset(options={"q": np.full(nq, 1e9)}),
                "seed float": lambda: env.reset(seed=1.5),
                "seed list": lambda: env.reset(seed=[0, -1, 2]),
                "reset_mask": lambda: env.reset(options={"reset_mask": [np.nan] * n}),
                "action nan": lambda: env.step(
                    np.where(env._autoreset[:, None], 0.0, np.nan) * np.ones((n, nu))
                    if not env._autoreset.all()
                    else "x"
                ),  # every member resetting: NaN would be ignored  # fmt: skip
                "set_attr bad value": lambda: env.set_attr(name, value),
                "set_attr not a setting": lambda: env.set_attr("max_episode_steps", 3),
                "model": lambda: setattr(env, "model", None),
                # a per-joint value as a list: one value per member by Gymnasium's rule, so refused where nu != n
                "set_attr short list": lambda: (
                    env.set_attr("u_max", [float(x) for x in env.env.u_max])
                    if nu != n
                    else env.set_attr("dt", [0.01] * (n - 1))
                ),  # fmt: skip
                "set_attr unequal list": lambda: env.set_attr("dt", [0.01] * (n - 1) + [0.02]),
            }
            try:
                calls[kind]()
            except ValueError:
                pass
            else:  # only a value that happens to be valid for that setting may pass (e.g. -1.0 for nothing here)
                assert kind == "set_attr bad value", f"{kind} was accepted"
                setattr(env.env, name, before[4][name])
                return
            assert (
                np.array_equal(env._qc, before[0])
                and np.array_equal(env._vc, before[1])
                and np.array_equal(env._t, before[2])
            )
            assert repr([g.bit_generator.state for g in env._rngs]) == before[3]

        @invariant()
        def agrees_with_its_twin(self):
            assert self.env.spec is None or json.loads(self.env.spec.to_json())["id"] == env_id  # serializable
            np.testing.assert_array_equal(self.obs, self.obs_twin)
            np.testing.assert_array_equal(self.env._qc, self.twin._qc)
            assert np.all(np.isfinite(self.obs))

    VectorMachine.TestCase.settings = settings(
        max_examples=examples(6), stateful_step_count=12, deadline=None, suppress_health_check=[HealthCheck.too_slow]
    )
    return VectorMachine


for _id in mbs_envs.ENV_IDS:
    _name = "TestVector" + _id.split("/")[-1].replace("-", "_")
    globals()[_name] = vector_machine_for(_id).TestCase
