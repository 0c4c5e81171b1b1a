"""``mbs_envs/Planar2R-v0``: joint-space tracking with the planar 2R manipulator."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..models.planar2r import Planar2R
from .rendering import Shape, arm_shapes
from ..dynamics import compiled as _compiled
from ..dynamics.jit import njit
from ..models import planar2r as _model
from . import tracking as _tracking
from .engine import engine_step
from .tracking import JointTrackingEnv


@njit
def step_kernel(theta, stepper, control, task, state, out):  # pragma: no cover - compiled
    """The compiled step of this scene: :func:`~mbs_envs.envs.engine.engine_step` with the model's kernels."""
    engine_step(
        _model.advance_kernel,
        _model.energy_kernel,
        _compiled.no_constraint_info,
        _compiled.never_singular,
        _tracking.tracking_task,
        theta,
        stepper,
        control,
        task,
        state,
        out,
    )


class Planar2REnv(JointTrackingEnv):
    """Planar 2R arm under gravity, both joints driven: track a random smooth joint reference.

    ## Description

    Two rigid links in a vertical plane (docs/physics.md §3), both joints driven
    by torque-limited motors, gravity along -y. Each episode draws a reference
    ``q_ref(t) = c + sum_k A_k sin(w_k t + p_k)`` (three components per joint)
    whose velocity and acceleration are analytic; the task is to follow it.
    ``th1`` is measured from +x counter-clockwise (hanging straight down is
    ``th1 = -pi/2``), ``th2`` relative to link 1.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: joint torques normalized by the limits,
    ``u = action * torque_limit`` [N m]. Finite out-of-range actions saturate;
    NaN/inf or wrongly shaped actions raise ``ValueError``.

    ## Observation Space

    ``Box((12,), float32)``: ``[cos q (2), sin q (2), v (2), e (2), v_ref (2), a_ref (2)]``
    with ``e = wrap(q_ref - q)`` in ``[-pi, pi)``; see
    :func:`mbs_envs.envs.tracking.decode_tracking`.

    ## Rewards

    ``r = -(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |action|^2)``, default weights
    ``(1, 0.1, 0.001)``; the three terms are in ``info`` (``reward_tracking``,
    ``reward_velocity``, ``reward_effort``).

    ## Starting State

    Reference centre ``c1 ~ U(-pi/2 - 1, -pi/2 + 1)``, ``c2 ~ U(-1.2, 1.2)``;
    total amplitude per joint ``U(0.5, 1) * (0.6, 0.8)`` rad; frequencies
    ``U(0.5, 3)`` rad/s. Start ``q0 = q_ref(0) + U(-0.1, 0.1)``,
    ``v0 = v_ref(0) + U(-0.1, 0.1)``; or exactly ``reset(options={"q": ..., "v": ...})``.

    ## Episode End

    Truncation after ``max_episode_steps`` (default 500, i.e. 5 s at ``dt = 0.01``).
    Termination only if the simulation diverges (``info["diverged"]``).

    ## Arguments

    ``gym.make("mbs_envs/Planar2R-v0", params=None, dt=0.01, integrator="rk4",
    substeps=2, torque_limit=(40.0, 20.0), reward_weights=(1.0, 0.1, 0.001),
    start_noise=0.1, rtol=None, atol=None, compiled=True, render_mode=None, max_episode_steps=500)``

    - ``params``: overrides of :class:`mbs_envs.models.planar2r.Planar2RParams`
      (``m1, m2, l1, l2, r1, r2, I1, I2, g, b1, b2, f1, f2, v_s``).
    - ``dt``: control step [s]; ``substeps`` physics steps per control step
      (default two RK4 steps of 5 ms; accuracy and cost in docs/numerics.md and docs/performance.md).
    - ``compiled``: the step runs as one numba kernel (:mod:`mbs_envs.dynamics.compiled`)
      whenever the integrator is explicit; False forces the numpy path.
    - ``integrator``: any name of :func:`mbs_envs.dynamics.integrators.available`.

    ``info`` holds ``t``, ``energy``, ``diverged``, ``tracking_error``,
    ``q_ref``, the reward terms and the applied torque ``u``.

    ## Version History

    - v0: initial version.
    """

    step_kernel = staticmethod(step_kernel)

    center_low = np.array([-np.pi / 2 - 1.0, -1.2])
    center_high = np.array([-np.pi / 2 + 1.0, 1.2])
    max_amplitude = np.array([0.6, 0.8])

    def __init__(
        self,
        params: Mapping[str, Any] | None = None,
        torque_limit: Any = (40.0, 20.0),
        substeps: int = 2,
        **kwargs: Any,
    ):
        super().__init__(Planar2R(params), torque_limit, substeps=substeps, **kwargs)

    def _render_extent(self) -> float:
        p = self.model.params
        return 1.1 * (p.l1 + p.l2)

    def _drawing(self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: Any = None) -> list[Shape]:
        ghost = self.model.joint_positions(self.task_now(np.asarray(t), task)[0])
        return arm_shapes(self.model.joint_positions(q), ghost, self._torque_arcs(u))
