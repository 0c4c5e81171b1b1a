"""Training stable-baselines3 agents on the scenes (the logic of ``scripts/train.py``).

Agents train on the batched vector env through the SB3 adapter
(:func:`mbs_envs.sb3.make_sb3_vec_env`): one numpy step for all members. While
training, :class:`TrainingLog` evaluates the deterministic policy every
``eval_every`` env-steps on fixed seeds (a batched rollout, the same metrics
as ``scripts/compare.py``) and records it against the *training* wall time
(evaluation time excluded), which is what the comparison plots as "error
against run time". A run saves ``agent.zip`` (SB3), ``config.json`` (env id
and arguments, algorithm, hyperparameters, the exact command, wall time,
versions) and ``training_log.csv``.

Requires the ``rl`` extra.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import pathlib
import platform
import sys
import time
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, CallbackList
from stable_baselines3.common.noise import NormalActionNoise
from tqdm import tqdm

from .evaluation import episode_metrics, rollout_batch
from .sb3 import make_sb3_vec_env

ALGOS = {"ppo": PPO, "sac": SAC, "td3": TD3}


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """One training run.

    Attributes
    ----------
    env_id : str
    algo : {"ppo", "sac", "td3"}
    steps : int
        Environment steps (summed over the parallel members).
    seed : int
    n_envs : int, optional
        Parallel members (default 64 for PPO, 4 for SAC/TD3).
    env_kwargs : dict
        Arguments of the environment (``params``, ``n_links``, ...).
    net_arch : tuple of int
        Hidden layers of the policy (and value/Q) networks.
    eval_every : int, optional
        Env-steps between evaluations (default ``steps / 10``).
    eval_seeds : int
        Episodes per evaluation (seeds 10_000 ...; disjoint from comparison seeds 0 ...).
    """

    env_id: str
    algo: str
    steps: int
    seed: int = 0
    n_envs: int | None = None
    env_kwargs: dict = dataclasses.field(default_factory=dict)
    net_arch: tuple[int, ...] = (64, 64)
    eval_every: int | None = None
    eval_seeds: int = 5

    def __post_init__(self) -> None:
        if self.algo not in ALGOS:
            raise ValueError(f"algo must be one of {sorted(ALGOS)}, got {self.algo!r}")
        if not (isinstance(self.steps, int) and self.steps > 0):
            raise ValueError(f"steps must be a positive integer, got {self.steps!r}")
        if self.n_envs is not None and not (isinstance(self.n_envs, int) and self.n_envs > 0):
            raise ValueError(f"n_envs must be a positive integer, got {self.n_envs!r}")

    @property
    def members(self) -> int:
        return self.n_envs or (64 if self.algo == "ppo" else 4)


def hyperparameters(config: TrainConfig, action_dim: int) -> dict[str, Any]:
    """SB3 constructor arguments used for ``config`` (recorded in ``config.json``)."""
    policy_kwargs = {"net_arch": list(config.net_arch)}
    if config.algo == "ppo":
        n_steps = 128
        return {"n_steps": n_steps, "batch_size": n_steps * config.members // 4, "n_epochs": 10,
                "learning_rate": 3e-4, "gamma": 0.99, "gae_lambda": 0.95, "ent_coef": 0.0,
                "policy_kwargs": policy_kwargs}  # fmt: skip
    common = {"learning_rate": 1e-3, "buffer_size": min(config.steps, 1_000_000), "learning_starts": 2_000,
              "batch_size": 256, "gamma": 0.99, "train_freq": 1, "gradient_steps": 1, "policy_kwargs": policy_kwargs}  # fmt: skip
    if config.algo == "td3":
        common["action_noise"] = NormalActionNoise(np.zeros(action_dim), 0.1 * np.ones(action_dim))
    return common


def evaluate(policy: Any, env_id: str, seeds: list[int], env_kwargs: dict, **rollout_kwargs: Any) -> dict[str, float]:
    """Mean episode metrics of ``policy`` over ``seeds`` (one batched rollout), plus the failure rate."""
    venv = gym.make_vec(env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", autoreset_mode="Disabled", **env_kwargs)
    episodes = rollout_batch(venv, policy, seeds, **rollout_kwargs)
    venv.close()
    metrics = [episode_metrics(ep) for ep in episodes]
    out = {k: float(np.mean([m[k] for m in metrics])) for k in ("return", "rms_error", "rms_error_settled", "max_error", "rms_torque", "peak_torque")}
    out["failure_rate"] = float(np.mean([ep.terminated for ep in episodes]))
    return out


class TrainingLog(BaseCallback):
    """Progress bar, and the deterministic policy's metrics every ``eval_every`` env-steps."""

    def __init__(self, config: TrainConfig, eval_every: int):
        super().__init__()
        self.config = config
        self.eval_every = eval_every
        self.rows: list[dict[str, float]] = []
        self.eval_time = 0.0
        self._next = 0
        self._t0 = 0.0
        self._bar: tqdm | None = None

    def _on_training_start(self) -> None:
        self._t0 = time.perf_counter()
        self._bar = tqdm(total=self.config.steps, desc=f"{self.config.algo} {self.config.env_id}", unit="step", mininterval=1.0)
        self._evaluate()

    def _evaluate(self) -> None:
        tic = time.perf_counter()
        seeds = list(range(10_000, 10_000 + self.config.eval_seeds))
        metrics = evaluate(self.model, self.config.env_id, seeds, self.config.env_kwargs)
        self.eval_time += time.perf_counter() - tic
        wall = time.perf_counter() - self._t0 - self.eval_time
        self.rows.append({"timesteps": int(self.num_timesteps), "train_wall_s": wall, **metrics})
        self._next = self.num_timesteps + self.eval_every

    def _on_step(self) -> bool:
        if self._bar is not None:
            self._bar.update(min(self.num_timesteps, self.config.steps) - self._bar.n)
        if self.num_timesteps >= self._next:
            self._evaluate()
        return True

    def _on_training_end(self) -> None:
        if self.rows[-1]["timesteps"] != self.num_timesteps:
            self._evaluate()
        if self._bar is not None:
            self._bar.close()

    @property
    def train_wall_s(self) -> float:
        return time.perf_counter() - self._t0 - self.eval_time


