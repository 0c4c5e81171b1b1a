"""Training stable-baselines3 agents on the scenes (the logic of ``scripts/train.py``).

Agents train on the batched vector env through the SB3 adapter
(:func:`mbs_envs.envs.sb3.make_sb3_vec_env`): one numpy step for all members. While
training, :class:`TrainingLog` evaluates the deterministic policy every
``eval_every`` env-steps on fixed seeds (a batched rollout, the same metrics
as ``scripts/compare.py``) and records it against the *training* wall time
(evaluation time excluded), which is what the comparison plots as "error
against run time". A run saves ``agent.zip`` (SB3), ``config.json`` (env id
and arguments, algorithm, hyperparameters, the exact command, wall time,
versions) and ``training_log.csv``. A run stopped early (Ctrl-C, or SIGTERM at a job's time limit) saves the same,
its ``config.json`` recording the steps done and ``interrupted`` (the steps planned), so that it ships or continues
(``init``) as any other.

Requires the ``rl`` extra.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import json
import os
import pathlib
import platform
import re
import time
from collections.abc import Mapping
from typing import Any, Iterator

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, CallbackList
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.noise import NormalActionNoise
from stable_baselines3.common.vec_env import VecNormalize
from tqdm import tqdm

from . import seeds as seed_ranges
from ..envs import registry
from .evaluation import ERROR_METRIC, SCORING, default_gains_entry, make_controller, rollout_batch
from .residual import ResidualPolicy, check_bound, residual_vec_env
from ..envs.sb3 import check_action_repeat, make_sb3_vec_env
from .held import HeldPolicy
from .normalized import NormalizedPolicy, ObsNormalization
from .provenance import command_line

ALGOS = {"ppo": PPO, "sac": SAC, "td3": TD3}


#: a checkpoint's file name, ``agent_<decisions>_steps.zip`` (SB3's CheckpointCallback with the prefix ``agent``)
CHECKPOINT = re.compile(r"agent_(\d+)_steps\.zip")


#: the hyperparameters a continued run may change (none shapes a network or a buffer): the discount, the target
#: networks' rate, the learning rate, the batch and the gradient steps per update
CONTINUED_HYPER = ("gamma", "tau", "learning_rate", "batch_size", "gradient_steps")


def init_files(init: str | pathlib.Path) -> tuple[pathlib.Path, pathlib.Path, pathlib.Path, int | None]:
    """Where a continued run's source is: ``(run folder, agent file, replay buffer file, checkpoint's decisions)``.

    ``init`` is a folder saved by :func:`train` (its agent and buffer; decisions None), or one of its checkpoints,
    ``<folder>/checkpoints/agent_<n>_steps.zip`` (that agent and the buffer saved with it, ``n`` decisions in).
    """
    init = pathlib.Path(init)
    match = CHECKPOINT.fullmatch(init.name)
    if match and init.parent.name == "checkpoints":
        n = int(match.group(1))
        return init.parents[1], init, init.parent / f"agent_replay_buffer_{n}_steps.pkl", n
    return init, init / "agent.zip", init / REPLAY_BUFFER, None


def check_init(config: "TrainConfig") -> dict[str, Any]:
    """The ``config.json`` of ``config.init``'s run, or a ``ValueError`` naming what does not match."""
    folder, agent, _, _ = init_files(config.init)
    if not agent.exists() or not (folder / "config.json").exists():
        raise ValueError(
            f"init: {str(config.init)!r} is no agent saved by train (a folder with agent.zip and config.json, "
            "or its checkpoints/agent_<n>_steps.zip)"
        )
    source = json.loads((folder / "config.json").read_text())
    mine = {"algo": config.algo, "action_repeat": config.action_repeat, "normalize": config.normalize,
            "residual": (config.residual or None)}  # fmt: skip
    theirs = {"algo": source["algo"], "action_repeat": source.get("action_repeat", 1), "normalize": source.get("normalize", False),
              "residual": (source.get("residual") or {}).get("base")}  # fmt: skip
    for key in mine:
        if mine[key] != theirs[key]:
            raise ValueError(f"init: the source agent has {key}={theirs[key]!r}, this run {mine[key]!r}")
    if set(config.hyper) - set(CONTINUED_HYPER):
        raise ValueError(
            f"init: a continued run keeps the source's networks and buffers; hyper may set only {CONTINUED_HYPER}, "
            f"got {sorted(config.hyper)}"
        )
    if config.normalize:
        raise ValueError(
            "init: continuing a normalized run is not supported (only its observation statistics are saved)"
        )
    return source


#: env arguments that only draw the episodes' starts: a transition stored under other values is worth the same
START_ARGUMENTS = ("start_upright", "start_noise", "start_states")


