"""Stacked tasks: an episode's task state (a dataclass of arrays, or None) for many members at once.

A task drawn at reset (a reference, a commanded spin, ...) is a tree of frozen dataclasses whose
leaves are float arrays; a batch of members holds one tree whose leaves carry the members along a
new axis 0. The single env holds member 0 of a batch of one (:func:`tree_pick` with an int), so
single and vector envs draw and transform their tasks with the same code.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np


def tree_pick(task: Any, idx: np.ndarray | int) -> Any:
    """Members ``idx`` (an index array) of a stacked task, or one member in the single env's shapes
    (an int: its leaves new arrays, 0-d where the batch's are 1-d)."""
    if task is None:
        return None
    if dataclasses.is_dataclass(task):
        return type(task)(**{f.name: tree_pick(getattr(task, f.name), idx) for f in dataclasses.fields(task)})
    return np.array(task[idx])


def tree_assign(batch: Any, idx: np.ndarray, items: Any) -> None:
    """Write the stacked ``items`` (``len(idx)`` members) into members ``idx`` of ``batch``, in place."""
    if batch is None:
        return
    if dataclasses.is_dataclass(batch):
        for f in dataclasses.fields(batch):
            tree_assign(getattr(batch, f.name), idx, getattr(items, f.name))
        return
    batch[idx] = items


def tree_leaves(task: Any) -> list[np.ndarray]:
    """The arrays of a task tree, in field order (none for None)."""
    if task is None:
        return []
    if dataclasses.is_dataclass(task):
        return [x for f in dataclasses.fields(task) for x in tree_leaves(getattr(task, f.name))]
    return [task]