def train(config: TrainConfig, out: pathlib.Path, tensorboard: bool = False, checkpoint_every: int | None = None) -> dict[str, Any]:
    """Train one agent and save it with its configuration and log to ``out``.

    Returns
    -------
    dict
        The contents of ``config.json``.
    """
    import stable_baselines3
    import torch

    if tensorboard:
        try:
            import tensorboard as _  # noqa: F401
        except ImportError:
            raise ValueError("tensorboard logging needs the tensorboard package: pip install tensorboard") from None
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)
    venv = make_sb3_vec_env(config.env_id, n_envs=config.members, seed=config.seed, **config.env_kwargs)
    hyper = hyperparameters(config, venv.action_space.shape[0])
    model = ALGOS[config.algo](
        "MlpPolicy", venv, seed=config.seed, device="cpu", verbose=0,
        tensorboard_log=str(out / "tensorboard") if tensorboard else None, **hyper,
    )  # fmt: skip
    log = TrainingLog(config, config.eval_every or max(config.steps // 10, 1))
    callbacks: list[BaseCallback] = [log]
    if checkpoint_every:
        callbacks.append(CheckpointCallback(max(checkpoint_every // config.members, 1), str(out / "checkpoints"), name_prefix="agent"))
    model.learn(config.steps, callback=CallbackList(callbacks))
    wall = log.train_wall_s
    model.save(out / "agent.zip")
    venv.close()
    with open(out / "training_log.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(log.rows[0]))
        w.writeheader()
        w.writerows(log.rows)
    record = {
        "env_id": config.env_id,
        "env_kwargs": config.env_kwargs,
        "algo": config.algo,
        "steps": config.steps,
        "seed": config.seed,
        "n_envs": config.members,
        "net_arch": list(config.net_arch),
        "hyperparameters": {k: (repr(v) if k == "action_noise" else v) for k, v in hyper.items()},
        "command": "python " + " ".join(sys.argv) if sys.argv and sys.argv[0].endswith("train.py") else None,
        "train_wall_s": wall,
        "final_evaluation": log.rows[-1],
        "versions": {"python": platform.python_version(), "stable_baselines3": stable_baselines3.__version__,
                     "torch": torch.__version__, "numpy": np.__version__},  # fmt: skip
    }
    (out / "config.json").write_text(json.dumps(record, indent=2, default=str))
    return record


def load_agent(folder: pathlib.Path) -> tuple[Any, dict[str, Any]]:
    """An agent saved by :func:`train` and its ``config.json``."""
    folder = pathlib.Path(folder)
    record = json.loads((folder / "config.json").read_text())
    model = ALGOS[record["algo"]].load(folder / "agent.zip", device="cpu")
    return model, record
