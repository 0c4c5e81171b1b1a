"""Joint-space tracking controllers: PD, PD + gravity compensation, computed torque.

With ``e = q_ref - q`` and ``de = v_ref - v`` on the tracked coordinates
(every joint of a serial scene; the crank of the four-bar), following
docs/physics.md §7, "Control on top of the equations":

- PD:               ``u = Kp e + Kd de``
- PD + gravity:     ``u = Kp e + Kd de + u_g(q)``, ``u_g = inverse_dynamics(q, 0, 0)``
  the input that holds the mechanism still against gravity (``G(q)`` for a
  serial model; the static crank torque of the constrained four-bar)
- computed torque:  ``u = inverse_dynamics(q, v, a)`` with the tracked
  accelerations ``a_ref + Kd de + Kp e`` (completed to a consistent ``a`` by
  the constraints where there are any), which makes the closed loop
  ``e'' + Kd e' + Kp e = 0`` when the model is exact.

The gains have the same numbers in all three, but PD's are torques per error
[N m/rad, N m s/rad] while computed torque's are accelerations per error
[1/s^2, 1/s]: computed torque scales them by the mass matrix.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mbs_envs.envs.tracking import JointTrackingEnv

from .base import Controller, gain
from .tuned import tuned_gains


class PD(Controller):
    """Proportional-derivative joint control ``u = Kp (q_ref - q) + Kd (v_ref - v)``.

    Parameters
    ----------
    env : gymnasium.Env
    kp : float or array_like (m,), optional
        Proportional gain [N m/rad]; default the tuned one (``controllers/tuned.json``):
        ``J omega^2`` with the env's ``joint_inertia`` ``J`` and the tuned bandwidth.
    kd : float or array_like (m,), optional
        Derivative gain [N m s/rad]; default ``2 J zeta omega``.
    """

    #: the entry of controllers/tuned.json
    tuned_name = "PD"
    fits = (JointTrackingEnv,)

    def __init__(self, env: Any, kp: Any = None, kd: Any = None):
        super().__init__(env)
        default = self.default_gains(env)
        self.kp = gain(default[0] if kp is None else kp, self.model.nu, "kp")
        self.kd = gain(default[1] if kd is None else kd, self.model.nu, "kd")

    @classmethod
    def default_gains(cls, env: Any) -> tuple[Any, Any]:
        """``(kp, kd)`` from the tuned bandwidth and damping ratio (see :mod:`controllers.tuned`)."""
        g = tuned_gains(env, cls.tuned_name)
        return cls.gains_from_bandwidth(env, g["omega"], g["zeta"])

    @staticmethod
    def gains_from_bandwidth(env: Any, omega: float, zeta: float) -> tuple[Any, Any]:
        """``(J omega^2, 2 J zeta omega)`` with the env's ``joint_inertia`` ``J``."""
        J = np.asarray(getattr(env.unwrapped, "joint_inertia", 1.0), float)
        return J * omega**2, 2.0 * J * zeta * omega

    def feedback(self, obs: Any) -> np.ndarray:
        """``Kp (q_ref - q) + Kd (v_ref - v)`` on the tracked coordinates, shape ``(..., m)``."""
        idx = list(obs.tracked)
        return self.kp * (obs.q_ref - obs.q[..., idx]) + self.kd * (obs.v_ref - obs.v[..., idx])

    def input(self, obs: Any) -> np.ndarray:
        return self.feedback(obs)


class PDGravity(PD):
    """PD plus gravity compensation ``u_g(q) = inverse_dynamics(q, 0, 0)`` (= ``G(q)`` when ``B = I``)."""

    tuned_name = "PD+gravity"

    def input(self, obs: Any) -> np.ndarray:
        rest = np.zeros_like(obs.v)
        return self.feedback(obs) + self.model.inverse_dynamics(obs.q, rest, rest)


class ComputedTorque(PD):
    """Computed torque (inverse-dynamics control).

    ``u = inverse_dynamics(q, v, a_ref + Kd (v_ref - v) + Kp (q_ref - q))``.

    Parameters
    ----------
    env : gymnasium.Env
    kp : float or array_like (n,)
        [1/s^2], default the tuned ``omega^2`` (``controllers/tuned.json``).
    kd : float or array_like (n,)
        [1/s], default the tuned ``2 zeta omega``.
    """

    tuned_name = "computed torque"

    @staticmethod
    def gains_from_bandwidth(env: Any, omega: float, zeta: float) -> tuple[Any, Any]:
        """``(omega^2, 2 zeta omega)``: the closed loop ``e'' + 2 zeta omega e' + omega^2 e = 0``."""
        return omega**2, 2.0 * zeta * omega

    def input(self, obs: Any) -> np.ndarray:
        a_tracked = obs.a_ref + self.feedback(obs)
        if self.model.constrained:  # the crank's acceleration fixes the others'
            a = self.model.complete_acceleration(obs.q, obs.v, a_tracked)
        else:
            a = a_tracked
        return self.model.inverse_dynamics(obs.q, obs.v, a)
