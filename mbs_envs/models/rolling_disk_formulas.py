"""The rolling disk's equations, written once (docs/physics.md §5): plain functions of floats or broadcasting arrays
(the numpy methods of :class:`~mbs_envs.models.rolling_disk.RollingDisk`) and, compiled, of one member's floats (the
kernels), from ``s1, c1 = sin, cos(heading)``, ``s2, c2 = sin, cos(lean)`` and the rates ``d1, d2, d3`` of heading,
lean and spin.
"""

from __future__ import annotations

from ..dynamics.jit import njit


def disk_inertias(m, r):
    """``(A, C) = (m r^2 / 4, m r^2 / 2)`` [kg m^2]: diametral and axial."""
    return m * r**2 / 4, m * r**2 / 2


def disk_mass_entries(s2, c2, A, C):
    """The lean-dependent entries ``(M33, M35)`` of ``M`` (``M44 = A``, ``M55 = C``, ``m`` for the centre)."""
    return A * c2**2 + C * s2**2, C * s2


def disk_coriolis_entries(s2, c2, d1, d2, d3, A, C):
    """``C v`` on heading, lean and spin, from the Christoffel symbols of ``M(th2)``."""
    D = 2 * (C - A) * s2 * c2  # dM33/dth2 (heading-heading entry)
    E = C * c2  # dM35/dth2
    return D * d1 * d2 + E * d2 * d3, -0.5 * D * d1**2 - E * d1 * d3, E * d1 * d2


def angular_velocity_entries(s1, c1, s2, c2, d1, d2, d3):
    """``w = Jw (d1, d2, d3)`` in the ground frame [rad/s]."""
    return c1 * d2 - s1 * c2 * d3, s1 * d2 + c1 * c2 * d3, d1 + s2 * d3


def contact_offset_entries(s1, c1, s2, c2, r):
    """``rC = -r (s1 s2, -c1 s2, c2)`` [m]: the contact point from the centre."""
    return -r * (s1 * s2), -r * (-c1 * s2), -r * c2


def rolling_jacobian_entries(s1, c1, s2, c2, x, y, z):
    """The angular block ``-[rC]x Jw`` (3 x 3, rows) of ``Psi = [I3, -[rC]x Jw]``,
    with ``rC = (x, y, z)`` (:func:`contact_offset_entries`)."""
    # [rC]x Jw with [rC]x = [[0, -z, y], [z, 0, -x], [-y, x, 0]], Jw = [[0, c1, -s1 c2], [0, s1, c1 c2], [1, 0, s2]]
    return (
        (-y, z * s1, z * c1 * c2 - y * s2),
        (x, -z * c1, z * s1 * c2 + x * s2),
        (0.0 * x, y * c1 - x * s1, -(y * s1 * c2 + x * c1 * c2)),
    )


def rolling_bias_entries(s1, c1, s2, c2, d1, d2, d3, r, rC, w):
    """``dPsi v = (dJw v_ang) x rC + w x drC`` (the velocity-squared terms) [m/s^2], with
    ``rC`` and ``w`` from :func:`contact_offset_entries` and :func:`angular_velocity_entries`."""
    a0 = -s1 * d1 * d2 - c1 * c2 * d1 * d3 + s1 * s2 * d2 * d3  # dJw v_ang
    a1 = c1 * d1 * d2 - s1 * c2 * d1 * d3 - c1 * s2 * d2 * d3
    a2 = c2 * d2 * d3
    b0, b1, b2 = rC
    w0, w1, w2 = w
    e0 = -r * (c1 * s2 * d1 + s1 * c2 * d2)  # drC
    e1 = -r * (s1 * s2 * d1 - c1 * c2 * d2)
    e2 = -r * (-s2 * d2)
    return (
        (a1 * b2 - a2 * b1) + (w1 * e2 - w2 * e1),
        (a2 * b0 - a0 * b2) + (w2 * e0 - w0 * e2),
        (a0 * b1 - a1 * b0) + (w0 * e1 - w1 * e0),
    )


_disk_inertias = njit(disk_inertias)
_disk_mass_entries = njit(disk_mass_entries)
_disk_coriolis_entries = njit(disk_coriolis_entries)
_rolling_jacobian_entries = njit(rolling_jacobian_entries)
_contact_offset_entries = njit(contact_offset_entries)
_angular_velocity_entries = njit(angular_velocity_entries)
_rolling_bias_entries = njit(rolling_bias_entries)
