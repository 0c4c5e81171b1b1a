"""Actions of every real dtype and byte order are converted; anything else is refused and changes nothing."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mbs_envs  # noqa: F401

REAL_DTYPES = ["<f2", ">f2", "<f4", ">f4", "<f8", ">f8", "i1", ">i2", "<i4", ">i8", "u1", ">u2", "?", np.longdouble]


@settings(max_examples=40, deadline=None)
@given(
    dtype=st.sampled_from(REAL_DTYPES), values=st.lists(st.floats(-3, 3), min_size=2, max_size=2), vector=st.booleans()
)
def test_real_dtypes_and_byte_orders_step_like_float64(dtype, values, vector):
    a = np.array(values).astype(dtype)
    a64 = a.astype(np.float64)
    if vector:
        envs = [
            gym.make_vec("mbs_envs/Planar2R-v0", num_envs=2, vectorization_mode="vector_entry_point") for _ in range(2)
        ]
        a, a64 = np.stack([a, a]), np.stack([a64, a64])
    else:
        envs = [gym.make("mbs_envs/Planar2R-v0") for _ in range(2)]
    for e in envs:
        e.reset(seed=3)
    obs, *_ = envs[0].step(a)
    ref, *_ = envs[1].step(a64)
    np.testing.assert_array_equal(obs, ref)


@pytest.mark.parametrize("action", [["0.1", "0.2"], np.array([1 + 1j, 0]), np.array(["2020-01-01", "2020-01-02"], "datetime64[D]"),
                                    "ab", np.array([0.1, "x"], dtype=object), [None, 1.0], np.array([1, 2], "timedelta64[s]")])  # fmt: skip
@pytest.mark.parametrize("env_id", ["mbs_envs/Planar2R-v0", "mbs_envs/RollingDisk-v0"])
def test_non_real_actions_are_refused_and_change_nothing(action, env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    q, v, t = env.unwrapped.q, env.unwrapped.v, env.unwrapped.t
    with pytest.raises(ValueError, match="real numbers|shape"):
        env.step(action)
    np.testing.assert_array_equal(env.unwrapped.q, q)
    np.testing.assert_array_equal(env.unwrapped.v, v)
    assert env.unwrapped.t == t
