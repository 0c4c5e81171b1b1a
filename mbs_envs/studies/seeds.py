"""Which seeds serve which purpose: disjoint ranges for training, tuning and testing.

A comparison is only fair if nothing was fitted on the episodes it is scored
on. Every integer passed to ``reset(seed=...)`` by the project's studies comes
from one of these ranges:

- **test** ``[0, 10_000)``: the comparison report (``scripts/compare.py`` takes
  the first ``n``);
- **validation** ``[10_000, 20_000)``: the learning curves recorded while an
  agent trains (:class:`mbs_envs.studies.training.TrainingLog`);
- **tuning** ``[20_000, 30_000)``: the gain search of the model-based
  controllers (:mod:`mbs_envs.studies.tuning`);
- **training** ``[100_000, ...)``: the members of a training run's vector env;
  run ``k`` seeds member ``i`` with ``100_000 + 1_000 k + i`` at its first reset
  (later episodes come from each member's generator, not from integer seeds).
"""

from __future__ import annotations

TEST = range(0, 10_000)
VALIDATION = range(10_000, 20_000)
TUNING = range(20_000, 30_000)
TRAINING_BASE = 100_000
#: members of one training run at most (keeps the runs' ranges apart)
MAX_MEMBERS = 1_000


def _take(block: range, n: int, name: str) -> list[int]:
    if not (isinstance(n, int) and 0 < n <= len(block)):
        raise ValueError(f"n must be an integer in [1, {len(block)}] for {name} seeds, got {n!r}")
    return list(block[:n])


def test_seeds(n: int) -> list[int]:
    """The first ``n`` test seeds."""
    return _take(TEST, n, "test")


def validation_seeds(n: int) -> list[int]:
    """The first ``n`` validation seeds (learning curves)."""
    return _take(VALIDATION, n, "validation")


def tuning_seeds(n: int) -> list[int]:
    """The first ``n`` tuning seeds (gain search)."""
    return _take(TUNING, n, "tuning")


def training_members(run_seed: int, n_envs: int) -> list[int]:
    """Seeds of the ``n_envs`` members of training run ``run_seed`` at their first reset."""
    if not (isinstance(run_seed, int) and run_seed >= 0):
        raise ValueError(f"run seed must be an integer >= 0, got {run_seed!r}")
    if not (isinstance(n_envs, int) and 0 < n_envs <= MAX_MEMBERS):
        raise ValueError(f"n_envs must be an integer in [1, {MAX_MEMBERS}], got {n_envs!r}")
    start = TRAINING_BASE + MAX_MEMBERS * run_seed
    return list(range(start, start + n_envs))
