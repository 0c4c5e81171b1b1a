"""The scenes and conditions of the studies: which scenes are compared, the plant conditions (nominal, masses and
lengths scaled, observation noise, input delay) and the env arguments of a plant under a condition. The comparison,
the tuning and the hand-over tuning read them from here.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np

from ..envs.registry import SCENES as REGISTRY

#: scene -> (env id, env kwargs, model-based controllers by display name -> "module:class"), from the registry
SCENES: dict[str, tuple[str, dict, dict[str, str]]] = {
    s.name: (s.id, dict(s.kwargs), dict(s.controllers)) for s in REGISTRY if s.compared
}


@dataclasses.dataclass(frozen=True)
class Condition:
    """A plant condition: ``scale`` of masses and lengths (1 = nominal), observation noise,
    and an input delay of ``delay`` control steps (the plant applies the action chosen
    ``delay`` steps earlier; zero before that)."""

    name: str
    scale: float = 1.0
    obs_noise: float = 0.0
    delay: int = 0


def conditions(levels: tuple[float, ...] = (0.2,), noise: float = 0.01, delay: int = 1) -> list[Condition]:
    """Nominal, mismatch ``+-p`` for each level, observation noise (if ``noise``) and input delay (if ``delay``)."""
    out = [Condition("nominal")]
    for p in levels:
        out += [Condition(f"mismatch +{p:.0%}", 1 + p), Condition(f"mismatch -{p:.0%}", 1 - p)]
    if noise:
        out.append(Condition(f"obs noise {noise:g}", obs_noise=noise))
    if delay:
        out.append(Condition(f"input delay {delay} step" + ("s" if delay > 1 else ""), delay=delay))
    return out


def scaled_params(model: Any, s: float) -> dict[str, Any]:
    """Masses ``m*`` times ``s``, lengths ``l*``/``r*`` (and the spatial chain's ``offset``, ``com``) times ``s``,
    inertias ``I*`` (``inertia``) times ``s^3``."""
    out = {}
    for name in model.params.names():
        value = getattr(model.params, name)
        head = name.rstrip("0123456789")
        if head in ("m", "l", "r", "offset", "com"):
            out[name] = value * s
        elif head in ("I", "inertia"):
            out[name] = value * s**3
    return out


def plant_kwargs(scene: str, condition: Condition) -> dict[str, Any]:
    """Env arguments of the plant: scaled parameters, nominal actuators (limits, armature)."""
    env_id, kwargs, _ = SCENES[scene]
    if condition.scale == 1.0:
        return dict(kwargs)
    return model_kwargs(scene, scaled_params(gym.make(env_id, **kwargs).unwrapped.model, condition.scale))


def listed(params: dict[str, Any]) -> dict[str, Any]:
    """``params`` with arrays as lists (``gym.make`` keywords that survive JSON and pickling as they are)."""
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in params.items()}


def model_kwargs(scene: str, params: dict[str, Any]) -> dict[str, Any]:
    """Env arguments of the scene's plant with the parameters ``params`` changed and the actuators nominal
    (the torque limits and the drives' armature, which some scenes derive from the parameters)."""
    env_id, kwargs, _ = SCENES[scene]
    nominal = gym.make(env_id, **kwargs).unwrapped
    params = dict(params)
    if hasattr(nominal.model.params, "armature"):
        params["armature"] = nominal.model.params.armature
    return {**kwargs, "params": listed(params),
            "torque_limit": nominal.u_max.tolist()}  # fmt: skip


#: the tuning's plants: nominal and masses and lengths -20 %, +20 % (:mod:`mbs_envs.studies.tuning`)
TUNING_CONDITIONS = (Condition("nominal"), Condition("mismatch -20%", 0.8), Condition("mismatch +20%", 1.2))
