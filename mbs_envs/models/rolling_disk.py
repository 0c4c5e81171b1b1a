"""Scene 3: a thin disk rolling without slipping on the ground (docs/physics.md §5).

``q = (x, y, z, th1, th2, th3)``: centre of the disk, heading ``th1`` about Z,
lean ``th2`` about the moved x axis, spin ``th3`` about the moved y axis (the
symmetry axis). ``R = Rz(th1) Rx(th2) Ry(th3)``; ``v = dq/dt``.

With ``A = Ixx = Izz`` and ``C = Iyy`` the body inertias and ``n = R e_y =
(-s1 c2, c1 c2, s2)`` the spin axis, the world inertia is
``A I + (C - A) n n^T`` and ``w = Jw(q) (dth1, dth2, dth3)`` with
``Jw = [[0, c1, -s1 c2], [0, s1, c1 c2], [1, 0, s2]]``. Hence

    M = blockdiag(m I3, [[A c2^2 + C s2^2, 0, C s2], [0, A, 0], [C s2, 0, C]]),

    T = m |dx|^2 / 2 + (A (c2^2 dth1^2 + dth2^2) + C (dth3 + s2 dth1)^2) / 2,
    V = m g z.

Rolling without slipping, ``(dx, dy, dz) + w x rC = 0`` with the contact point
``rC = -r (s1 s2, -c1 s2, c2)``, is ``Psi v = 0`` with ``Psi = [I3, -[rC]x Jw]``;
its z row is the derivative of the holonomic ``phi = z - r cos th2``. As the
translational columns of ``Psi`` are the identity, the multipliers ``lam`` are
the contact force of the ground on the disk [N] (world frame).

Inputs ``u = (drive, steer)`` are the generalized forces conjugate to the spin
angle ``th3`` and the heading ``th1``. Because ``dw/d(dth3) = n`` and
``dw/d(dth1) = e_z``, a torque ``tau`` applied to the disk gives exactly
``drive = tau . n`` (its component about the spin axis) and
``steer = tau . e_z`` (its vertical component); ``B`` is constant.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from ..linalg import cross
from .base import Params, as_vector, param
from .constrained import ConstrainedModel


@dataclasses.dataclass(frozen=True)
class RollingDiskParams(Params):
    """Parameters of :class:`RollingDisk`; a uniform thin disk (``Ixx = m r^2/4``, ``Iyy = m r^2/2``).

    ``b_roll`` and ``b_pivot`` are optional viscous rolling and pivoting
    resistances on the spin and heading rates (off by default).
    """

    m: float = param(1.0, "positive", "kg", "mass")
    r: float = param(0.3, "positive", "m", "radius")
    g: float = param(9.81, "nonnegative", "m/s^2", "gravity along -z")
    b_roll: float = param(0.0, "nonnegative", "N m s/rad", "rolling resistance on dth3")
    b_pivot: float = param(0.0, "nonnegative", "N m s/rad", "pivoting resistance on dth1")


def critical_spin(m: float, r: float, g: float, A: float | None = None, C: float | None = None) -> float:
    """Spin rate above which steady upright straight rolling is linearly stable [rad/s].

    Linearizing the lean/heading equations about upright rolling at spin ``W``
    (in this scene's coordinates; the full model's Jacobian has these entries),

        (A + m r^2) lean'' = m g r lean + (C + m r^2) W heading',
        A heading'' = -C W lean',

    and integrating the second, ``heading' = -C W lean / A + const``, gives
    ``(A + m r^2) lean'' = (m g r - (C + m r^2) C W^2 / A) lean``: stable
    (oscillating) iff ``W^2 > m g r A / (C (C + m r^2))``. For the uniform thin
    disk (``A = m r^2 / 4``, ``C = m r^2 / 2``) this is ``sqrt(g / (3 r))``.

    Parameters
    ----------
    m, r, g : float
        Mass [kg], radius [m], gravity [m/s^2].
    A, C : float, optional
        Diametral and axial moments of inertia [kg m^2] (default: uniform disk).
    """
    A = m * r**2 / 4 if A is None else A
    C = m * r**2 / 2 if C is None else C
    return float(np.sqrt(m * g * r * A / (C * (C + m * r**2))))


def steady_turn_residual(lean, W, Omega, a, b, c):
    """Euler's equation about the centre for steady circular rolling, and its partials.

    The centre moves on a circle at speed ``V = r (W + Omega s2)`` with angular
    rate ``Omega``; with ``(a, b, c)`` from :meth:`RollingDisk.steady_turning_coefficients`,

        F = a W Omega c2 + b Omega^2 s2 c2 + c s2 = 0,

    ``s2, c2 = sin, cos(lean)``. Floats or broadcasting arrays.

    Returns
    -------
    F, dF/dlean, dF/dOmega
    """
    s, co = np.sin(lean), np.cos(lean)
    F = a * W * Omega * co + b * Omega**2 * s * co + c * s
    dF_dlean = -a * W * Omega * s + b * Omega**2 * (co**2 - s**2) + c * co
    dF_dOmega = a * W * co + 2 * b * Omega * s * co
    return F, dF_dlean, dF_dOmega


class RollingDisk(ConstrainedModel):
    """Thin disk rolling without slipping (docs/physics.md §5); see the module docstring."""

    Params = RollingDiskParams
    nq = 6
    nv = 6
    nu = 2
    nc = 3
    position_rows: ClassVar[tuple[int, ...]] = (2,)
    #: the heading, lean and spin rates parametrize the allowed motions
    independent: ClassVar[tuple[int, ...]] = (3, 4, 5)
    #: |lean| beyond this is "flat": the Euler angles are near their singularity
    flat_lean: ClassVar[float] = np.pi / 2 - 0.05

    @property
    def inertias(self) -> tuple[float, float]:
        """``(A, C) = (m r^2 / 4, m r^2 / 2)`` [kg m^2]: diametral and axial."""
        p = self.params
        return p.m * p.r**2 / 4, p.m * p.r**2 / 2

    @property
    def critical_spin(self) -> float:
        """See :func:`critical_spin`."""
        p = self.params
        return critical_spin(p.m, p.r, p.g)

    @property
    def actuation(self) -> np.ndarray:
        """``B`` (6 x 2): drive on ``th3``, steer on ``th1``."""
        B = np.zeros((6, 2))
        B[5, 0] = 1.0
        B[3, 1] = 1.0
        return B

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        q = as_vector(q, 6, "q")
        A, C = self.inertias
        s2, c2 = np.sin(q[..., 4]), np.cos(q[..., 4])
        M = np.zeros(q.shape[:-1] + (6, 6))
        M[..., 0, 0] = M[..., 1, 1] = M[..., 2, 2] = self.params.m
        M[..., 3, 3] = A * c2**2 + C * s2**2
        M[..., 3, 5] = M[..., 5, 3] = C * s2
        M[..., 4, 4] = A
        M[..., 5, 5] = C
        return M

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C v`` from the Christoffel symbols of ``M(th2)``, shape ``(..., 6)``."""
        q = as_vector(q, 6, "q")
        v = as_vector(v, 6, "v")
        A, C = self.inertias
        s2, c2 = np.sin(q[..., 4]), np.cos(q[..., 4])
        d1, d2, d3 = v[..., 3], v[..., 4], v[..., 5]
        D = 2 * (C - A) * s2 * c2  # dM33/dth2 (heading-heading entry)
        E = C * c2  # dM35/dth2
        out = np.zeros(np.broadcast_shapes(q.shape, v.shape))
        out[..., 3] = D * d1 * d2 + E * d2 * d3
        out[..., 4] = -0.5 * D * d1**2 - E * d1 * d3
        out[..., 5] = E * d1 * d2
        return out

    def gravity(self, q: np.ndarray) -> np.ndarray:
        q = as_vector(q, 6, "q")
        G = np.zeros(q.shape)
        G[..., 2] = self.params.m * self.params.g
        return G

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        q = as_vector(q, 6, "q")
        return self.params.m * self.params.g * q[..., 2]

    def friction(self, v: np.ndarray) -> np.ndarray:
        v = as_vector(v, 6, "v")
        F = np.zeros(v.shape)
        F[..., 3] = self.params.b_pivot * v[..., 3]
        F[..., 5] = self.params.b_roll * v[..., 5]
        return F

    # -- kinematics -----------------------------------------------------------

    @staticmethod
    def _trig(q: np.ndarray):
        return np.sin(q[..., 3]), np.cos(q[..., 3]), np.sin(q[..., 4]), np.cos(q[..., 4])

    def angular_velocity(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``w`` in the ground frame [rad/s], shape ``(..., 3)``."""
        q = as_vector(q, 6, "q")
        v = as_vector(v, 6, "v")
        s1, c1, s2, c2 = self._trig(q)
        d1, d2, d3 = v[..., 3], v[..., 4], v[..., 5]
        return np.stack([c1 * d2 - s1 * c2 * d3, s1 * d2 + c1 * c2 * d3, d1 + s2 * d3], axis=-1)

    def contact_offset(self, q: np.ndarray) -> np.ndarray:
        """Contact point relative to the centre, ``rC = -r (s1 s2, -c1 s2, c2)`` [m]."""
        q = as_vector(q, 6, "q")
        s1, c1, s2, c2 = self._trig(q)
        return -self.params.r * np.stack([s1 * s2, -c1 * s2, c2], axis=-1)

    def spin_axis(self, q: np.ndarray) -> np.ndarray:
        """``n = R e_y = (-s1 c2, c1 c2, s2)``, shape ``(..., 3)``."""
        q = as_vector(q, 6, "q")
        s1, c1, s2, c2 = self._trig(q)
        return np.stack([-s1 * c2, c1 * c2, s2], axis=-1)

    # -- constraints ------------------------------------------------------------

    def constraint_residual(self, q: np.ndarray) -> np.ndarray:
        """Height ``phi = z - r cos th2`` [m], shape ``(..., 1)``."""
        q = as_vector(q, 6, "q")
        return (q[..., 2] - self.params.r * np.cos(q[..., 4]))[..., None]

    def constraint_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``Psi = [I3, -[rC]x Jw]`` (3 x 6): the contact point's velocity map."""
        q = as_vector(q, 6, "q")
        s1, c1, s2, c2 = self._trig(q)
        rC = self.contact_offset(q)
        Jw = np.zeros(q.shape[:-1] + (3, 3))
        Jw[..., 0, 1], Jw[..., 0, 2] = c1, -s1 * c2
        Jw[..., 1, 1], Jw[..., 1, 2] = s1, c1 * c2
        Jw[..., 2, 0], Jw[..., 2, 2] = 1.0, s2
        # w x rC = -rC x w = -[rC]x Jw v_ang
        skew = np.zeros(q.shape[:-1] + (3, 3))
        skew[..., 0, 1], skew[..., 0, 2] = -rC[..., 2], rC[..., 1]
        skew[..., 1, 0], skew[..., 1, 2] = rC[..., 2], -rC[..., 0]
        skew[..., 2, 0], skew[..., 2, 1] = -rC[..., 1], rC[..., 0]
        Psi = np.zeros(q.shape[:-1] + (3, 6))
        Psi[..., :, :3] = np.eye(3)
        Psi[..., :, 3:] = -skew @ Jw
        return Psi

    def constraint_bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``dPsi v = (dJw v_ang) x rC + w x drC`` (velocity-squared terms), shape ``(..., 3)``."""
        q = as_vector(q, 6, "q")
        v = as_vector(v, 6, "v")
        r = self.params.r
        s1, c1, s2, c2 = self._trig(q)
        d1, d2, d3 = v[..., 3], v[..., 4], v[..., 5]
        dJw_v = np.stack(
            [
                -s1 * d1 * d2 - c1 * c2 * d1 * d3 + s1 * s2 * d2 * d3,
                c1 * d1 * d2 - s1 * c2 * d1 * d3 - c1 * s2 * d2 * d3,
                c2 * d2 * d3,
            ],
            axis=-1,
        )
        drC = -r * np.stack(
            [c1 * s2 * d1 + s1 * c2 * d2, s1 * s2 * d1 - c1 * c2 * d2, -s2 * d2], axis=-1
        )
        return cross(dJw_v, self.contact_offset(q)) + cross(self.angular_velocity(q, v), drC)

    # -- states -------------------------------------------------------------------

    def rolling_state(
        self,
        heading: float = 0.0,
        lean: float = 0.0,
        spin: float = 0.0,
        dheading: float = 0.0,
        dlean: float = 0.0,
        dspin: float = 0.0,
        x: float = 0.0,
        y: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """A consistent state: the disk on the ground (``z = r cos lean``) with the
        centre's velocity from the rolling constraints.

        Returns
        -------
        q, v : ndarray, shape (6,)
        """
        if not abs(lean) < self.flat_lean:
            raise ValueError(f"lean must be within +-{self.flat_lean:.3f} rad of upright, got {lean!r}")
        q = np.array([x, y, self.params.r * np.cos(lean), heading, lean, spin], float)
        v = self.complete_velocity(q, np.array([dheading, dlean, dspin], float))
        return q, v

    def singular(self, q: np.ndarray) -> np.ndarray:
        """Whether ``|th2|`` passed :attr:`flat_lean`: the disk is nearly flat and
        the Euler angles (and ``M``) near their singularity at ``th2 = +-pi/2``.
        Simulations stop there (reported as divergence) rather than return NaN."""
        return np.abs(as_vector(q, 6, "q")[..., 4]) > self.flat_lean

    def steady_turning_coefficients(self) -> tuple[float, float, float]:
        """``(a, b, c) = (C + m r^2, C - A + m r^2, m g r)`` of the steady-turn equation
        (:func:`steady_turn_residual`)."""
        p = self.params
        A, C = self.inertias
        return C + p.m * p.r**2, C - A + p.m * p.r**2, p.m * p.g * p.r

    def steady_turning_spin(self, lean: float, heading_rate: float) -> float:
        """Spin rate ``W`` of steady circular rolling at constant ``lean`` and ``heading_rate``:
        the root in ``W`` of :func:`steady_turn_residual` (linear in ``W``).

        Raises
        ------
        ValueError
            If ``heading_rate`` is zero (straight rolling: any ``W`` with ``lean = 0``).
        """
        if heading_rate == 0:
            raise ValueError("heading_rate must be non-zero for a steady turn")
        a, b, c = self.steady_turning_coefficients()
        F0 = steady_turn_residual(lean, 0.0, heading_rate, a, b, c)[0]  # the terms without W
        return float(-F0 / (a * heading_rate * np.cos(lean)))

    def reduced_dynamics(self, x: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """The motion in the independent coordinates, ``dx/dt = f(x, u)``.

        ``x = (th1, th2, dth1, dth2, dth3)``; the position ``(x, y)`` and spin
        angle ``th3`` do not enter the dynamics (symmetries), ``z = r cos th2``
        and the centre's velocity follow from the constraints.

        Returns
        -------
        ndarray, shape (..., 5): ``(dth1, dth2, ddth1, ddth2, ddth3)``
        """
        x = as_vector(x, 5, "x")
        q = np.zeros(x.shape[:-1] + (6,))
        q[..., 2] = self.params.r * np.cos(x[..., 1])
        q[..., 3] = x[..., 0]
        q[..., 4] = x[..., 1]
        v = self.complete_velocity(q, x[..., 2:5])
        a = self.forward_dynamics(q, v, u)
        return np.concatenate([x[..., 2:4], a[..., 3:6]], axis=-1)
