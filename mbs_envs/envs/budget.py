"""The budgets an environment is made within: the work of one control step (:func:`step_work`, at most
:data:`STEP_WORK_BUDGET`), the work of a batch (:data:`BATCH_WORK_BUDGET`), the number of members
(:data:`MAX_MEMBERS`) and the memory of a batch (:func:`memory_per_member` against :func:`memory_budget`);
:func:`check_work_budget` refuses a make beyond them with a ``ValueError`` that names the budget.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dynamics import integrators


#: The work budget of one member's control step, in equation-of-motion evaluations times degrees
#: of freedom (:func:`step_work`). 2e6 is about a second of the numpy path (~5 us per 2-dof evaluation)
#: and well above every setting the studies use (the largest: RK4 x 40 substeps on the 2R, 320;
#: a 500-link chain under RK4, 2,000); SDIRK3 with 1e5 substeps on the 2R (1.4e7) took minutes per step.
STEP_WORK_BUDGET = 2e6
#: The work budget of one batched step (members x :func:`step_work`): 1e6 members of the 2R under RK4.
BATCH_WORK_BUDGET = 2e8
#: The most members a batched env holds: each keeps its own generator (~1 kB) besides its state.
MAX_MEMBERS = 2**20


#: the environment variable that sets the memory budget of a batched env [bytes] (default: half the machine's memory)
MEMORY_BUDGET_VAR = "MBS_ENVS_MEMORY_BUDGET"


def memory_budget() -> float:
    """The bytes a batched env may take: ``MBS_ENVS_MEMORY_BUDGET`` if set (a number of bytes, e.g. ``8e9``), else half
    of the machine's physical memory.

    Raises
    ------
    ValueError
        If the variable is set to something other than a positive number.
    """
    import os

    text = os.environ.get(MEMORY_BUDGET_VAR, "").strip()
    if text:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not (0 < value < float("inf")):
            raise ValueError(f"{MEMORY_BUDGET_VAR} must be a positive number of bytes, got {text!r}")
        return value
    return 0.5 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def memory_per_member(nq: int, nv: int, obs_dim: int) -> float:
    """An upper estimate of a batched env's bytes per member while it steps: ``1.5 (1500 + 64 (nq + nv + obs_dim))``.

    Measured on every kind of scene (RSS after reset and three steps of 4,000-20,000 members, beyond that of 8):
    2.1-2.5 kB for the 2R, four-bar, disk and cart-pole (the formula 2.5-2.8 kB before the factor), 32-51 kB for the
    100-link chains (52.7 kB); the factor 1.5 covers the reset's transient peak and other batch sizes.
    """
    return 1.5 * (1500.0 + 64.0 * (nq + nv + obs_dim))


def step_work(integrator: Any, substeps: int, nv: int) -> float:
    """Equation-of-motion evaluations per control step times ``nv`` (the work of one member's step).

    Explicit Runge-Kutta: ``substeps x stages``; implicit (SDIRK, implicit Euler): each stage counts
    its Newton iterations (``max_iter``) times the ``1 + nv`` evaluations of a finite-difference
    Jacobian; the joint-implicit Euler 8 iterations of ``1 + nv``; the adaptive scipy methods choose
    their own steps (counted as one evaluation per substep: their cost is the tolerance's business).
    """
    tableau = getattr(integrator, "tableau", None)
    stages = len(tableau.c) if tableau is not None else 1
    iterations = getattr(integrator, "max_iter", None)
    if iterations is not None:
        stages *= iterations * (1 + nv)
    elif isinstance(integrator, integrators.JointImplicitEuler):
        stages = 8 * (1 + nv)
    return float(substeps) * stages * nv


def check_work_budget(env: Any, num_envs: int = 1) -> None:
    """Refuse settings whose control step would exceed :data:`STEP_WORK_BUDGET` (one member) or, for
    ``num_envs`` members, :data:`BATCH_WORK_BUDGET`, :data:`MAX_MEMBERS` or the memory budget
    (:func:`memory_budget`, :func:`memory_per_member`): a ``ValueError`` stating the budget and the settings that
    break it."""
    work = step_work(env.integrator, env.substeps, env.model.nv)
    if work > STEP_WORK_BUDGET:
        raise ValueError(
            f"substeps = {env.substeps} with integrator {type(env.integrator).__name__} on {env.model.nv} dof is "
            f"{work:.3g} evaluations x dof per control step, above the work budget of {STEP_WORK_BUDGET:.0e} "
            f"(mbs_envs.envs.budget.STEP_WORK_BUDGET); use fewer substeps or a cheaper integrator"
        )
    if num_envs > MAX_MEMBERS:
        raise ValueError(
            f"num_envs = {num_envs} is above the budget of {MAX_MEMBERS} members (mbs_envs.envs.budget.MAX_MEMBERS)"
        )
    if num_envs * work > BATCH_WORK_BUDGET:
        raise ValueError(
            f"num_envs = {num_envs} members x {work:.3g} evaluations x dof per step is {num_envs * work:.3g}, above the "
            f"batch work budget of {BATCH_WORK_BUDGET:.0e} (mbs_envs.envs.budget.BATCH_WORK_BUDGET); use fewer members or substeps"
        )
    if num_envs > 1:
        need = num_envs * memory_per_member(env.model.nq, env.model.nv, int(np.prod(env.observation_space.shape)))
        budget = memory_budget()
        if need > budget:
            raise ValueError(
                f"num_envs = {num_envs} members of {type(env).__name__} ({env.model.nq} coordinates) would need about "
                f"{need / 2**30:.3g} GiB, above the memory budget of {budget / 2**30:.3g} GiB (half the machine's memory, "
                f"or {MEMORY_BUDGET_VAR} in bytes); use fewer members"
            )
