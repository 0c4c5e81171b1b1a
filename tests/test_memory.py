"""glibc's malloc keeps a batched step's freed work arrays (mbs_envs.dynamics.memory)."""

from __future__ import annotations

import resource
import sys

import gymnasium as gym
import numpy as np
import pytest

from mbs_envs.dynamics import memory


def test_the_setting_applies_to_glibc_on_linux_unless_switched_off():
    assert memory.wanted({}, "linux", "glibc")
    assert memory.wanted({memory.ENV_VAR: "1"}, "linux", "glibc")
    assert not memory.wanted({memory.ENV_VAR: "0"}, "linux", "glibc")
    assert not memory.wanted({memory.ENV_VAR: " 0 "}, "linux", "glibc")
    assert not memory.wanted({}, "linux", "")  # musl, or no C library python could name
    assert not memory.wanted({}, "darwin", "")
    assert not memory.wanted({}, "win32", "")


@pytest.mark.skipif(
    not memory.wanted({}, sys.platform, __import__("platform").libc_ver()[0]), reason="glibc on Linux only"
)
def test_a_large_batched_step_faults_in_no_memory_once_a_vector_env_exists():
    """Without the setting a fresh process stepping 2048 ten-link chains faulted in 488 pages per step
    (glibc returned the step's work arrays to the OS each time; docs/performance.md); with it, none."""
    venv = gym.make_vec(
        "mbs_envs/SerialChain-v0", num_envs=2048, vectorization_mode="vector_entry_point", full_info=False
    )
    assert memory.keep_freed_memory()  # applied by the vector env, once per process
    venv.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (8, 2048, 10))
    for a in actions[:3]:  # the first steps take the heap the later ones reuse
        venv.step(a)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for a in actions[3:]:
        venv.step(a)
    per_step = (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / 5
    assert per_step < 20
