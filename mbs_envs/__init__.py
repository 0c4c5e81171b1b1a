"""mbs_envs: Gymnasium environments for multi-body mechanisms, backed by their equations of motion.

``import mbs_envs`` registers the environment ids (``mbs_envs/Planar2R-v0``, ...)
with Gymnasium.
"""

from gymnasium.envs.registration import register, registry

from . import models
from .dynamics import integrators
from .envs.presets import PROTOCOL_IDS, TRAINING_IDS
from .envs.registry import SCENES
from .envs.vector import vector_entry_point as _vector_entry_point
from .simulate import Trajectory, simulate  # the module first, then the name is the function

__version__ = "0.2.0"
__all__ = ["SCENES", "Trajectory", "integrators", "models", "simulate", "__version__"]

#: id -> (entry point, max_episode_steps), from the scene registry (:mod:`mbs_envs.envs.registry`)
ENV_IDS = {s.id: (s.entry_point, s.max_episode_steps) for s in SCENES}

for _scene in SCENES:
    if _scene.id not in registry:
        register(
            id=_scene.id,
            entry_point=_scene.entry_point,
            vector_entry_point=_vector_entry_point(_scene.entry_point),
            max_episode_steps=_scene.max_episode_steps,
        )

# the published protocols' ids (a preset's plant and setup with the protocol's episode length; mbs_envs.envs.presets),
# and the same plants with the v2 task's reward to train on
for _id, _entry, _preset, _steps in PROTOCOL_IDS + TRAINING_IDS:
    if _id not in registry:
        register(
            id=_id,
            entry_point=_entry,
            vector_entry_point=_vector_entry_point(_entry),
            max_episode_steps=_steps,
            kwargs={"preset": _preset},
        )
