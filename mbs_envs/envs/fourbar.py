"""``mbs_envs/FourBar-v0``: drive a four-bar's crank along a reference motion."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .. import validation as check
from ..dynamics import compiled as _compiled
from ..dynamics.jit import njit
from ..models import fourbar as _model
from ..models.fourbar import FourBar
from .rendering import GROUND, Dot, Line, Polygon, Shape, arm_shapes
from . import tracking as _tracking
from .base import checked_residual_limit
from .engine import engine_step
from .tracking import JointTrackingEnv


@njit
def step_kernel(theta, stepper, control, task, state, out):  # pragma: no cover - compiled
    """The compiled step of this scene: :func:`~mbs_envs.envs.engine.engine_step` with the model's
    kernels (the projection after every step, the loop residual and the multipliers)."""
    engine_step(
        _model.advance_kernel,
        _model.energy_kernel,
        _model.constraint_info_kernel,
        _compiled.never_singular,
        _tracking.tracking_task,
        theta,
        stepper,
        control,
        task,
        state,
        out,
    )


class FourBarEnv(JointTrackingEnv):
    """Four-bar linkage (a closed loop, crank driven): the crank follows a rippled spin reference.

    ## Description

    A closed-loop linkage (docs/physics.md §4): crank, coupler and rocker on a
    ground link, simulated as a DAE with Lagrange multipliers and constraint
    stabilization. Only the crank is driven. Each episode draws a crank
    reference ``th1_ref(t) = c + s t + sum_k A_k sin(w_k t + p_k)`` (mean spin
    ``s``, three ripple components) with analytic rate and acceleration; the
    crank must follow it against gravity and the configuration-dependent
    effective inertia of the whole linkage.

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: crank torque normalized by ``torque_limit``.
    Finite out-of-range actions saturate; NaN/inf or wrongly shaped actions
    raise ``ValueError``.

    ## Observation Space

    ``Box((12,), float32)``: ``[cos q (3), sin q (3), v (3), e, v_ref, a_ref]``
    with ``q = (th1, ph2, ph1)``, ``e = wrap(th1_ref - th1)``.

    ## Rewards

    ``r = -(w_e e^2 + w_de (v_ref - dth1)^2 + w_u action^2)``, default weights
    ``(1, 0.1, 0.001)``, terms in ``info``.

    ## Starting State

    Reference: ``c ~ U(-pi, pi)``, ``s ~ U(1, 4)`` rad/s, ripple amplitude
    ``U(0.5, 1) * 0.5`` rad, frequencies ``U(0.5, 3)`` rad/s. Start crank angle
    and rate at the reference plus ``U(-0.1, 0.1)``; the coupler and rocker
    close the loop on the assembly ``branch`` (+1: joint B left of the line
    from the crank tip to ``O4``) with consistent rates. A state given to
    ``reset(options={"q": ..., "v": ...})`` is projected onto the constraints,
    or refused with ``ValueError`` if it cannot be.

    ## Episode End

    Truncation after ``max_episode_steps`` (default 500, 5 s). Termination if
    the simulation diverges: non-finite or huge state, or a loop-closure
    residual beyond ``residual_limit`` [m] (``info["diverged"]``; between 1e-8 and 1).

    ## Arguments

    ``gym.make("mbs_envs/FourBar-v0", params=None, dt=0.01, integrator="rk4",
    substeps=1, stabilization="projection", torque_limit=8.0, branch=1,
    residual_limit=0.01, ...)`` plus the keywords of
    :class:`~mbs_envs.envs.tracking.JointTrackingEnv`.

    ``pd_gains``: the default gains of a PD controller on this env,
    ``J (100, 20)`` with ``J`` the mean effective crank inertia over a turn, so
    that PD has computed torque's closed-loop bandwidth at the average inertia.

    ``info`` holds ``t``, ``energy``, ``diverged``, ``constraint_residual``
    (max ``|phi|`` [m]), ``multipliers`` (force of the rocker on the coupler at
    B [N]), ``tracking_error``, ``q_ref``, the reward terms and ``u``.

    ## Version History

    - v0: initial version.
    """

    step_kernel = staticmethod(step_kernel)
    residual_limit = checked_residual_limit()

    center_low = np.array([-np.pi])
    center_high = np.array([np.pi])
    max_amplitude = np.array([0.5])
    rate_range = (1.0, 4.0)
    #: Grashof classes whose crank turns fully (the task spins it)
    turning_classes = ("crank-rocker", "double-crank")

    def __init__(
        self,
        params: Mapping[str, Any] | None = None,
        torque_limit: Any = 8.0,
        branch: int = 1,
        residual_limit: float = 0.01,
        stabilization: str = "projection",
        **kwargs: Any,
    ):
        self.branch = check.one_of(branch, "branch", (1, -1))
        # above the residual a start state may keep (consistency_tol): a lower limit would end every episode at once
        self.residual_limit = residual_limit
        model = FourBar(params)
        if model.grashof not in self.turning_classes:
            p = model.params
            raise ValueError(
                f"params: FourBar-v0 spins the crank, but l0 = {p.l0:g}, l1 = {p.l1:g}, l2 = {p.l2:g}, l3 = {p.l3:g} "
                f"make a {model.grashof} linkage whose crank cannot turn fully; the crank turns fully only in a "
                f"Grashof linkage (shortest + longest < sum of the other two) whose crank or ground link is the shortest"
            )
        super().__init__(model, torque_limit, stabilization=stabilization, **kwargs)
        th1 = np.linspace(-np.pi, np.pi, 360, endpoint=False)
        self.mean_crank_inertia = float(np.mean(self.model.effective_inertia(self.model.assemble(th1, self.branch))))
        self.joint_inertia = self.mean_crank_inertia
        self.pd_gains = (100.0 * self.mean_crank_inertia, 20.0 * self.mean_crank_inertia)

    def _state_from_tracked(self, q_t: np.ndarray, v_t: np.ndarray, model: FourBar) -> tuple[np.ndarray, np.ndarray]:
        return model.consistent_state(q_t[..., 0], v_t[..., 0], self.branch)

    def task_info(self, q, v, now, task, u) -> dict[str, Any]:
        return {**super().task_info(q, v, now, task, u), **self.constraint_info(q, v, u)}

    def _render_extent(self) -> float:
        p = self.model.params
        return 0.6 * (p.l0 + p.l1 + p.l3) + 0.5 * p.l2

    def _render_center(self, q: np.ndarray) -> tuple[float, float]:
        return (0.5 * self.model.params.l0, 0.0)

    def _drawing(self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: Any = None) -> list[Shape]:
        """The ground link and its two pivots (hatched blocks), the crank, coupler and rocker, the
        reference pose as a ghost and the crank torque."""
        l0, h = self.model.params.l0, 0.06 * self._render_extent()
        ground: list[Shape] = [Line(np.array([[0.0, 0.0], [l0, 0.0]]), GROUND, 4)]
        for x in (0.0, l0):  # pivots: a triangle on a block
            ground.append(Polygon(np.array([[x, 0.0], [x - h, -1.5 * h], [x + h, -1.5 * h]]), GROUND))
            ground.append(Line(np.array([[x - 1.6 * h, -1.5 * h], [x + 1.6 * h, -1.5 * h]]), GROUND, 3))
        q_ref = self.model.assemble(self.task_now(np.asarray(t), task)[0][0], self.branch)
        arm = arm_shapes(self.model.joint_positions(q), self.model.joint_positions(q_ref), self._torque_arcs(u))
        return ground + arm + [Dot(np.array([l0, 0.0]), 5)]
