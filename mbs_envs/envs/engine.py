"""The compiled backend of the environments' step: one numba function for B members.

:meth:`MBSEnv.step <mbs_envs.envs.base.MBSEnv.step>` (B = 1) and the vector env
(B = ``num_envs``) call the same function, a scene's ``step_kernel``: a
module-level binding of :func:`engine_step` to its model's kernels and its task's
kernel (bound at compile time and cached on disk, see :mod:`mbs_envs.dynamics.compiled`).
The sequence is :meth:`MBSEnv.step`'s numpy one:

1. ``u = action * u_max`` held, ``B u`` applied (``B`` selects one coordinate per input);
2. physics: the model's ``advance_kernel`` (explicit Runge-Kutta, with a
   constrained model's projection after every step);
3. divergence: non-finite, ``|x| > limit``, a singular configuration, or a
   constraint residual beyond ``residual_limit``; a diverged member keeps its state;
4. ``t += dt``; the task's kernel writes the observation, the reward and its
   terms, its ``info`` quantities and its termination;
5. the model's energy (unless ``full`` is False), and for constrained models the constraint residual and
   the multipliers (unless ``full`` is False), complete ``info``.

Arguments are packed tuples (no long positional lists):

- ``control = (dt, limit, residual_limit, u_max, actuated, nc, full)``; ``full`` False skips the
  energy and the multipliers (their ``info`` columns NaN), which no step needs (the constraint-info
  kernel is then given ``lam`` with no rows: it computes the residual only);
- ``task``: the task's own tuple (its static arguments, then its per-member
  columns; see the task's ``task_arguments`` and ``task_columns``);
- ``state = (q, v, t, action)``: columns ``(n, B)``, ``(n, B)`` (C-contiguous) and ``(B,)``, updated
  in place, and the validated action in rows ``(B, nu)``;
- ``out = (u, obs, info, bad, terminated)``, written: ``u`` ``(nu, B)``, ``obs``
  ``(obs_dim, B)`` float32 and ``info`` ``(S, B)`` float64 in columns, one per member (the env
  returns their transposes), ``info``'s rows those of the env's
  :meth:`~mbs_envs.envs.base.MBSEnv.info_layout` (the task's, starting with the reward, then
  ``energy``, then for constrained models ``constraint_residual`` and ``multipliers``);
  ``bad, terminated`` ``(B,)``.

A task kernel has the signature ``task_step(q, v, t, action, task, obs, info, terminated)``
with ``q, v`` in columns ``(n, B)``, ``action`` in columns ``(nu, B)``, and writes
its rows of ``info`` (from 0), ``obs`` and ``terminated``.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.jit import njit


@njit(cache=False, inline="always")  # takes kernels as arguments: cached inside the scenes' module-level bindings
def engine_step(
    advance, energy, constraint_info, singular, task_step, theta, stepper, control, task, state, out
):  # pragma: no cover
    """One control step of every member (module docstring).

    Parameters
    ----------
    advance, energy, constraint_info, singular : compiled kernels of the model
        ``advance(theta, stepper, q, v, tau)``, ``energy(q, v, theta, E)``,
        ``constraint_info(q, v, tau, theta, residual, lam)``, ``singular(q, flags)``.
    task_step : compiled kernel of the task
    theta : ndarray, shape (P, B)
        The model's parameters in columns (:func:`mbs_envs.dynamics.compiled.batch_theta`).
    stepper : tuple
        :meth:`mbs_envs.dynamics.compiled.TableauArrays.packed`.
    control, task, state, out : tuple
        See the module docstring.
    """
    dt, limit, residual_limit, u_max, actuated, nc, full = control
    q, v, t, action = state
    u, obs, info, bad, terminated = out
    n, B = q.shape
    q0, v0 = q.copy(), v.copy()  # what a diverged member keeps
    ac = np.ascontiguousarray(action.T)
    tau = np.zeros((n, B))
    for k in range(u.shape[0]):  # every loop below runs along a row: SIMD over the members
        ak, uk, tk, m = ac[k], u[k], tau[actuated[k]], u_max[k]
        for b in range(B):
            x = ak[b] * m
            uk[b] = x
            tk[b] = x
    advance(theta, stepper, q, v, tau)
    residual, lam = np.empty(B), np.empty((B if full else 0, nc))  # lam without rows: the residual only
    constraint_info(q, v, tau, theta, residual, lam)
    flags = np.zeros(B, np.bool_)
    singular(q, flags)
    ok = np.ones(B, np.bool_)
    for k in range(n):
        qk, vk = q[k], v[k]
        for b in range(B):
            ok[b] &= (abs(qk[b]) <= limit) & (abs(vk[b]) <= limit)
    reverted = False
    for b in range(B):
        ok[b] &= (residual[b] <= residual_limit) & (not flags[b])
        bad[b] = not ok[b]
        reverted |= not ok[b]
        t[b] = t[b] + dt
    if reverted:  # diverged members keep their states, and the info is of the states kept
        for k in range(n):
            for b in range(B):
                if not ok[b]:
                    q[k, b] = q0[k, b]
                    v[k, b] = v0[k, b]
        constraint_info(q, v, tau, theta, residual, lam)
    task_step(q, v, t, ac, task, obs, info, terminated)
    c = info.shape[0] - 1 - (1 + nc if nc > 0 else 0)
    E = info[c]
    if full:
        energy(q, v, theta, E)
    else:
        for b in range(B):
            E[b] = np.nan
    for b in range(B):
        terminated[b] |= bad[b]
    if nc > 0:
        r = info[c + 1]
        for b in range(B):
            r[b] = residual[b]
        for i in range(nc):
            li = info[c + 2 + i]
            if full:
                for b in range(B):
                    li[b] = lam[b, i]
            else:  # not computed (lam has no rows)
                for b in range(B):
                    li[b] = np.nan
