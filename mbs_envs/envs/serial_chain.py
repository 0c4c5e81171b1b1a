"""``mbs_envs/SerialChain-v0``: joint-space tracking with an N-link planar chain."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..models.serial_chain import SerialChain
from .rendering import Shape, arm_shapes
from ..dynamics import compiled as _compiled
from ..dynamics.jit import njit
from ..models import serial_chain as _model
from . import tracking as _tracking
from .engine import engine_step
from .tracking import ChainTrackingEnv


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


class SerialChainEnv(ChainTrackingEnv):
    """Planar N-link chain, every joint driven: track a random smooth joint reference.

    ## Description

    docs/physics.md §6: ``n_links`` links hanging from a fixed pivot under
    gravity, joint ``i`` at angle ``q_i`` relative to link ``i-1``. Each
    episode draws a reference around the hanging posture (``q_1 = -pi/2``,
    the others 0), a sum of three sinusoids per joint, with analytic rates and
    accelerations; the task is to follow it. Forward dynamics by the
    articulated-body algorithm, O(N).

    ## Action Space

    ``Box(-1, 1, (n_links,), float32)``: joint torques normalized by
    ``torque_limit``. Default: each drive is sized to hold the chain beyond
    it horizontal, ``|G_i(q = 0)|`` (the base drive ~``N^2`` times the tip's);
    computed torque stays within it on the default task (peak 0.75 of it at
    N = 2, 0.48 at N = 100, 0.39 at N = 500; measured).

    ## Drives

    Each joint's drive has a rotor inertia reflected through its gear
    (``armature``, adding to the diagonal of ``M``), default
    ``torque_limit / rotor_acceleration`` (30 rad/s^2): a drive at full torque
    accelerates its own rotor at 30 rad/s^2. Without it the default rope's
    tip links (a few grams) whip at 200 rad/s (N = 5) to 1500 rad/s (N = 10)
    under random actions and a 10 ms RK4 step diverges; with it, random
    actions stay below 100 rad/s up to N = 500 at one RK4 step per control
    step (measured). Pass ``params={"armature": 0}`` for the bare chain.

    ## Observation Space

    ``Box((6 n_links,), float32)``: ``[cos q, sin q, v, wrap(q_ref - q), v_ref, a_ref]``.

    ## Rewards

    ``r = -(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |action|^2) / n_links``,
    default weights ``(1, 0.1, 0.001)``; terms in ``info``.

    ## Starting State

    Reference centre ``c_1 ~ U(-pi/2 - 0.5, -pi/2 + 0.5)``,
    ``c_i ~ U(-1, 1) / n_links`` (i > 1); total amplitude per joint
    ``U(0.5, 1) * 0.8 / n_links`` rad; frequencies ``U(0.5, 3)`` rad/s. The
    ``1 / n_links`` scaling keeps the posture of the whole chain (the absolute
    angle of its last link is the sum of the joint angles) the same for any N.
    Start at the reference plus ``U(-0.1, 0.1) / n_links``, or exactly through
    ``reset(options={"q": ..., "v": ...})``.

    ## Episode End

    Truncation after 500 steps (5 s); termination only on divergence.

    ## Arguments

    ``gym.make("mbs_envs/SerialChain-v0", n_links=10, params=None,
    torque_limit=None, dt=0.01, integrator="rk4", substeps=1, ...)``;
    ``params`` overrides :class:`~mbs_envs.models.serial_chain.SerialChainParams`
    (per-link arrays or scalars: ``m, l, r, I, armature, g, b, f, v_s``).
    Forward dynamics by the articulated-body algorithm, O(N); the step runs
    compiled (timings per N in docs/performance.md).

    ``pd_gains``: per-joint default PD gains ``(100, 20) J_i`` with
    ``J_i = 1 / (M^-1)_ii`` the apparent inertia of joint i at the hanging
    posture (computed torque's bandwidth joint by joint; a uniform 100 N m/rad,
    or gains on ``M_ii``, are unstable on light links).

    ## Version History

    - v0: initial version.
    """

    step_kernel = staticmethod(step_kernel)
    Model = SerialChain

    @staticmethod
    def holding_torque(model: SerialChain) -> np.ndarray:
        """The drives' torque limits: :meth:`horizontal_gravity_torque`."""
        return SerialChainEnv.horizontal_gravity_torque(model)

    @staticmethod
    def horizontal_gravity_torque(model: SerialChain) -> np.ndarray:
        """Gravity torque at each joint with the whole chain held horizontal [N m], shape (N,)."""
        return np.abs(model.gravity(np.zeros(model.n_links)))

    @staticmethod
    def posture(model: SerialChain) -> np.ndarray:
        """Hanging: ``q_1 = -pi/2``, the others 0."""
        return np.r_[-np.pi / 2, np.zeros(model.n_links - 1)]

    def _render_extent(self) -> float:
        return 1.1 * float(np.sum(self.model.params.l))

    def _drawing(self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: Any = None) -> list[Shape]:
        ghost = self.model.joint_positions(self.task_now(np.asarray(t), task)[0])
        return arm_shapes(self.model.joint_positions(q), ghost, self._torque_arcs(u))
