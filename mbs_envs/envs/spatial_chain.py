"""``mbs_envs/SpatialChain-v0``: joint-space tracking with an N-link chain in space."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..dynamics import compiled as _compiled
from ..dynamics.jit import njit
from ..models import spatial_chain as _model
from ..models.spatial_chain import SpatialChain
from . import tracking as _tracking
from .engine import engine_step
from .rendering import GHOST, Line, Shape, arm_shapes, oblique
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


@njit
def batched_step_kernel(theta, stepper, control, task, state, out):  # pragma: no cover - compiled
    """:func:`step_kernel` of a batch: the ABA in SIMD tiles of members (:func:`~mbs_envs.models.spatial_chain.aba_tiles`;
    each member's bits those of :func:`step_kernel`)."""
    engine_step(
        _model.tiled_advance_kernel,
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


def reach_gravity_torque(model: SpatialChain) -> np.ndarray:
    """The largest gravity torque joint ``i`` can feel [N m], shape (N,).

    ``|g| sum_{k >= i} m_k (sum_{j = i+1}^{k} |offset_j| + |com_k|)``: each centre of mass beyond the
    joint at its largest possible distance (the chain beyond held out straight), its weight at right
    angles to the lever and to the axis. An upper bound of ``|G_i(q)|`` for every ``q``; equal to it for a
    straight chain held horizontal about a horizontal axis (the planar chain's
    :meth:`~mbs_envs.envs.serial_chain.SerialChainEnv.horizontal_gravity_torque`).
    """
    p = model.params
    hop = np.linalg.norm(p.offset, axis=1)  # |offset_j|, joint j's distance from joint j-1
    reach = np.cumsum(np.r_[0.0, hop[1:]])  # joint 0 to joint k along the chain
    lever = reach[None, :] - reach[:, None] + np.linalg.norm(p.com, axis=1)[None, :]  # [i, k]: joint i to centre k
    return float(np.linalg.norm(p.g_vec)) * np.sum(np.triu(p.m[None, :] * lever), axis=1)


#: the gradient tolerance of :func:`hanging_posture`'s BFGS [N m]
GTOL = 1e-10


def hanging_posture(model: SpatialChain) -> np.ndarray:
    """A rest posture [rad], shape (N,): the minimum of the potential energy reached from
    ``q = (0, pi/2, 0, ..., 0)`` (the default chain's own minimum: a horizontal first link turning about
    the vertical, everything beyond hanging straight down) by BFGS on ``V(q)`` with the gradient ``G(q)``.

    Where ``G`` already vanishes at that start to BFGS's tolerance (``max |G| <= 1e-10``: the default chain,
    ``|G| ~ 1e-16``), BFGS returns the start untouched at its first test, and so does this, without importing
    ``scipy.optimize`` (0.2-0.3 s of a fresh process's first ``gym.make``, docs/performance.md)."""
    n = model.n_links
    q0 = np.zeros(n)
    if n > 1:
        q0[1] = np.pi / 2
    if np.max(np.abs(model.gravity(q0))) <= GTOL:  # BFGS's own first test (its default norm: the largest entry)
        return q0
    from scipy.optimize import minimize

    res = minimize(lambda q: float(model.potential_energy(q)), q0, jac=lambda q: model.gravity(q), method="BFGS",
                   options={"gtol": GTOL, "maxiter": 200 * n})  # fmt: skip
    return np.asarray(res.x, float)


class SpatialChainEnv(ChainTrackingEnv):
    """N-link chain in space, every joint driven: track a random smooth joint reference.

    ## Description

    docs/physics.md §6b: ``n_links`` rigid links, link ``i`` on a revolute joint about its own axis
    ``a_i`` in the parent's frame (default: z, y, z, y, ..., a backbone of alternating bends), a 1 kg,
    1 m chain of equal solid cylinders by default, gravity along -z. The first link turns about the
    vertical at the base; in the rest posture it is horizontal and the rest hangs straight down (every
    later joint then bends it in one of two perpendicular vertical planes). Each episode draws a
    reference about that posture, a sum of three sinusoids per joint, with analytic rates and
    accelerations; the task is to follow it. Forward dynamics by the spatial articulated-body
    algorithm (Featherstone, world-frame spatial vectors), O(N), compiled.

    ## Action Space

    ``Box(-1, 1, (n_links,), float32)``: joint torques normalized by ``torque_limit``. Default: each drive
    is sized by :func:`reach_gravity_torque`, the largest gravity torque its joint can feel.

    ## Drives

    As ``SerialChain-v0``: a rotor inertia reflected through the gear (``armature``) of
    ``torque_limit / 30 rad/s^2``; ``params={"armature": 0}`` for the bare chain.

    ## Observation Space

    ``Box((6 n_links,), float32)``: ``[cos q, sin q, v, wrap(q_ref - q), v_ref, a_ref]``.

    ## Rewards

    ``r = -(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |action|^2) / n_links``, default weights
    ``(1, 0.1, 0.001)``; terms in ``info``.

    ## Starting State

    Reference centres: the rest posture (:func:`hanging_posture`) plus ``U(-0.5, 0.5)`` on the first two
    joints (the turn about the vertical and the first bend) and ``U(-1, 1) / n_links`` on the others;
    amplitude per joint ``U(0.5, 1) * 0.8 / n_links`` rad, frequencies ``U(0.5, 3)`` rad/s. Start at the
    reference plus ``U(-0.1, 0.1) / n_links``, or exactly through ``reset(options={"q": ..., "v": ...})``.

    ## Episode End

    Truncation after 500 steps (5 s); termination only on divergence.

    ## Arguments

    ``gym.make("mbs_envs/SpatialChain-v0", n_links=10, params=None, torque_limit=None, dt=0.01,
    integrator="rk4", substeps=1, ...)``; ``params`` overrides
    :class:`~mbs_envs.models.spatial_chain.SpatialChainParams` (per-link arrays or one value for every
    link: ``m, l, axis, offset, com, inertia, armature, b``; ``g_vec``), or is a ready
    ``SpatialChainParams`` (taken as it is, armature included).

    ``pd_gains``: per-joint PD gains ``(100, 20) J_i``, ``J_i = 1 / (M^-1)_ii`` at the rest posture.

    ## Rendering

    The chain seen obliquely from above (azimuth -60 deg, elevation 30 deg, orthographic) over a floor grid
    with its shadow, the reference pose faint underneath and the base's vertical axis as a line; legible
    at 100 links.

    ## Version History

    - v0: initial version.
    """

    step_kernel = staticmethod(step_kernel)
    batched_step_kernel = staticmethod(batched_step_kernel)
    Model = SpatialChain
    wide_joints = 2

    holding_torque = staticmethod(reach_gravity_torque)
    posture = staticmethod(hanging_posture)

    def _reach(self) -> float:
        """The chain's length from the base to the tip [m]."""
        p = self.model.params
        return float(np.sum(np.linalg.norm(p.offset[1:], axis=1)) + p.l[-1])

    def _render_extent(self) -> float:
        return 0.75 * self._reach()

    def _render_center(self, q: np.ndarray) -> tuple[float, float]:
        c = oblique(np.array([0.0, 0.0, -0.5 * self._reach()]))
        return (float(c[0]), float(c[1]))

    def _drawing(self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: Any = None) -> list[Shape]:
        """The chain seen by :func:`~mbs_envs.envs.rendering.oblique`: a floor grid just below the
        hanging tip with the chain's shadow on it (straight down), the vertical axis through the base,
        the reference pose faint beneath the chain, and torque arcs at the joints."""
        L = self._reach()
        points = self.model.joint_positions(q)
        ghost = self.model.joint_positions(self.task_now(np.asarray(t), task)[0])
        floor = -1.05 * L
        shapes: list[Shape] = []
        span = np.linspace(-0.6 * L, 0.6 * L, 7)
        for k in span:
            shapes.append(Line(oblique(np.array([[k, span[0], floor], [k, span[-1], floor]])), (225, 225, 225), 1))
            shapes.append(Line(oblique(np.array([[span[0], k, floor], [span[-1], k, floor]])), (225, 225, 225), 1))
        shadow = points.copy()
        shadow[:, 2] = floor
        shapes.append(Line(oblique(shadow), (170, 170, 170), 2))
        shapes.append(Line(oblique(np.array([[0.0, 0.0, 0.15 * L], [0.0, 0.0, floor]])), GHOST, 1))
        return shapes + arm_shapes(oblique(points), oblique(ghost), self._torque_arcs(u))

    draws_ground = False
