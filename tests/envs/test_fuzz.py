"""Stateful fuzzing of every registered env (Hypothesis ``RuleBasedStateMachine``).

Random sequences of reset (with seeds), step (valid, out-of-range and invalid
actions), pickle and deepcopy round trips and close. Invariants: observations
and rewards are always finite; invalid actions raise ``ValueError`` and change
nothing; out-of-range actions act exactly like their saturation; and the whole
episode so far replays identically in a fresh env from its seed.
"""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, precondition, rule

import mbs_envs

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
        max_examples=8, stateful_step_count=12, deadline=None, suppress_health_check=[HealthCheck.too_slow]
    )
    return EnvMachine


for _id in mbs_envs.ENV_IDS:
    _name = "Test" + _id.split("/")[-1].replace("-", "_")
    globals()[_name] = machine_for(_id).TestCase
