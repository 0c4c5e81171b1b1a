"""mbs_envs: Gymnasium environments for multi-body mechanisms, backed by their equations of motion.

``import mbs_envs`` registers the environment ids (``mbs_envs/Planar2R-v0``, ...)
with Gymnasium.
"""

import functools

from gymnasium.envs.registration import register, registry

from . import integrators, models
from .envs.vector import make_vector as _make_vector
from .simulate import Trajectory, simulate

__version__ = "0.1.0"
__all__ = ["Trajectory", "integrators", "models", "simulate", "__version__"]

#: id -> (entry point, max_episode_steps)
ENV_IDS = {
    "mbs_envs/Planar2R-v0": ("mbs_envs.envs.planar2r:Planar2REnv", 500),
    "mbs_envs/FourBar-v0": ("mbs_envs.envs.fourbar:FourBarEnv", 500),
    "mbs_envs/RollingDisk-v0": ("mbs_envs.envs.rolling_disk:RollingDiskEnv", 1000),
    "mbs_envs/SerialChain-v0": ("mbs_envs.envs.serial_chain:SerialChainEnv", 500),
}

for _id, (_entry, _steps) in ENV_IDS.items():
    if _id not in registry:
        register(
            id=_id,
            entry_point=_entry,
            vector_entry_point=functools.partial(_make_vector, _entry),
            max_episode_steps=_steps,
        )
