"""RL agents against model-based controllers (the logic of ``scripts/compare.py``).

For each scene, each policy (the model-based controllers that apply, and the
shipped SB3 agents) is rolled out on the same seeds, in one batched rollout per
(scene, condition, policy). Conditions: the nominal plant; model mismatch, where
the plant's masses and lengths are scaled by ``1 +- p`` (inertias by
``(1 +- p)^3``, i.e. the same bodies made bigger or smaller) while every
controller keeps the nominal model and the actuators keep their nominal limits;
and observation noise (Gaussian, in observation units). Policies are built
inside the worker from names (controllers from the nominal env, agents loaded
from disk), so the cells can run in processes or on Ray.
"""

from __future__ import annotations

import dataclasses
import pathlib
import time
from typing import Any

import gymnasium as gym
import numpy as np

from .evaluation import episode_metrics, rollout_batch

#: scene -> (env id, env kwargs, model-based controllers by display name -> "module:class")
SCENES: dict[str, tuple[str, dict, dict[str, str]]] = {
    "Planar2R": ("mbs_envs/Planar2R-v0", {}, {"PD": "controllers:PD", "PD+gravity": "controllers:PDGravity", "computed torque": "controllers:ComputedTorque"}),
    "FourBar": ("mbs_envs/FourBar-v0", {}, {"PD": "controllers:PD", "PD+gravity": "controllers:PDGravity", "computed torque": "controllers:ComputedTorque"}),
    "SerialChain": ("mbs_envs/SerialChain-v0", {}, {"PD": "controllers:PD", "PD+gravity": "controllers:PDGravity", "computed torque": "controllers:ComputedTorque"}),
    "RollingDisk": ("mbs_envs/RollingDisk-v0", {}, {"LQR": "controllers:LQR", "PD steering": "controllers:SteeringPD", "no control": "controllers:NoControl"}),
}


@dataclasses.dataclass(frozen=True)
class Condition:
    """A plant condition: ``scale`` of masses and lengths (1 = nominal) and observation noise."""

    name: str
    scale: float = 1.0
    obs_noise: float = 0.0


def conditions(levels: tuple[float, ...] = (0.1, 0.2, 0.3), noise: float = 0.01) -> list[Condition]:
    out = [Condition("nominal")]
    for p in levels:
        out += [Condition(f"mismatch +{p:.0%}", 1 + p), Condition(f"mismatch -{p:.0%}", 1 - p)]
    if noise:
        out.append(Condition(f"obs noise {noise:g}", obs_noise=noise))
    return out


def scaled_params(model: Any, s: float) -> dict[str, Any]:
    """Masses ``m*`` times ``s``, lengths ``l*``/``r*`` times ``s``, inertias ``I*`` times ``s^3``."""
    out = {}
    for name in model.params.names():
        value = getattr(model.params, name)
        head = name.rstrip("0123456789")
        if head in ("m", "l", "r"):
            out[name] = value * s
        elif head == "I":
            out[name] = value * s**3
    return out


def plant_kwargs(scene: str, condition: Condition) -> dict[str, Any]:
    """Env arguments of the plant: scaled parameters, nominal actuators (limits, armature)."""
    env_id, kwargs, _ = SCENES[scene]
    nominal = gym.make(env_id, **kwargs).unwrapped
    kw = dict(kwargs)
    if condition.scale != 1.0:
        params = scaled_params(nominal.model, condition.scale)
        if hasattr(nominal.model.params, "armature"):
            params["armature"] = nominal.model.params.armature
        kw["params"] = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in params.items()}
        kw["torque_limit"] = nominal.u_max.tolist()
    return kw


def load_policy(spec: str, nominal_env: gym.Env) -> Any:
    """A controller (``"module:Class"``) built on the nominal env, or an agent (a folder with ``agent.zip``)."""
    if ":" in spec and not pathlib.Path(spec).exists():
        module, cls = spec.split(":")
        return getattr(__import__(module, fromlist=[cls]), cls)(nominal_env)
    from .training import load_agent

    return load_agent(pathlib.Path(spec))[0]


def find_agents(root: pathlib.Path, scene: str) -> dict[str, str]:
    """Shipped agents of a scene: ``{"PPO": ".../ppo", ...}`` for every ``<root>/<id>/<algo>/agent.zip``."""
    env_id = SCENES[scene][0].split("/")[-1]
    folder = pathlib.Path(root) / env_id
    return {p.parent.name.upper(): str(p.parent) for p in sorted(folder.glob("*/agent.zip"))}


def latency_us(policy: Any, obs: np.ndarray, repeats: int = 200) -> float:
    """Median wall time of one ``predict`` on a single observation [us]."""
    policy.predict(obs, deterministic=True)
    times = []
    for _ in range(repeats):
        tic = time.perf_counter()
        policy.predict(obs, deterministic=True)
        times.append(time.perf_counter() - tic)
    return float(np.median(times) * 1e6)


def evaluate_cell(task: dict[str, Any]) -> list[dict[str, Any]]:
    """All policies of one (scene, condition) on the same seeds; one row per policy and seed."""
    import torch

    torch.set_num_threads(1)
    scene, condition = task["scene"], Condition(**task["condition"])
    env_id, kwargs, _ = SCENES[scene]
    nominal = gym.make(env_id, **kwargs)
    venv = gym.make_vec(env_id, num_envs=len(task["seeds"]), vectorization_mode="vector_entry_point",
                        autoreset_mode="Disabled", **plant_kwargs(scene, condition))  # fmt: skip
    rows = []
    for name, spec in task["policies"].items():
        policy = load_policy(spec, nominal)
        episodes = rollout_batch(venv, policy, task["seeds"], obs_noise=condition.obs_noise, noise_seed=1)
        lat = latency_us(policy, nominal.reset(seed=0)[0]) if condition.name == "nominal" else float("nan")
        for seed, ep in zip(task["seeds"], episodes):
            rows.append({"scene": scene, "condition": condition.name, "policy": name,
                         "kind": "RL" if name in task.get("agents", ()) else "model-based", "seed": seed,
                         **episode_metrics(ep), "failed": bool(ep.terminated), "latency_us": lat})  # fmt: skip
    venv.close()
    return rows