def same_task(source: Mapping[str, Any], config: "TrainConfig") -> bool:
    """Whether a continued run trains on its source's task, so that the transitions (and rewards) stored in the
    source's replay buffer are this run's: the same env id and env arguments, the training members' arguments
    alike but for the starts (:data:`START_ARGUMENTS`, a curriculum). Otherwise the run starts with an empty buffer."""

    def task(env_id: str, env_kwargs: Mapping[str, Any], train_env_kwargs: Mapping[str, Any]) -> tuple:
        return env_id, dict(env_kwargs), {k: v for k, v in train_env_kwargs.items() if k not in START_ARGUMENTS}

    return task(source["env_id"], source.get("env_kwargs", {}), source.get("train_env_kwargs", {})) == task(
        config.env_id, config.env_kwargs, config.train_env_kwargs)  # fmt: skip


def residual_base(env_id: str) -> str:
    """The default base controller (``"module:Class"``) of a residual agent on ``env_id``:
    the scene's best model-based controller (:attr:`mbs_envs.envs.registry.Scene.residual_base`)."""
    return registry.scene(env_id).residual_base


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
        Parallel members (default 64 for PPO, 8 for SAC/TD3). Member ``i`` of
        run ``seed`` starts from ``reset(seed=100_000 + 1_000 seed + i)``
        (:func:`mbs_envs.studies.seeds.training_members`), apart from test seeds.
    env_kwargs : dict
        Arguments of the environment (``params``, ``n_links``, ...): the task trained on and evaluated.
    train_env_kwargs : dict
        Arguments applied on top of ``env_kwargs`` to the training members only, never to the
        validation episodes: a training curriculum, e.g. ``{"start_upright": 0.5}`` on the swing-up
        scenes (half the training episodes start near upright; the task scored still starts hanging).
    eval_env_kwargs : dict
        Arguments applied on top of ``env_kwargs`` to the validation episodes only, e.g. ``{"randomize": {...}}``:
        each validation seed's plant drawn from its own generator (the same plants at every evaluation), so that
        ``keep_best`` keeps the agent best over a set of plants rather than on the nominal one.
    net_arch : tuple of int, optional
        Hidden layers of the policy (and value/Q) networks; default SB3's:
        (64, 64) for PPO, (256, 256) for SAC and TD3.
    eval_every : int, optional
        Env-steps between evaluations (default ``steps / 10``).
    eval_seeds : int
        Episodes per evaluation (validation seeds 10_000 ..., :mod:`mbs_envs.studies.seeds`).
    residual : str, optional
        Train a residual agent on top of this controller (``"module:Class"``,
        built on the nominal env with its default gains); see :mod:`mbs_envs.studies.residual`.
    residual_bound : float
        Largest correction, as a fraction of the actuator limit.
    hyper : dict, optional
        Overrides of the numeric hyperparameters of :func:`hyperparameters`
        (e.g. ``{"gamma": 0.998}``); a key it does not set is a ``ValueError``.
    normalize : bool
        Train behind SB3's ``VecNormalize`` (observations and rewards, the rewards with
        the run's discount); the observation statistics are saved with the agent
        (:mod:`mbs_envs.studies.normalized`) and applied when it is loaded.
    action_repeat : int
        Control steps each of the agent's actions is held for (``K``; 1: it decides
        every step). The agent trains through the adapter's action repeat
        (:class:`mbs_envs.envs.sb3.SB3VecEnv`) and is evaluated, compared and
        recorded holding its decisions the same way
        (:class:`mbs_envs.studies.held.HeldPolicy`). ``steps`` still counts control
        steps (the simulated time), so a run with ``K = 8`` makes 8 times fewer
        decisions and gradient updates for the same budget.
    init : str, optional
        A folder saved by :func:`train` whose agent this run continues (its weights, and its
        optimizer's state) instead of starting afresh, e.g. an agent of an earlier task version
        trained on further on the new reward, or a run continued for a longer budget (an off-policy run's replay
        buffer, saved beside its agent, comes with it on the same task: :func:`same_task`); or one of the
        folder's checkpoints (``checkpoints/agent_<n>_steps.zip``, with the buffer saved beside it). The algorithm,
        action repeat, normalization and residual base must be the source's; its hyperparameters are kept but for
        those ``hyper`` sets among :data:`CONTINUED_HYPER` (a longer discount for a fine-tuning, say);
        not for a normalized run (its reward statistics are not saved).
        ``config.json`` records the source and its budget.
    keep_best : bool
        Ship the agent of the best evaluation on the validation seeds (never test seeds) instead of the last one:
        the fewest failed episodes by the task's rule, then the highest return (:func:`better_evaluation`; SB3's
        ``EvalCallback`` keeps the highest return alone, which on a swing-up scene can prefer an agent that balances
        less often). A run's return can collapse late in it. ``config.json`` records which evaluation was kept.
    perturb : str or dict, optional
        Train under the robustness axes (``"dfki"``, or the fields of
        :class:`mbs_envs.envs.perturbed.TrainingPerturbations`): each training member meets one perturbation
        (measurement noise, torque noise, a lagging actuator, a delay, torque pulses) per episode, drawn at its
        reset; validation runs the task unperturbed. ``config.json`` records the ranges.
    smooth : CAPS, dict or str, optional
        Regularize an off-policy actor toward a smooth feedback law (:mod:`mbs_envs.studies.smoothing`: the CAPS
        terms' weights and noise, as :class:`~mbs_envs.studies.smoothing.CAPS`, its fields or
        ``"temporal,spatial,sigma"``). The reward is untouched; ``config.json`` records the setting.
    """

    env_id: str
    algo: str
    steps: int
    seed: int = 0
    n_envs: int | None = None
    env_kwargs: dict = dataclasses.field(default_factory=dict)
    train_env_kwargs: dict = dataclasses.field(default_factory=dict)
    eval_env_kwargs: dict = dataclasses.field(default_factory=dict)
    net_arch: tuple[int, ...] | None = None
    eval_every: int | None = None
    eval_seeds: int = 10
    residual: str | None = None
    residual_bound: float = 0.25
    hyper: dict = dataclasses.field(default_factory=dict)
    action_repeat: int = 1
    normalize: bool = False
    init: str | None = None
    keep_best: bool = False
    perturb: Any = None
    smooth: Any = None

    def __post_init__(self) -> None:
        if self.algo not in ALGOS:
            raise ValueError(f"algo must be one of {sorted(ALGOS)}, got {self.algo!r}")
        if self.smooth is not None:
            from .smoothing import CAPS

            caps = CAPS.of(self.smooth)
            if self.algo == "ppo":
                raise ValueError("smooth: CAPS regularizes an off-policy actor (sac, td3), not ppo")
            object.__setattr__(self, "smooth", dataclasses.asdict(caps))  # checked, JSON-ready
        if not (isinstance(self.steps, int) and self.steps > 0):
            raise ValueError(f"steps must be a positive integer, got {self.steps!r}")
        if self.n_envs is not None and not (
            isinstance(self.n_envs, int) and 0 < self.n_envs <= seed_ranges.MAX_MEMBERS
        ):
            raise ValueError(f"n_envs must be an integer in [1, {seed_ranges.MAX_MEMBERS}], got {self.n_envs!r}")
        if not (isinstance(self.seed, int) and self.seed >= 0):
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")
        if self.net_arch is not None and not (
            len(self.net_arch) > 0 and all(isinstance(k, int) and k > 0 for k in self.net_arch)
        ):
            raise ValueError(f"net_arch must be positive layer widths, got {self.net_arch!r}")
        check_bound(self.residual_bound)
        check_action_repeat(self.action_repeat)
        if self.residual and self.action_repeat != 1:
            raise ValueError("action_repeat > 1 is not available for residual agents (their base acts every step)")
        if self.init is not None:
            check_init(self)
        if self.perturb is not None:
            from ..envs.perturbed import TrainingPerturbations

            object.__setattr__(self, "perturb", TrainingPerturbations.of(self.perturb).as_dict())  # checked, JSON-ready
        defaults = _defaults(self, 1)
        for key, value in self.hyper.items():
            if key not in defaults or not isinstance(defaults[key], (int, float)):
                tunable = sorted(k for k, v in defaults.items() if isinstance(v, (int, float)))
                raise ValueError(f"hyper: {key!r} is not a numeric hyperparameter of {self.algo}; one of {tunable}")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
                raise ValueError(f"hyper: {key}={value!r} is not a finite number")
            if isinstance(defaults[key], int) and not isinstance(value, int):
                raise ValueError(f"hyper: {key} must be an integer, got {value!r}")
        if "gamma" in self.hyper and not 0.0 < self.hyper["gamma"] < 1.0:
            raise ValueError(f"hyper: gamma must be in (0, 1), got {self.hyper['gamma']!r}")

    @property
    def members(self) -> int:
        return self.n_envs or (64 if self.algo == "ppo" else 8)

    @property
    def layers(self) -> list[int]:
        return list(self.net_arch) if self.net_arch else ([64, 64] if self.algo == "ppo" else [256, 256])


def hyper_setting(text: str) -> tuple[str, int | float]:
    """``"gamma=0.998"`` -> ``("gamma", 0.998)`` (an integer stays an integer)."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise ValueError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, int(value)
    except ValueError:
        try:
            return key, float(value)
        except ValueError:
            raise ValueError(f"{key}: {value!r} is not a number") from None


