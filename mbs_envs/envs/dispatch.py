"""The compiled step of one environment: :class:`StepDispatch`, which kernel runs and with which arguments.

An :class:`~mbs_envs.envs.base.MBSEnv` steps through its scene's compiled kernel
(:func:`mbs_envs.envs.engine.engine_step` bound to the model's and the task's kernels) when the scene declares one
and the model, the integrator and the stabilization allow it (:meth:`StepDispatch.tableau`). Building the kernel's
arguments costs more than a small scene's step, so the dispatch keeps them, each under the objects it was built
from, and builds them again only when one of those is replaced:

- the tableau: under the integrator, the stabilization and the model;
- the stepper and the control tuple: under the tableau, the stabilization, the actuated coordinates and the
  settings' version (:func:`mbs_envs.validation.settings_version`);
- a single env's entry point (the kernel's overload called directly, :func:`mbs_envs.dynamics.background.entry`):
  under the parameter column, the stepper, the control tuple and the task's arguments and columns, and, while the
  kernel compiles in the background, the background's generation.

The path of an action: ``MBSEnv.step`` -> :meth:`StepDispatch.run` -> the kernel; nothing here calls back into the
env except to read its settings and its task's layout.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from .. import validation as check
from ..dynamics import background
from ..dynamics.compiled import TableauArrays, batch_theta, compiled_stepping, projection_tol


class InfoColumn(NamedTuple):
    """One named entry of the step's ``info`` array: its first column, its width (None: a scalar), boolean or not."""

    name: str
    column: int
    width: int | None
    boolean: bool


def info_columns(layout: tuple[tuple[str, int | None, bool], ...]) -> tuple[int, tuple[InfoColumn, ...]]:
    """``(width, columns)`` of an ``info`` layout ``((name, width, boolean), ...)``: the array's total width and
    each entry's :class:`InfoColumn`, the reward (the first entry) left out."""
    columns, c = [], 0
    for name, w, boolean in layout:
        columns.append(InfoColumn(name, c, w, boolean))
        c += 1 if w is None else w
    return c, tuple(columns[1:])


