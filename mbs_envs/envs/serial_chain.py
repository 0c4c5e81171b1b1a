"""``mbs_envs/SerialChain-v0``: joint-space tracking with an N-link planar chain."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..models.serial_chain import SerialChain
from .rendering import Polyline
from .tracking import JointTrackingEnv


class SerialChainEnv(JointTrackingEnv):
    """An N-link planar chain, every joint driven, tracking a random smooth joint reference.

    ## Description

    PHYSICS.md scene 4: ``n_links`` links hanging from a fixed pivot under
    gravity, joint ``i`` at angle ``q_i`` relative to link ``i-1``. Each
    episode draws a reference around the hanging posture (``q_1 = -pi/2``,
    the others 0), a sum of three sinusoids per joint, with analytic rates and
    accelerations; the task is to follow it. Forward dynamics by the
    articulated-body algorithm, O(N).

    ## Action Space

    ``Box(-1, 1, (n_links,), float32)``: joint torques normalized by
    ``torque_limit`` (default: three times the largest gravity torque each
    joint can see, i.e. with the chain beyond it held horizontal).

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

    ``gym.make("mbs_envs/SerialChain-v0", n_links=5, params=None,
    torque_limit=None, dt=0.01, integrator="rk4", substeps=ceil(n_links / 10), ...)``;
    ``params`` overrides :class:`~mbs_envs.models.serial_chain.SerialChainParams`
    (per-link arrays or scalars: ``m, l, r, I, g, b, f, v_s``).

    ``pd_gains``: per-joint default PD gains ``(100, 20) J_i`` with
    ``J_i = 1 / (M^-1)_ii`` the apparent inertia of joint i at the hanging
    posture (computed torque's bandwidth joint by joint; a uniform 100 N m/rad,
    or gains on ``M_ii``, are unstable on light links).
    """

    omega_range = (0.5, 3.0)

    def __init__(
        self,
        n_links: int = 5,
        params: Mapping[str, Any] | None = None,
        torque_limit: Any = None,
        reward_weights: Any = (1.0, 0.1, 1e-3),
        **kwargs: Any,
    ):
        model = SerialChain({**(params or {}), "n_links": n_links})
        n = model.n_links
        self.center_low = np.r_[-np.pi / 2 - 0.5, np.full(n - 1, -1.0 / n)]
        self.center_high = np.r_[-np.pi / 2 + 0.5, np.full(n - 1, 1.0 / n)]
        self.max_amplitude = np.full(n, 0.8 / n)
        if torque_limit is None:
            torque_limit = 3.0 * self.horizontal_gravity_torque(model)
        weights = np.asarray(reward_weights, float) / n
        kwargs.setdefault("start_noise", 0.1 / n)
        # short links have fast modes: RK4 at 10 ms diverges from N ~ 50 (measured);
        # ceil(N / 10) substeps was stable with computed torque at N = 50
        kwargs.setdefault("substeps", int(np.ceil(n / 10)))
        super().__init__(model, torque_limit, reward_weights=weights, **kwargs)
        # PD gains with computed torque's bandwidth at the hanging posture, joint by
        # joint, on the apparent inertia 1 / (M^-1)_ii (the others free to move)
        M = model.mass_matrix(np.r_[-np.pi / 2, np.zeros(n - 1)])
        J = 1.0 / np.diag(np.linalg.inv(M))
        self.pd_gains = (100.0 * J, 20.0 * J)

    @staticmethod
    def horizontal_gravity_torque(model: SerialChain) -> np.ndarray:
        """Gravity torque at each joint with the whole chain held horizontal [N m], shape (N,)."""
        return np.abs(model.gravity(np.zeros(model.n_links)))

    def _render_extent(self) -> float:
        return 1.1 * float(np.sum(self.model.params.l))

    def _polylines(self) -> list[Polyline]:
        q_ref = self.reference_now()[0]
        return [
            (self.model.joint_positions(q_ref), (180, 200, 240)),
            (self.model.joint_positions(self._q), (0, 90, 200)),
        ]