def hyperparameters(config: TrainConfig, action_dim: int) -> dict[str, Any]:
    """SB3 constructor arguments used for ``config`` (recorded in ``config.json``):
    the defaults below with ``config.hyper`` applied.

    PPO: 128 steps per member and update, minibatches of a quarter of the
    rollout, 10 epochs, SB3's learning rate. SAC and TD3 (SB3-zoo settings of
    continuous-control tasks): one gradient step per transition
    (``gradient_steps=-1`` with ``train_freq=1``: as many steps as members),
    batch 256, SB3's default networks; TD3 explores with Gaussian action noise
    of 0.1 (a tenth of the actuator range). SAC's temperature is learned toward
    a target entropy of ``-4`` per action dimension instead of SB3's ``-1``:
    the tracking rewards are of order 1e-3 per step, so at SB3's target the
    entropy bonus outweighs the reward and the learned policy keeps action
    noise of a third of the actuator range (measured on the previous agents).
    Residual agents start with a small exploration noise (``log_std_init = -2``).
    """
    hyper = {**_defaults(config, action_dim), **config.hyper}
    if config.algo == "ppo" and "batch_size" not in config.hyper:
        hyper["batch_size"] = hyper["n_steps"] * config.members // 4
    if config.algo == "td3":
        hyper["action_noise"] = NormalActionNoise(np.zeros(action_dim), 0.1 * np.ones(action_dim))
    return hyper


