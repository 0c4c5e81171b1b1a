"""Starts drawn ahead: a vector env's autoresets take each member's next start from a batch drawn earlier.

An autoreset resets a few members per step. Drawn then, every reset would pay the fixed cost of the
task's batched code (reference, projection, checks, observation: some hundred numpy calls) for two or
three members. Instead :class:`StartsAhead` draws the *next* start of many members in one batch
(:meth:`~mbs_envs.envs.base.MBSEnv.draw_starts`, checked by ``_check_start``) and an autoreset copies
the member's start from it.

Nothing observable changes. Member ``i``'s generator is used for its resets only, in the order of its
episodes: drawing episode ``k + 1``'s numbers right after episode ``k``'s gives the very numbers a reset
would draw later. What can make an early draw wrong is undone exactly: a member with a start ahead
keeps its generator's state from before that draw (``before``), and everything that would draw
differently -- a reset with options or a new seed, a setting changed since (the key of
:meth:`StartsAhead.key`) -- first *rewinds* the generator to it. A start the task would refuse is not
kept (the member is marked refused and its generator rewound): its autoreset then draws as before,
and raises as before.

States of a member: *none* (no start ahead; generator as without the lookahead), *ready* (a start ahead;
generator past its draws, ``before[i]`` its state before them), *refused* (the start drawn was refused;
generator rewound).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import validation as check
from ..dynamics.jit import njit
from .stacking import tree_assign, tree_leaves, tree_pick

NONE, READY, REFUSED = 0, 1, 2


class StartsAhead:
    """The next start of each member of a vector env (see the module docstring).

    Parameters
    ----------
    n : int
        Members.
    """

    #: the members without a start ahead are drawn as one batch once this many (or a quarter of all)
    #: have none, or sooner when an autoreset needs one
    BATCH = 256
    #: at most this many starts are drawn ahead in one call (a batch of a million members draws as its
    #: autoresets need, not a million starts at the first)
    MOST = 4096

    def __init__(self, n: int):
        self.n = n
        self.status = np.zeros(n, np.int8)
        self.n_none = n  # members with status none
        self.taken = 0  # starts taken by autoresets (diagnostics: the share of resets served ahead)
        self.before: list[Any] = [None] * n  # generator states before the draws of a ready start
        self.key: tuple | None = None
        self.q = self.v = self.obs = None
        self.task: Any = None
        self.columns: tuple | None = None
        self.scales: dict[str, np.ndarray] = {}

    def __getstate__(self) -> dict:
        """Copies and pickles leave out the cached views (:meth:`_pairs`): a copied view would no longer
        be a view of the copied arrays."""
        state = dict(self.__dict__)
        state.pop("_pairs_cache", None)
        return state

    @staticmethod
    def key_of(venv: Any) -> tuple:
        """What the starts depend on besides the generators: the task env's settings."""
        env = venv.env
        return (check.settings_version(env), float(env.residual_limit), float(env.divergence_limit))

    # -- undoing ---------------------------------------------------------------------

    def rewind(self, venv: Any, members: np.ndarray) -> list[tuple[int, Any]]:
        """Members ``members`` get no start ahead, their generators as without the lookahead. Returns what
        :meth:`unrewind` needs to undo this (a refused reset must change nothing)."""
        undo = []
        for i in members[self.status[members] != NONE]:
            i = int(i)
            if self.status[i] == READY:
                g = venv._rngs[i]
                undo.append((i, g.bit_generator.state, self.before[i], READY))
                g.bit_generator.state = self.before[i]
            else:
                undo.append((i, None, None, REFUSED))
            self.status[i], self.before[i] = NONE, None
        self.n_none += len(undo)
        return undo

    def unrewind(self, venv: Any, undo: list) -> None:
        """Undo :meth:`rewind` (its return value)."""
        for i, after, before, status in undo:
            if status == READY:
                venv._rngs[i].bit_generator.state = after
            self.status[i], self.before[i] = status, before
        self.n_none -= len(undo)

    def validate(self, venv: Any) -> None:
        """Rewind every member if a setting changed since the starts ahead were drawn."""
        key = self.key_of(venv)
        if key != self.key:
            self.rewind(venv, np.arange(self.n))
            self.key = key

    # -- drawing ahead -----------------------------------------------------------------

    def fill(self, venv: Any, members: np.ndarray) -> None:
        """Draw the next start of ``members`` (status none) as one batch; a batch the task refuses is
        drawn member by member, the refused ones marked so."""
        gens = [venv._rngs[i] for i in members]
        before = [g.bit_generator.state for g in gens]
        try:
            scales, model = venv._draw_member_params(members)
            task, q0, v0 = venv.env.draw_starts({}, gens, model)
            obs = venv.env._check_start(q0, v0, task, False)
        except ValueError:
            for g, state in zip(gens, before):
                g.bit_generator.state = state
            if len(members) == 1:
                self.status[members[0]] = REFUSED
                self.n_none -= 1
            else:
                for i in members:
                    self.fill(venv, np.array([i]))
            return
        if self.q is None:  # the first fill: arrays for every member (the state in columns, as the batch's)
            self.q, self.v = np.zeros((q0.shape[-1], self.n)), np.zeros((v0.shape[-1], self.n))
            self.obs = np.zeros((self.n,) + obs.shape[1:], obs.dtype)
            self.task = tree_pick(venv._task, slice(None))
            self.scales = {k: s.copy() for k, s in venv._scales.items()}
        self.q[:, members], self.v[:, members], self.obs[members] = q0.T, v0.T, obs
        tree_assign(self.task, members, task)
        for k, s in scales.items():
            self.scales[k][members] = s
        if self.columns is not None:
            for whole, part in zip(self.columns, venv.env.task_columns(task)):
                whole[..., members] = part
        self.status[members] = READY
        self.n_none -= len(members)
        for i, state in zip(members.tolist(), before):
            self.before[i] = state

    def ready(self, venv: Any, idx: np.ndarray) -> np.ndarray:
        """Make sure members ``idx`` have had their start drawn ahead (filling them, with up to :attr:`MOST`
        other members without one, in one batch); return the mask of those whose start is ready."""
        self.validate(venv)
        status = self.status[idx]
        if np.any(status == NONE):
            self.fill(venv, self._none_first(idx[status == NONE]))
            status = self.status[idx]
        return status == READY

    def _none_first(self, needed: np.ndarray) -> np.ndarray:
        """``needed`` and other members without a start ahead, at most :attr:`MOST` in all (``needed`` always)."""
        others = np.flatnonzero(self.status == NONE)
        others = others[~np.isin(others, needed)][: max(0, self.MOST - len(needed))]
        return np.sort(np.concatenate([needed, others]))

    def top_up(self, venv: Any) -> None:
        """Draw ahead for the members without a start once there are enough of them for one batch."""
        if self.n_none >= min(self.BATCH, max(1, self.n // 4)):
            self.validate(venv)
            self.fill(venv, np.flatnonzero(self.status == NONE)[: self.MOST])

    # -- taking ----------------------------------------------------------------------

    def take(self, venv: Any, members: np.ndarray) -> np.ndarray:
        """Start the ready ``members`` from their starts ahead (their generators are already past the
        draws, as after a reset); return their first observations."""
        rows, columns = self._pairs(venv)
        for whole, ahead in rows:
            copy_rows(whole, ahead, members)
        for whole, ahead in columns:
            copy_columns(whole, ahead, members)
        self.status[members] = NONE
        self.n_none += len(members)
        self.taken += len(members)
        for i in members.tolist():
            self.before[i] = None
        return self.obs[members]

    def _pairs(self, venv: Any) -> tuple[list, list]:
        """``(the batch's array, the starts' array)`` of every per-member array a start sets, as 2-D views:
        members in rows (task leaves, randomization scales) or in columns (the state, the compiled task
        columns); kept while the batch's arrays are the same objects."""
        c = self.__dict__.get("_pairs_cache")
        key = (venv._task, venv._task_columns, venv._scales, venv._qc, venv._vc)
        if c is None or any(a is not b for a, b in zip(c[0], key)):
            if venv._task_columns is not None and self.columns is None:
                self.columns = venv.env.task_columns(self.task)
            n = self.n
            rows = [
                (_view(w, (n, -1)), _view(a, (n, -1))) for w, a in zip(tree_leaves(venv._task), tree_leaves(self.task))
            ]
            rows += [(_view(venv._scales[k], (n, 1)), _view(self.scales[k], (n, 1))) for k in venv._scales]
            columns = [(venv._qc, self.q), (venv._vc, self.v)]
            if venv._task_columns is not None:
                columns += [(_view(w, (-1, n)), _view(a, (-1, n))) for w, a in zip(venv._task_columns, self.columns)]
            c = self._pairs_cache = (key, (rows, columns))
        return c[1]


def _view(x: np.ndarray, shape: tuple) -> np.ndarray:
    """``x.reshape(shape)``, which must be a view (a copy would take the starts' values and drop them)."""
    v = x.reshape(shape)
    if not np.may_share_memory(v, x):
        raise RuntimeError(f"a per-member array of shape {x.shape} is not contiguous: its 2-D form would be a copy")
    return v


@njit
def copy_rows(dst, src, members):  # pragma: no cover - compiled
    """``dst[members] = src[members]`` of 2-D arrays (one compiled call instead of numpy's fancy indexing)."""
    for i in members:
        for j in range(dst.shape[1]):
            dst[i, j] = src[i, j]


@njit
def copy_columns(dst, src, members):  # pragma: no cover - compiled
    """``dst[:, members] = src[:, members]`` of 2-D arrays."""
    for j in range(dst.shape[0]):
        for i in members:
            dst[j, i] = src[j, i]