class StepDispatch:
    """The compiled step of ``env`` and the arguments it keeps (module docstring).

    Parameters
    ----------
    env : MBSEnv
        Read for its settings (``model``, ``integrator``, ``stabilization``, ``dt``, ``substeps``, ``u_max``,
        ``divergence_limit``, ``residual_limit``), its scene's kernels (``step_kernel``, ``batched_step_kernel``)
        and its task's arguments and ``info`` layout.
    """

    def __init__(self, env: Any):
        self.env = env
        self._tableau: tuple | None = None
        self._arguments: tuple | None = None
        self._direct: tuple | None = None
        self._info: tuple[int, tuple[InfoColumn, ...]] | None = None
        self.actuated: np.ndarray | None = None

    def tableau(self) -> TableauArrays | None:
        """The tableau of the compiled step, or None when steps take the numpy path (see ``MBSEnv.compiled``)."""
        env = self.env
        k = self._tableau  # (integrator, stabilization, model, tableau): decided again when one is replaced
        if k is None or k[0] is not env.integrator or k[1] is not env.stabilization or k[2] is not env.model:
            k = self._tableau = (env.integrator, env.stabilization, env.model, self._decide())
        return k[3]

    def _decide(self) -> TableauArrays | None:
        env = self.env
        B = env.model.actuation
        selects = bool(np.all((B == 0) | (B == 1)) and np.all(B.sum(axis=0) == 1) and np.all(B.sum(axis=1) <= 1))
        declared = "step_kernel" in type(env).__dict__ and env.step_kernel is not None
        if not (env.wants_compiled and declared and selects):
            return None
        self.actuated = np.argmax(B, axis=0).astype(np.int64)
        return compiled_stepping(env.model, env.integrator, env.stabilization)

    def info_columns(self) -> tuple[int, tuple[InfoColumn, ...]]:
        """:func:`info_columns` of the env's ``info_layout`` (fixed at construction: computed once)."""
        if self._info is None:
            self._info = info_columns(self.env.info_layout())
        return self._info

    def info_rows(self, info: np.ndarray) -> dict[str, np.ndarray]:
        """The named entries of :meth:`run`'s ``info`` array, one row per member (``(B,)`` or ``(B, width)``)."""
        out = {}
        for name, c, w, boolean in self.info_columns()[1]:
            x = info[:, c] if w is None else info[:, c : c + w]
            out[name] = x.astype(bool) if boolean else x
        return out

    def arguments(self, tab: TableauArrays, nc: int, full_info: bool) -> tuple:
        """``(stepper, control)`` of the step kernel (:mod:`mbs_envs.envs.engine`), kept until a setting changes."""
        env = self.env
        stab, actuated = env.stabilization, self.actuated
        key = (check.settings_version(env), env.residual_limit, nc, full_info)
        c = self._arguments  # (tableau, stabilization, actuated, key, (stepper, control))
        if c is None or c[0] is not tab or c[1] is not stab or c[2] is not actuated or c[3] != key:
            stepper = tab.packed(env.dt / env.substeps, env.substeps, projection_tol(stab))
            # writable copies: compiled code takes one array type
            control = (float(env.dt), float(env.divergence_limit), float(env.residual_limit), np.array(env.u_max),
                       actuated, nc, full_info)  # fmt: skip
            c = self._arguments = (tab, stab, actuated, key, (stepper, control))
        return c[4]

    @property
    def warm(self) -> bool:
        """Whether a single env's entry point is the compiled kernel (not its Python while it compiles)."""
        return self._direct is not None and self._direct[5] is None

    def run(self, model: Any, q, v, t, task_columns: tuple, action, tab: TableauArrays | None = None,
            full_info: bool = True) -> tuple:  # fmt: skip
        """The compiled control step of a batch (a single env: one member), in place: ``MBSEnv.run_step_kernel``."""
        env = self.env
        B, nu = q.shape[1], model.nu
        tab = self.tableau() if tab is None else tab
        stepper, control = self.arguments(tab, model.nc, bool(full_info))
        buf = np.empty((nu + self.info_columns()[0], B))  # u and info: one allocation
        u, info = buf[:nu], buf[nu:]
        obs = np.empty(env.observation_space.shape + (B,), np.float32)
        flags = np.zeros((2, B), bool)
        bad, terminated = flags[0], flags[1]
        theta, task = batch_theta(model, B), env.task_arguments()
        state, out = (q, v, t, action), (u, obs, info, bad, terminated)
        if B > 1:  # compiled before the first step (its Python would loop over the members); no floating-point warnings
            kernel = env.step_kernel if env.batched_step_kernel is None else env.batched_step_kernel
            kernel(theta, stepper, control, task + task_columns, state, out)
            return obs.T, info.T, u.T, bad, terminated
        # a single env: its overload called directly (:func:`mbs_envs.dynamics.jit.direct`), looked up again when an
        # argument object changes (a setting, the model's parameters, the episode's task); the state and the outputs
        # are built above the same way every step, so their types repeat. Until the kernel is compiled, its Python
        # (the same bits, :mod:`mbs_envs.dynamics.background`), looked up again once the compiling child has answered
        d = self._direct  # (theta, stepper, control, task, task_columns, generation or None, entry, head)
        if (
            d is None or d[0] is not theta or d[1] is not stepper or d[2] is not control or d[3] is not task
            or d[4] is not task_columns or (d[5] is not None and d[5] != background.generation())
        ):  # fmt: skip
            head = (theta, stepper, control, task + task_columns)
            f, compiled = background.entry(env.step_kernel, head + (state, out))
            d = self._direct = (
                theta,
                stepper,
                control,
                task,
                task_columns,
                None if compiled else background.generation(),
                f,
                head,
            )
        d[6](*d[7], state, out)
        return obs.T, info.T, u.T, bad, terminated