def _defaults(config: TrainConfig, action_dim: int) -> dict[str, Any]:
    """The project's defaults of ``config.algo`` (:func:`hyperparameters`), without TD3's noise."""
    policy_kwargs: dict[str, Any] = {"net_arch": config.layers}
    if config.residual and config.algo in ("ppo", "sac"):
        # a residual starts as the base controller and explores gently around it: Gaussian
        # std e^-2 = 0.14 of the correction bound (SB3's default std 1 would push the
        # plant by the whole bound at every step and bury the base controller's precision)
        policy_kwargs["log_std_init"] = -2.0
    if config.algo == "ppo":
        n_steps = 128
        return {"n_steps": n_steps, "batch_size": n_steps * config.members // 4, "n_epochs": 10,
                "learning_rate": 3e-4, "gamma": 0.99, "gae_lambda": 0.95, "ent_coef": 0.0,
                "policy_kwargs": policy_kwargs}  # fmt: skip
    common = {"learning_rate": 1e-3, "buffer_size": min(config.steps, 1_000_000), "learning_starts": 5_000,
              "batch_size": 256, "gamma": 0.99, "tau": 0.005, "train_freq": 1, "gradient_steps": -1,
              "policy_kwargs": policy_kwargs}  # fmt: skip
    if config.algo == "sac":
        common["learning_rate"] = 3e-4
        # the swing-up rewards are of order 1 per step: SB3's own target (-dim A) there
        common["target_entropy"] = "auto" if registry.scene(config.env_id).scoring == "swing-up" else -4.0 * action_dim
    return common


def evaluate(policy: Any, env_id: str, seeds: list[int], env_kwargs: dict, **rollout_kwargs: Any) -> dict[str, float]:
    """Mean episode metrics of ``policy`` over ``seeds`` (one batched rollout), plus the failure rate.

    A failure is what the scene's scoring calls one (:data:`mbs_envs.studies.evaluation.SCORING`:
    an episode ended early; on a swing-up scene, one not ending upright).
    ``rms_error_settled`` (and ``time_to_swing_up`` on a swing-up scene) is the mean
    over the episodes that did not fail: a failed episode's figure would flatter
    it (the failure rate says how many failed).
    """
    venv = gym.make_vec(
        env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", autoreset_mode="Disabled", **env_kwargs
    )
    episodes = rollout_batch(venv, policy, seeds, **rollout_kwargs)
    venv.close()
    scoring = registry.scene(env_id).scoring
    scored = [SCORING[scoring](ep) for ep in episodes]
    ok = [m for m, failed in scored if not failed]
    out = {
        k: float(np.mean([m[k] for m, _ in scored]))
        for k in ("return", "rms_error", "max_error", "rms_torque", "peak_torque")
    }
    for k in dict.fromkeys(("rms_error_settled", ERROR_METRIC[scoring])):
        out[k] = float(np.mean([m[k] for m in ok])) if ok else float("nan")
    out["failure_rate"] = float(np.mean([failed for _, failed in scored]))
    return out


