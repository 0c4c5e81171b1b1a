"""Scene 1: the planar 2R manipulator (double pendulum), PHYSICS.md.

``q = (th1, th2)``: ``th1`` angle of link 1 from the fixed +x axis
(counter-clockwise), ``th2`` angle of link 2 relative to link 1. Gravity acts
along -y. Both joints are driven (``B = I``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .base import Model, Params, as_vector, param, smoothed_friction


@dataclasses.dataclass(frozen=True)
class Planar2RParams(Params):
    """Parameters of :class:`Planar2R`; defaults are two uniform 1 kg, 1 m rods.

    ``r_i`` is the distance of link i's centre of mass from its proximal joint,
    ``I_i`` its moment of inertia about the centre of mass (z axis).
    """

    m1: float = param(1.0, "positive", "kg", "mass of link 1")
    m2: float = param(1.0, "positive", "kg", "mass of link 2")
    l1: float = param(1.0, "positive", "m", "length of link 1")
    l2: float = param(1.0, "positive", "m", "length of link 2")
    r1: float = param(0.5, "nonnegative", "m", "joint 1 to centre of mass of link 1")
    r2: float = param(0.5, "nonnegative", "m", "joint 2 to centre of mass of link 2")
    I1: float = param(1.0 / 12.0, "nonnegative", "kg m^2", "inertia of link 1 about its COM")
    I2: float = param(1.0 / 12.0, "nonnegative", "kg m^2", "inertia of link 2 about its COM")
    g: float = param(9.81, "finite", "m/s^2", "gravitational acceleration along -y")
    b1: float = param(0.0, "nonnegative", "N m s/rad", "viscous friction, joint 1")
    b2: float = param(0.0, "nonnegative", "N m s/rad", "viscous friction, joint 2")
    f1: float = param(0.0, "nonnegative", "N m", "smoothed Coulomb friction, joint 1")
    f2: float = param(0.0, "nonnegative", "N m", "smoothed Coulomb friction, joint 2")
    v_s: float = param(0.01, "positive", "rad/s", "Coulomb smoothing speed")

    def _check(self) -> None:
        # M is positive definite for all q iff each link has rotational inertia
        # about its joint: I_i + m_i r_i^2 > 0 (see the determinant of M).
        for i in (1, 2):
            I, m, r = (getattr(self, f"{k}{i}") for k in ("I", "m", "r"))
            if not I + m * r**2 > 0:
                raise ValueError(
                    f"parameters I{i}, r{i}: link {i} has no inertia about its joint "
                    f"(I{i} + m{i} r{i}^2 = 0)"
                )


class Planar2R(Model):
    """Planar two-link manipulator; equations exactly as PHYSICS.md scene 1.

    With ``M11 = I1 + I2 + m1 r1^2 + m2 (l1^2 + r2^2 + 2 l1 r2 c2)``,
    ``M12 = I2 + m2 (r2^2 + l1 r2 c2)``, ``M22 = I2 + m2 r2^2``,
    ``C v = (-m2 l1 r2 s2 (2 dth1 dth2 + dth2^2), m2 l1 r2 s2 dth1^2)``,
    ``G = ((m1 r1 + m2 l1) g c1 + m2 r2 g c12, m2 r2 g c12)``.
    """

    Params = Planar2RParams
    batched_params = True
    nq = 2
    nv = 2
    nu = 2

    @property
    def actuation(self) -> np.ndarray:
        """``B = I`` (2 x 2): both joint torques act directly."""
        return np.eye(2)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``M(q)``, shape ``(..., 2, 2)`` [kg m^2]."""
        p = self.params
        q = as_vector(q, 2, "q")
        c2 = np.cos(q[..., 1])
        m22 = p.I2 + p.m2 * p.r2**2
        m12 = m22 + p.m2 * p.l1 * p.r2 * c2
        m11 = p.I1 + p.m1 * p.r1**2 + p.I2 + p.m2 * (p.l1**2 + p.r2**2) + 2 * p.m2 * p.l1 * p.r2 * c2
        M = np.empty(q.shape[:-1] + (2, 2))
        M[..., 0, 0] = m11
        M[..., 0, 1] = m12
        M[..., 1, 0] = m12
        M[..., 1, 1] = m22
        return M

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C(q, v) v``, shape ``(..., 2)`` [N m]."""
        p = self.params
        q = as_vector(q, 2, "q")
        v = as_vector(v, 2, "v")
        h = p.m2 * p.l1 * p.r2 * np.sin(q[..., 1])
        d1, d2 = v[..., 0], v[..., 1]
        return np.stack(np.broadcast_arrays(-h * (2 * d1 * d2 + d2**2), h * d1**2), axis=-1)

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """``G(q)``, shape ``(..., 2)`` [N m]."""
        p = self.params
        q = as_vector(q, 2, "q")
        g12 = p.m2 * p.r2 * p.g * np.cos(q[..., 0] + q[..., 1])
        g1 = (p.m1 * p.r1 + p.m2 * p.l1) * p.g * np.cos(q[..., 0]) + g12
        return np.stack([g1, g12], axis=-1)

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        """``V = m1 g r1 s1 + m2 g (l1 s1 + r2 s12)`` [J], shape ``(...)``."""
        p = self.params
        q = as_vector(q, 2, "q")
        s1 = np.sin(q[..., 0])
        s12 = np.sin(q[..., 0] + q[..., 1])
        return p.g * (p.m1 * p.r1 * s1 + p.m2 * (p.l1 * s1 + p.r2 * s12))

    def friction(self, v: np.ndarray) -> np.ndarray:
        """``F_i = b_i v_i + f_i tanh(v_i / v_s)``, shape ``(..., 2)`` [N m]."""
        p = self.params
        v = as_vector(v, 2, "v")
        if isinstance(p.b1, float) and isinstance(p.b2, float) and isinstance(p.f1, float) and isinstance(p.f2, float):
            b, f = np.array([p.b1, p.b2]), np.array([p.f1, p.f2])
        else:  # per-member parameters (domain randomization): shape (B, 2)
            b = np.stack(np.broadcast_arrays(p.b1, p.b2), axis=-1)
            f = np.stack(np.broadcast_arrays(p.f1, p.f2), axis=-1)
        return smoothed_friction(v, b, f, np.asarray(p.v_s)[..., None])

    def joint_positions(self, q: np.ndarray) -> np.ndarray:
        """Positions of the base, the elbow and the tip in the plane [m].

        Returns
        -------
        ndarray, shape (..., 3, 2)
        """
        p = self.params
        q = as_vector(q, 2, "q")
        th1 = q[..., 0]
        th12 = th1 + q[..., 1]
        elbow = np.stack([p.l1 * np.cos(th1), p.l1 * np.sin(th1)], axis=-1)
        tip = elbow + np.stack([p.l2 * np.cos(th12), p.l2 * np.sin(th12)], axis=-1)
        return np.stack([np.zeros_like(elbow), elbow, tip], axis=-2)
