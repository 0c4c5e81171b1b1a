"""Actuator sizing by inverse dynamics: the torque, power and joint loads a motion needs.

The lecture's use of inverse dynamics: given a reference motion ``q_ref(t)``
(with its analytic rates and accelerations), the drive torques are
``u(t) = inverse_dynamics(q_ref, v_ref, a_ref)`` and the mechanical power of
drive ``j`` is ``P_j = u_j v_j`` (for a drive on a coordinate with ``B = I``;
generally ``P = u * (B^T v)``). For the constrained four-bar the reference
is the crank's; the whole consistent motion is completed from it (positions
by assembly, rates and accelerations through the constraints) and the joint
reaction forces come from the Lagrange multipliers (:meth:`FourBar.joint_forces`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..models.base import Model
from ..envs.references import SumOfSines


@dataclasses.dataclass(frozen=True)
class Sizing:
    """What a motion demands of each drive (and, for the four-bar, of each joint).

    Attributes
    ----------
    t : ndarray, shape (T,)
    u : ndarray, shape (T, nu)
        Drive inputs [N m].
    power : ndarray, shape (T, nu)
        Mechanical power of each drive [W] (positive: the drive does work).
    peak_torque, rms_torque : ndarray, shape (nu,)
    peak_power, rms_power : ndarray, shape (nu,)
    joint_forces : ndarray, shape (T, J, 2) or None
        Reaction forces at the joints [N] (four-bar: O, A, B, C).
    peak_joint_force : ndarray, shape (J,) or None
        Largest magnitude at each joint [N].
    """

    t: np.ndarray
    u: np.ndarray
    power: np.ndarray
    peak_torque: np.ndarray
    rms_torque: np.ndarray
    peak_power: np.ndarray
    rms_power: np.ndarray
    joint_forces: np.ndarray | None = None
    peak_joint_force: np.ndarray | None = None

    def table(self) -> list[dict[str, Any]]:
        """One row per drive: ``drive, peak_torque, rms_torque, peak_power, rms_power``."""
        return [
            {
                "drive": j,
                "peak_torque": float(self.peak_torque[j]),
                "rms_torque": float(self.rms_torque[j]),
                "peak_power": float(self.peak_power[j]),
                "rms_power": float(self.rms_power[j]),
            }
            for j in range(self.u.shape[-1])
        ]


def motion_from_reference(model: Model, reference: SumOfSines, t: np.ndarray, branch: int = 1):
    """The whole state ``(q, v, a)`` along a reference of the model's independent coordinates.

    Serial models track every coordinate (returned as is); constrained models
    (the four-bar) are completed: ``q`` by ``assemble`` on ``branch``, ``v`` and
    ``a`` through the constraints.
    """
    return model.motion_from_tracked(*reference(t), branch=branch)


def actuator_sizing(model: Model, reference: SumOfSines, t_final: float, dt: float = 1e-3, branch: int = 1) -> Sizing:
    """Drive torques and powers (and four-bar joint loads) along ``reference`` over ``[0, t_final]``.

    Parameters
    ----------
    model : Model
        Fully actuated serial model, or the four-bar (reference of the crank).
    reference : SumOfSines
        Of the tracked (independent) coordinates.
    t_final, dt : float
        Horizon and sampling step [s].
    branch : int
        Four-bar assembly branch.
    """
    if not (np.isfinite(t_final) and t_final > 0 and np.isfinite(dt) and 0 < dt <= t_final):
        raise ValueError(f"need 0 < dt <= t_final, got dt={dt!r}, t_final={t_final!r}")
    t = np.arange(0.0, t_final + 0.5 * dt, dt)
    q, v, a = motion_from_reference(model, reference, t, branch)
    u = model.inverse_dynamics(q, v, a)
    power = u * np.einsum("ij,...i->...j", model.actuation, v)  # u_j times the rate it drives
    forces = peak_f = None
    if hasattr(model, "joint_forces"):
        forces = model.joint_forces(q, v, u)
        peak_f = np.max(np.linalg.norm(forces, axis=-1), axis=0)
    return Sizing(
        t=t,
        u=u,
        power=power,
        peak_torque=np.max(np.abs(u), axis=0),
        rms_torque=np.sqrt(np.mean(u**2, axis=0)),
        peak_power=np.max(np.abs(power), axis=0),
        rms_power=np.sqrt(np.mean(power**2, axis=0)),
        joint_forces=forces,
        peak_joint_force=peak_f,
    )
