"""Hyperparameter search of the RL agents, the counterpart of the controllers' gain search.

The model-based controllers get their gains from a grid rolled out on the tuning
seeds (:mod:`mbs_envs.studies.tuning`); an agent gets the same care here: a grid of
hyperparameter overrides (:attr:`mbs_envs.studies.training.TrainConfig.hyper`, e.g.
the discount ``gamma`` or the entropy coefficient) and training settings
(:data:`SETTINGS`: the action repeat), one training run per candidate
(training seed ``seed``, i.e. its members' seeds from the training range), each
scored by its last evaluation on the **validation seeds**, never on the test seeds of
the comparison. Candidates are ranked like the controllers' (lexicographically):

    (failure rate, the scene's error metric over the episodes that did not fail, -return)

with the failure and the error as the scene's scoring defines them
(:data:`mbs_envs.studies.evaluation.SCORING`): on a swing-up scene a failure is an
episode not ending upright and the error the time to swing up. The return breaks ties
between candidates that all fail (it is what the agent maximizes).

Requires the ``rl`` extra.
"""

from __future__ import annotations

import itertools
import math
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

from ..envs import registry
from .evaluation import ERROR_METRIC
from .parallel import run_tasks
from .training import TrainConfig, train


#: grid keys that are training settings (:class:`~mbs_envs.studies.training.TrainConfig` fields), not SB3 arguments
SETTINGS = ("action_repeat",)


def candidate_config(hyper: Mapping[str, float]) -> dict[str, Any]:
    """The :class:`TrainConfig` fields of one grid candidate: its :data:`SETTINGS` as
    fields, the rest as ``hyper`` overrides (``{"action_repeat": 8, "gamma": 0.99}`` ->
    ``{"action_repeat": 8, "hyper": {"gamma": 0.99}}``)."""
    fields: dict[str, Any] = {k: v for k, v in hyper.items() if k in SETTINGS}
    return {**fields, "hyper": {k: v for k, v in hyper.items() if k not in SETTINGS}}


def agent_grid(spec: Mapping[str, Sequence[float]]) -> list[dict[str, float]]:
    """Every combination of the values in ``spec`` (``{"gamma": [0.99, 0.998]}`` -> two candidates)."""
    if not spec:
        raise ValueError("the grid needs at least one hyperparameter with values")
    for key, values in spec.items():
        if len(values) == 0:
            raise ValueError(f"grid: {key!r} has no values")
    keys = list(spec)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(spec[k] for k in keys))]


def rank_key(evaluation: Mapping[str, float], env_id: str) -> tuple[float, float, float]:
    """Sort key of a candidate's final evaluation (module docstring); NaN errors rank last."""
    error = evaluation[ERROR_METRIC[registry.scene(env_id).scoring]]
    return (evaluation["failure_rate"], error if math.isfinite(error) else math.inf, -evaluation["return"])


def _train_candidate(task: dict[str, Any]) -> dict[str, Any]:
    return train(
        TrainConfig(**task["config"]), pathlib.Path(task["out"]), overwrite=True
    )  # a re-run of a search replaces its candidates


def tune_agent(env_id: str, algo: str, steps: int, grid: list[dict[str, float]], out: pathlib.Path, seed: int = 0,
               eval_seeds: int = 20, workers: int | None = None, **config: Any) -> tuple[dict[str, float], list[dict[str, Any]]]:  # fmt: skip
    """Train one agent per candidate of ``grid`` and pick the best (module docstring).

    Parameters
    ----------
    env_id, algo, steps, seed
        As in :class:`~mbs_envs.studies.training.TrainConfig`; every candidate trains
        with the same ones.
    grid : list of dict
        Hyperparameter overrides, e.g. from :func:`agent_grid`.
    out : path
        Candidate ``k`` trains into ``out/candidate<k>``.
    eval_seeds : int
        Validation episodes of each evaluation.
    **config
        Further :class:`TrainConfig` fields (``n_envs``, ``net_arch``, ...).

    Returns
    -------
    best : dict
        The chosen overrides.
    rows : list of dict
        One per candidate: its overrides, its final evaluation, training wall time and folder.
    """
    out = pathlib.Path(out)
    tasks = []
    for k, hyper in enumerate(grid):
        cfg = dict(
            env_id=env_id, algo=algo, steps=steps, seed=seed, eval_seeds=eval_seeds, **candidate_config(hyper), **config
        )
        TrainConfig(**cfg)  # validate every candidate before training any
        tasks.append({"config": cfg, "out": str(out / f"candidate{k}")})
    records = run_tasks(_train_candidate, tasks, max_workers=workers)
    rows = [{"candidate": k, "hyper": dict(hyper), "folder": task["out"], "train_wall_s": r["train_wall_s"], **r["final_evaluation"]}
            for k, (hyper, task, r) in enumerate(zip(grid, tasks, records))]  # fmt: skip
    best = min(rows, key=lambda row: rank_key(row, env_id))
    return dict(best["hyper"]), rows
