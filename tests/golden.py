"""Episodes recorded from a fixed version of the environments, to keep later versions equal.

Each case is ``(label, id, make kwargs, seed)``; an episode applies the same
seeded random actions (beyond the limits, so saturation is covered) for
``STEPS`` steps through ``gym.make`` (single env) and through the vector env
(members seeded ``seed + i``), and records observations, rewards,
terminations and the energy in ``info``. Regenerate (only on purpose, when the
physics or a task changes) with ``python -m tests.golden``; the file records
the commit it was made from.
"""

from __future__ import annotations

import pathlib
import subprocess

import gymnasium as gym
import numpy as np

import mbs_envs  # noqa: F401  (registers the ids)

PATH = pathlib.Path(__file__).parent / "data" / "golden_episodes.npz"
STEPS = 150
VECTOR_MEMBERS = 3

CASES = [
    ("planar2r", "mbs_envs/Planar2R-v0", {}, 3),
    ("planar2r_numpy", "mbs_envs/Planar2R-v0", {"compiled": False}, 4),
    ("planar2r_friction", "mbs_envs/Planar2R-v0", {"params": {"f1": 0.3, "b2": 0.2}}, 5),
    ("fourbar", "mbs_envs/FourBar-v0", {}, 3),
    ("disk", "mbs_envs/RollingDisk-v0", {}, 3),
    ("chain2", "mbs_envs/SerialChain-v0", {"n_links": 2}, 3),
    ("chain10", "mbs_envs/SerialChain-v0", {"n_links": 10}, 3),
    ("chain10_friction", "mbs_envs/SerialChain-v0", {"n_links": 10, "params": {"f": 0.01, "b": 0.02}}, 6),
]


def actions(env_id: str, kwargs: dict, seed: int, n: int, members: int | None = None) -> np.ndarray:
    nu = gym.make(env_id, **kwargs).action_space.shape[0]
    shape = (STEPS, nu) if members is None else (STEPS, members, nu)
    return np.random.default_rng(1000 + seed).uniform(-1.3, 1.3, shape).astype(np.float32)


def single_episode(env_id: str, kwargs: dict, seed: int) -> dict[str, np.ndarray]:
    env = gym.make(env_id, **kwargs)
    obs0, _ = env.reset(seed=seed)
    rows = {"obs": [obs0], "reward": [], "terminated": [], "energy": []}
    for a in actions(env_id, kwargs, seed, STEPS):
        obs, r, term, trunc, info = env.step(a)
        rows["obs"].append(obs)
        rows["reward"].append(r)
        rows["terminated"].append(term)
        rows["energy"].append(info["energy"])
        if term or trunc:
            obs, _ = env.reset()
            rows["obs"].append(obs)  # the next episode's first observation follows a termination
    return {k: np.asarray(v) for k, v in rows.items()}


def vector_episode(env_id: str, kwargs: dict, seed: int) -> dict[str, np.ndarray]:
    envs = gym.make_vec(env_id, num_envs=VECTOR_MEMBERS, vectorization_mode="vector_entry_point", **kwargs)
    obs0, _ = envs.reset(seed=seed)
    rows = {"obs": [obs0], "reward": [], "terminated": [], "energy": []}
    for a in actions(env_id, kwargs, seed, STEPS, VECTOR_MEMBERS):
        obs, r, term, trunc, info = envs.step(a)
        rows["obs"].append(obs)
        rows["reward"].append(r)
        rows["terminated"].append(term)
        rows["energy"].append(info["energy"])
    return {k: np.asarray(v) for k, v in rows.items()}


def record() -> dict[str, np.ndarray]:
    out = {}
    for label, env_id, kwargs, seed in CASES:
        for kind, run in (("single", single_episode), ("vector", vector_episode)):
            for key, value in run(env_id, kwargs, seed).items():
                out[f"{label}/{kind}/{key}"] = value
    return out


if __name__ == "__main__":
    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=PATH.parent
    ).stdout.strip()
    PATH.parent.mkdir(exist_ok=True)
    np.savez_compressed(PATH, commit=np.array(commit), **record())
    print(f"wrote {PATH} ({PATH.stat().st_size / 1e3:.0f} kB) from commit {commit}")