def better_evaluation(row: Mapping[str, float], kept: Mapping[str, float] | None) -> bool:
    """Whether the validation ``row`` (:func:`evaluate`'s figures) beats the one ``kept`` so far (None: nothing kept):
    fewer failed episodes (the task's own rule), then a higher mean return. A row with a non-finite return never wins.
    """
    if not np.isfinite(row["return"]):
        return False
    if kept is None:
        return True
    return (-row["failure_rate"], row["return"]) > (-kept["failure_rate"], kept["return"])


class TrainingLog(BaseCallback):
    """Progress bar, and the deterministic policy's metrics every ``eval_every`` env-steps."""

    def __init__(
        self,
        config: TrainConfig,
        eval_every: int,
        as_policy: Any = None,
        csv_path: pathlib.Path | None = None,
        on_row: Any = None,
    ):
        super().__init__()
        self.on_row = on_row  # called with each evaluation's row (e.g. to keep the best agent)
        self.csv_path = csv_path
        self.config = config
        self.as_policy = as_policy or (lambda model: model)
        self.eval_every = eval_every
        self.rows: list[dict[str, float]] = []
        self.eval_time = 0.0
        self._next = 0
        self._t0 = 0.0
        self._bar: tqdm | None = None

    def _on_training_start(self) -> None:
        self._t0 = time.perf_counter()
        self._bar = tqdm(
            total=self.config.steps, desc=f"{self.config.algo} {self.config.env_id}", unit="step", mininterval=1.0
        )
        self._evaluate()

    @property
    def env_steps(self) -> int:
        """Control steps so far (SB3 counts decisions: ``action_repeat`` steps each)."""
        return int(self.num_timesteps) * self.config.action_repeat

    def _evaluate(self) -> None:
        tic = time.perf_counter()
        seeds = seed_ranges.validation_seeds(self.config.eval_seeds)
        metrics = evaluate(
            self.as_policy(self.model),
            self.config.env_id,
            seeds,
            {**self.config.env_kwargs, **self.config.eval_env_kwargs},
        )
        self.eval_time += time.perf_counter() - tic
        wall = time.perf_counter() - self._t0 - self.eval_time
        self.rows.append({"timesteps": self.env_steps, "train_wall_s": wall, **metrics})
        self._next = self.env_steps + self.eval_every
        if self.csv_path is not None:  # written as it grows: a long run's curve can be read before it ends
            write_log(self.csv_path, self.rows)
        if self.on_row is not None:
            self.on_row(self.rows[-1])

    def _on_step(self) -> bool:
        if self._bar is not None:
            self._bar.update(min(self.env_steps, self.config.steps) - self._bar.n)
        if self.env_steps >= self._next:
            self._evaluate()
        return True

    def _on_training_end(self) -> None:
        if self.rows[-1]["timesteps"] != self.env_steps:
            self._evaluate()
        if self._bar is not None:
            self._bar.close()

    @property
    def train_wall_s(self) -> float:
        return time.perf_counter() - self._t0 - self.eval_time


def write_log(path: pathlib.Path, rows: list[dict[str, float]]) -> None:
    """Write the training log's rows (one per evaluation) as CSV."""
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


#: the file a training run holds in its folder while it runs (another run into the same folder is refused)
CLAIM = "TRAINING"


def out_refusal(out: pathlib.Path, overwrite: bool = False) -> str | None:
    """Why a training run may not write into ``out`` (another run holds it, or it holds a trained agent and not
    ``overwrite``), or None."""
    out = pathlib.Path(out)
    if (out / CLAIM).exists():
        return f"out: {out} is being written by another training run (its {CLAIM} file; remove it if that run has died)"
    return _holds_agent(out, overwrite)


def _holds_agent(out: pathlib.Path, overwrite: bool) -> str | None:
    if (out / "config.json").exists() and not overwrite:
        return f"out: {out} already holds a trained agent (config.json); choose another folder or overwrite it"
    return None


