"""Run by .ci/run inside a fresh virtual environment holding only the built wheel and its core dependencies:
every registered id makes, resets and steps; the documented core imports work; nothing generic is installed at
the top level of site-packages."""

import importlib.util
import sys

import gymnasium as gym
import numpy as np

import mbs_envs
from mbs_envs import simulate  # noqa: F401
from mbs_envs.controllers import PD, ComputedTorque, PlannedSwingUp  # noqa: F401
from mbs_envs.models import FourBar, Planar2R, RollingDisk, SerialChain, SpatialChain  # noqa: F401

assert "site-packages" in mbs_envs.__file__, mbs_envs.__file__  # the wheel, not a checkout
assert importlib.util.find_spec("controllers") is None, "a top-level 'controllers' module is installed"
ids = [i for i in gym.registry if i.startswith("mbs_envs/")]
assert len(ids) == 18, ids
for env_id in ids:
    env = gym.make(env_id)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert np.all(np.isfinite(obs)) and np.isfinite(reward), env_id
    env.close()
    print(f"ok {env_id}")
print(f"mbs_envs {mbs_envs.__version__}: {len(ids)} ids make, reset and step in a fresh environment ({sys.prefix})")