@contextlib.contextmanager
def claimed(out: pathlib.Path, overwrite: bool = False) -> Iterator[pathlib.Path]:
    """``out`` created and held for one training run: refused (``ValueError`` naming ``out``) where another run holds
    it (its :data:`CLAIM` file, created atomically) or, unless ``overwrite``, where it already holds a trained agent
    (``config.json``); the claim is released when the run ends, however it ends."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(out / CLAIM, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        raise ValueError(out_refusal(out, overwrite)) from None
    try:
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        refusal = _holds_agent(out, overwrite)
        if refusal:
            raise ValueError(refusal)
        yield out
    finally:
        (out / CLAIM).unlink(missing_ok=True)


def train(config: TrainConfig, out: pathlib.Path, tensorboard: bool = False, checkpoint_every: int | None = None,
          overwrite: bool = False) -> dict[str, Any]:  # fmt: skip
    """Train one agent and save it with its configuration and log to ``out`` (held by :func:`claimed` while it runs:
    two runs into one folder would overwrite each other's agent and log).

    Returns
    -------
    dict
        The contents of ``config.json``.
    """
    if tensorboard:
        try:
            import tensorboard as _  # noqa: F401
        except ImportError:
            raise ValueError("tensorboard logging needs the tensorboard package: pip install tensorboard") from None
    with claimed(out, overwrite) as out:
        return _train(config, out, tensorboard, checkpoint_every)


def _train(config: TrainConfig, out: pathlib.Path, tensorboard: bool, checkpoint_every: int | None) -> dict[str, Any]:
    import stable_baselines3
    import torch

    torch.set_num_threads(1)
    members = seed_ranges.training_members(config.seed, config.members)
    venv = make_sb3_vec_env(
        config.env_id,
        n_envs=config.members,
        seed=members[0],
        action_repeat=config.action_repeat,
        perturb=config.perturb,
        **{**config.env_kwargs, **config.train_env_kwargs},
    )
    base = base_gains = None
    if config.residual:
        nominal = gym.make(config.env_id, **config.env_kwargs)
        base_gains = default_gains_entry(
            config.residual, nominal
        )  # recorded: a later retune leaves this agent's base alone
        base = make_controller(config.residual, nominal, base_gains)
        venv = residual_vec_env(venv, base, config.residual_bound)
    hyper = hyperparameters(config, venv.action_space.shape[0])
    normalization = None
    if config.normalize:  # the agent's own observations (a residual's base sees the plain ones)
        venv = VecNormalize(venv, norm_obs=True, norm_reward=True, gamma=hyper["gamma"])
        normalization = lambda: ObsNormalization.of(venv)  # noqa: E731
    as_policy = lambda model: as_evaluated(
        model, config.action_repeat, base, config.residual_bound, normalization and normalization()
    )  # noqa: E731
    source = None
    buffer_from = None
    if config.init is None:
        model = ALGOS[config.algo](
            "MlpPolicy", venv, seed=config.seed, device="cpu", verbose=0,
            tensorboard_log=str(out / "tensorboard") if tensorboard else None, **hyper,
        )  # fmt: skip
    else:
        source = check_init(config)
        source_folder, agent_file, buffer, checkpoint = init_files(config.init)
        model = ALGOS[config.algo].load(agent_file, env=venv, device="cpu", verbose=0,
                                        tensorboard_log=str(out / "tensorboard") if tensorboard else None)  # fmt: skip
        model.set_random_seed(config.seed)
        hyper = {**source["hyperparameters"], **config.hyper}
        for key, value in config.hyper.items():  # CONTINUED_HYPER only (check_init)
            setattr(model, key, value)
        if "learning_rate" in config.hyper:
            model._setup_lr_schedule()
        if hasattr(model, "load_replay_buffer") and buffer.exists() and same_task(source, config):
            model.load_replay_buffer(buffer)  # an off-policy run continues with its data (its rewards still hold)
            buffer_from = str(buffer)
    if config.smooth is not None:
        from .smoothing import CAPS, regularize

        regularize(model, CAPS(**config.smooth))
    if not tensorboard:  # SB3's own logger, left to itself, makes an empty folder in the system's temp dir per run
        model.set_logger(Logger(folder=None, output_formats=[]))
    kept: dict[str, Any] = {}

    def keep(row: dict[str, float]) -> None:
        if config.keep_best and better_evaluation(row, kept or None):
            kept.clear()
            kept.update(row)
            model.save(out / "agent.zip")
            if config.normalize:
                ObsNormalization.of(venv).save(out)

    log = TrainingLog(
        config, config.eval_every or max(config.steps // 10, 1), as_policy, out / "training_log.csv", on_row=keep
    )
    callbacks: list[BaseCallback] = [log]
    if checkpoint_every:
        every = checkpoint_every // (config.members * config.action_repeat)
        callbacks.append(
            CheckpointCallback(
                max(every, 1),
                str(out / "checkpoints"),
                name_prefix="agent",
                save_vecnormalize=config.normalize,
                save_replay_buffer=hasattr(model, "replay_buffer"),
            )
        )
    interrupted = False
    with stop_on_sigterm():
        try:
            model.learn(config.steps // config.action_repeat, callback=CallbackList(callbacks))
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM (a job's time limit): keep what was learnt, say so
            interrupted = True
            if log._bar is not None:
                log._bar.close()
    wall = log.train_wall_s
    if not kept:  # the last agent (keep_best: the best evaluated one is saved already)
        model.save(out / "agent.zip")
        if config.normalize:
            ObsNormalization.of(venv).save(out)
    if hasattr(model, "save_replay_buffer"):  # what a continued run (``init``) picks up; never shipped
        model.save_replay_buffer(out / REPLAY_BUFFER)
    venv.close()  # training_log.csv: written by the log at each evaluation, the last at the end of training
    record = {
        "env_id": config.env_id,
        "env_kwargs": config.env_kwargs,
        "train_env_kwargs": config.train_env_kwargs,
        "eval_env_kwargs": config.eval_env_kwargs,
        "algo": config.algo,
        "steps": log.env_steps if interrupted else config.steps,
        "interrupted": {"planned_steps": config.steps} if interrupted else None,
        "seed": config.seed,
        "n_envs": config.members,
        "training_member_seeds": [members[0], members[-1]],
        "validation_seeds": [seed_ranges.VALIDATION[0], seed_ranges.VALIDATION[config.eval_seeds - 1]],
        "net_arch": config.layers,
        "residual": {"base": config.residual, "gains": base_gains, "bound": config.residual_bound}
        if config.residual
        else None,
        "hyperparameters": {k: (repr(v) if k == "action_noise" else v) for k, v in hyper.items()},
        "hyper_overrides": config.hyper,
        "action_repeat": config.action_repeat,
        "normalize": config.normalize,
        "perturb": config.perturb,
        "smooth": config.smooth,
        "init": None
        if source is None
        else {
            "from": str(source_folder),
            "checkpoint": None if checkpoint is None else checkpoint * config.action_repeat,
            "env_id": source["env_id"],
            "steps": source["steps"],
            "init": source.get("init"),
            "replay_buffer": buffer_from,
        },
        "command": command_line("train.py"),
        "train_wall_s": wall,
        "final_evaluation": log.rows[-1],
        "kept": dict(kept) if kept else None,
        "versions": {
            "python": platform.python_version(),
            "stable_baselines3": stable_baselines3.__version__,
            "torch": torch.__version__,
            "numpy": np.__version__,
        },  # fmt: skip
    }
    (out / "config.json").write_text(json.dumps(record, indent=2, default=str))
    return record


@contextlib.contextmanager
def stop_on_sigterm() -> Iterator[None]:
    """SIGTERM raises ``KeyboardInterrupt`` in the main thread while the block runs (so a run stopped by a job's time
    limit saves its agent and record as a Ctrl-C does); the previous handler is restored after it. Elsewhere than
    in the main thread, nothing changes."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def load_agent(folder: pathlib.Path) -> tuple[Any, dict[str, Any]]:
    """An agent saved by :func:`train` and its ``config.json``.

    A residual agent comes back as a :class:`~mbs_envs.studies.residual.ResidualPolicy`
    around its base controller, built on the nominal env of its record with
    the gains it was trained with; an agent trained with ``action_repeat > 1`` as a
    :class:`~mbs_envs.studies.held.HeldPolicy` holding its decisions as in training, or every
    ``"evaluated_action_repeat"`` control steps where its record says so (an agent shipped to decide at another
    interval: :mod:`mbs_envs.studies.dfki_selection`).
    """
    folder = pathlib.Path(folder)
    record = json.loads((folder / "config.json").read_text())
    model = ALGOS[record["algo"]].load(folder / "agent.zip", device="cpu")
    residual = record.get("residual")
    normalization = ObsNormalization.load(folder) if record.get("normalize") else None
    if residual:
        base = make_controller(
            residual["base"], gym.make(record["env_id"], **record.get("env_kwargs", {})), residual.get("gains")
        )
        return as_evaluated(model, 1, base, residual["bound"], normalization), record
    repeat = record.get("evaluated_action_repeat") or record.get("action_repeat", 1)
    return as_evaluated(model, repeat, None, 0.0, normalization), record


def as_evaluated(
    model: Any, action_repeat: int, base: Any, bound: float, normalization: ObsNormalization | None
) -> Any:
    """The trained ``model`` as it is evaluated: on normalized observations if it trained on them,
    as the bounded correction of ``base`` (a residual agent), holding its decisions for
    ``action_repeat`` steps."""
    policy = model if normalization is None else NormalizedPolicy(model, normalization)
    if base is not None:
        policy = ResidualPolicy(base, policy, bound)
    return HeldPolicy(policy, action_repeat) if action_repeat > 1 else policy


#: an off-policy run's replay buffer, saved beside its agent (and with each checkpoint) for a run that continues it
REPLAY_BUFFER = "replay_buffer.pkl"
#: the files of a trained agent's folder that ship with it (checkpoints, the replay buffer and TensorBoard logs stay
#: behind)
SHIPPED_FILES = ("agent.zip", "config.json", "training_log.csv", "normalization.npz")


def ship(src: pathlib.Path, dst: pathlib.Path, checkpoint: int | None = None, kept: Mapping[str, Any] | None = None,
         evaluated_action_repeat: int | None = None) -> int:  # fmt: skip
    """Copy the agent saved by :func:`train` in ``src`` to ``dst`` without its optimizers' state (a continued run with
    the whole chain's training log and, as ``"total"`` in ``config.json``, its budget: :func:`whole_log`).

    ``checkpoint`` (control steps) ships that checkpoint of the run instead of its ``agent.zip``, with ``kept`` (why it
    was chosen) recorded as ``"kept"``; ``evaluated_action_repeat`` makes :func:`load_agent` hold its decisions that
    many control steps instead of the training's action repeat. The budget stays the whole run's (every step spent).

    The network weights (all of them, so SB3 loads the agent as usual), configuration, training
    log and normalization are kept; the Adam moments of every optimizer are dropped, which is a
    third to a half of an off-policy agent's file and plays no part in acting. A run continued
    from a shipped agent (``TrainConfig.init``) starts its optimizers afresh; ``config.json``
    records ``"shipped_without_optimizer_state": true``.

    Returns
    -------
    int
        The size of the shipped ``agent.zip`` [bytes].
    """
    import shutil

    import torch
    from stable_baselines3.common.save_util import recursive_getattr

    src, dst = pathlib.Path(src), pathlib.Path(dst)
    record = json.loads((src / "config.json").read_text())
    agent, extra = src / "agent.zip", {}
    if checkpoint is not None:
        repeat = record.get("action_repeat", 1)
        agent = src / "checkpoints" / f"agent_{int(checkpoint) // repeat}_steps.zip"
        if int(checkpoint) % repeat or not agent.exists():
            raise ValueError(f"checkpoint: {src} has no checkpoint at {checkpoint} control steps")
        extra["kept"] = {"checkpoint": int(checkpoint), **(kept or {})}
    elif kept is not None:
        raise ValueError("kept: only with a checkpoint (a run's own agent.zip keeps its training's record)")
    if evaluated_action_repeat is not None:
        from ..envs.sb3 import check_action_repeat

        extra["evaluated_action_repeat"] = check_action_repeat(evaluated_action_repeat)
    model = ALGOS[record["algo"]].load(agent, device="cpu")
    for name in model._get_torch_save_params()[0]:  # the state dicts SB3 saves: "policy", "<net>.optimizer", ...
        module = recursive_getattr(model, name)
        if isinstance(module, torch.optim.Optimizer):
            module.state.clear()
    dst.mkdir(parents=True, exist_ok=True)
    model.save(dst / "agent.zip")
    for name in SHIPPED_FILES[2:]:
        if (src / name).exists():
            shutil.copyfile(src / name, dst / name)
    rows, budget = whole_log(src)
    chain = {}
    if budget["runs"] > 1:  # a continued run ships its whole learning curve, the runs it continues first
        write_log(dst / "training_log.csv", rows)
        chain = {"total": budget}
    (dst / "config.json").write_text(
        json.dumps({**record, **extra, "shipped_without_optimizer_state": True, **chain}, indent=2, default=str)
    )
    return (dst / "agent.zip").stat().st_size


def whole_log(folder: pathlib.Path) -> tuple[list[dict], dict]:
    """The evaluations of the run in ``folder`` preceded by those of the runs it continues (``config.json``'s
    ``init``, followed while its folder is at hand), each later run's control steps and wall time counted on from
    where the one before ended, with the run's place in the chain in a column ``run`` (0 the first); and the
    chain's budget ``{"steps", "train_wall_s", "runs", "commands"}`` (each run's command, the first first)."""
    folder = pathlib.Path(folder)
    record = json.loads((folder / "config.json").read_text())
    source = (record.get("init") or {}).get("from")
    rows, budget = (
        whole_log(pathlib.Path(source)) if source and (pathlib.Path(source) / "config.json").exists() else ([], {})
    )
    steps0, wall0, run = budget.get("steps", 0), budget.get("train_wall_s", 0.0), budget.get("runs", 0)
    if (folder / "training_log.csv").exists():
        with open(folder / "training_log.csv", newline="") as f:
            for r in csv.DictReader(f):
                r.pop("run", None)
                rows.append({"run": run, **r, "timesteps": steps0 + int(float(r["timesteps"])),
                             "train_wall_s": wall0 + float(r["train_wall_s"])})  # fmt: skip
    return rows, {"steps": steps0 + int(record["steps"]), "train_wall_s": wall0 + float(record["train_wall_s"]),
                  "runs": run + 1, "commands": [*budget.get("commands", []), record.get("command")]}  # fmt: skip
