"""Scene 3: a thin disk rolling without slipping on the ground (docs/physics.md §5).

``q = (x, y, z, th1, th2, th3)``: centre of the disk, heading ``th1`` about Z,
lean ``th2`` about the moved x axis, spin ``th3`` about the moved y axis (the
symmetry axis). ``R = Rz(th1) Rx(th2) Ry(th3)``; ``v = dq/dt``.

With ``A = Ixx = Izz`` and ``C = Iyy`` the body inertias and ``n = R e_y =
(-s1 c2, c1 c2, s2)`` the spin axis, the world inertia is
``A I + (C - A) n n^T`` and ``w = Jw(q) (dth1, dth2, dth3)`` with
``Jw = [[0, c1, -s1 c2], [0, s1, c1 c2], [1, 0, s2]]``. Hence::

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
import sys
from typing import ClassVar

import numpy as np
from numba import objmode

from ..dynamics import constraints as _constraints
from ..dynamics.compiled import rk_run
from ..dynamics.jit import njit
from ..dynamics.trig import sincos_rows
from .base import Params, as_vector, param
from .constrained import ConstrainedModel
from .rolling_disk_formulas import (
    disk_inertias,
    disk_mass_entries,
    disk_coriolis_entries,
    angular_velocity_entries,
    contact_offset_entries,
    rolling_jacobian_entries,
    rolling_bias_entries,
    _disk_inertias,
    _disk_mass_entries,
    _disk_coriolis_entries,
    _rolling_jacobian_entries,
    _contact_offset_entries,
    _angular_velocity_entries,
    _rolling_bias_entries,
)


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


# kernel parameter rows (RollingDiskParams field order, :meth:`Model.kernel_params`)
_M, _R, _G, _B_ROLL, _B_PIVOT = range(5)


# -- the batch in columns, closed form ------------------------------------------------
# ``M = blockdiag(m I3, N)`` with ``N`` = [[M33, 0, M35], [0, A, 0], [M35, 0, C]] and
# ``Psi = [I3, J]``: ``S = Psi M^-1 Psi^T = I3 / m + J N^-1 J^T`` (3 x 3) is solved by its
# adjugate, the batch innermost (as FourBar's kernels); a member whose ``N`` is not positive
# definite, whose inputs are not finite or whose ``S`` is not provably well conditioned is
# recomputed by the general member path (:mod:`mbs_envs.dynamics.constraints`).


@njit
def _trig_columns(q):  # pragma: no cover - compiled
    """Rows ``(s1, c1, s2, c2)`` of heading and lean, ``q`` (6, B), as a (4, B) array."""
    return sincos_rows(q, 3, 2)


@njit
def _mass_closed(T, theta, b):  # pragma: no cover - compiled
    """``(m, A, C, M33, M35)`` of member ``b``."""
    A, C = _disk_inertias(theta[_M, b], theta[_R, b])
    M33, M35 = _disk_mass_entries(T[2, b], T[3, b], A, C)
    return theta[_M, b], A, C, M33, M35


@njit
def _jacobian_closed(T, theta, b):  # pragma: no cover - compiled
    """The angular block ``J`` of ``Psi = [I3, J]`` (rows) of member ``b``."""
    s1, c1, s2, c2 = T[0, b], T[1, b], T[2, b], T[3, b]
    x, y, z = _contact_offset_entries(s1, c1, s2, c2, theta[_R, b])
    return _rolling_jacobian_entries(s1, c1, s2, c2, x, y, z)


@njit
def _force_closed(T, v, tau, theta, b, A, C):  # pragma: no cover - compiled
    """``f = tau - (C v + G + F)`` of member ``b`` (as :func:`terms_member`)."""
    h3, h4, h5 = _disk_coriolis_entries(T[2, b], T[3, b], v[3, b], v[4, b], v[5, b], A, C)
    return (
        tau[0, b] - 0.0, tau[1, b] - 0.0, tau[2, b] - theta[_M, b] * theta[_G, b],
        tau[3, b] - (h3 + theta[_B_PIVOT, b] * v[3, b]), tau[4, b] - h4, tau[5, b] - (h5 + theta[_B_ROLL, b] * v[5, b]),
    )  # fmt: skip


@njit
def _bias_closed(T, v, theta, b):  # pragma: no cover - compiled
    """``gamma = -dPsi v`` of member ``b``."""
    s1, c1, s2, c2 = T[0, b], T[1, b], T[2, b], T[3, b]
    rC = _contact_offset_entries(s1, c1, s2, c2, theta[_R, b])
    w = _angular_velocity_entries(s1, c1, s2, c2, v[3, b], v[4, b], v[5, b])
    g0, g1, g2 = _rolling_bias_entries(s1, c1, s2, c2, v[3, b], v[4, b], v[5, b], theta[_R, b], rC, w)
    return -g0, -g1, -g2


@njit
def _residual_closed(T, q, theta, b):  # pragma: no cover - compiled
    """``phi = z - r cos th2`` of member ``b``."""
    return q[2, b] - theta[_R, b] * T[3, b]


# The member kernels of the general path (:mod:`mbs_envs.dynamics.constraints`): one member as a
# batch of one column, ``q, v, tau`` (6, 1) and ``p`` (P, 1), on the same formulas as the batch.


@njit
def mass_member(q, p, M):  # pragma: no cover - compiled
    """``M`` (6, 6) of one member."""
    m, A, C, M33, M35 = _mass_closed(_trig_columns(q), p, 0)
    M[:, :] = 0.0
    M[0, 0] = M[1, 1] = M[2, 2] = m
    M[3, 3], M[3, 5], M[5, 3], M[4, 4], M[5, 5] = M33, M35, M35, A, C


@njit
def residual_member(q, p, phi):  # pragma: no cover - compiled
    """``phi = z - r cos th2`` of one member into ``phi[0]``."""
    phi[0] = _residual_closed(_trig_columns(q), q, p, 0)


@njit
def jacobian_member(q, p, Psi):  # pragma: no cover - compiled
    """``Psi = [I3, -[rC]x Jw]`` (3, 6) of one member."""
    J = _jacobian_closed(_trig_columns(q), p, 0)
    Psi[:, :] = 0.0
    for i in range(3):
        Psi[i, i] = 1.0
        Psi[i, 3], Psi[i, 4], Psi[i, 5] = J[i][0], J[i][1], J[i][2]


@njit
def terms_member(q, v, tau, p, M, f, Psi, gamma):  # pragma: no cover - compiled
    """One member's ``M``, ``f = tau - (C v + G + F)``, ``Psi`` and ``gamma = -dPsi v``
    (the kernel interface of :func:`mbs_envs.dynamics.constraints.constrained_acceleration_columns`)."""
    T = _trig_columns(q)
    mass_member(q, p, M)
    jacobian_member(q, p, Psi)
    _, A, C, _, _ = _mass_closed(T, p, 0)
    f[0], f[1], f[2], f[3], f[4], f[5] = _force_closed(T, v, tau, p, 0, A, C)
    gamma[0], gamma[1], gamma[2] = _bias_closed(T, v, p, 0)


@njit
def _n_inv(M33, M35, A, C, y0, y1, y2):  # pragma: no cover - compiled
    """``N^-1 y`` (heading, lean, spin)."""
    d = M33 * C - M35 * M35
    return (C * y0 - M35 * y2) / d, y1 / A, (M33 * y2 - M35 * y0) / d


@njit(forceinline=True)
def _schur_closed(m, A, C, M33, M35, f, J, g):  # pragma: no cover - compiled
    """``M a = f + Psi^T lam``, ``Psi a = gamma``; returns ``(a (6-tuple), lam (3-tuple), ok)``."""
    xa = _n_inv(M33, M35, A, C, f[3], f[4], f[5])
    Y0 = _n_inv(M33, M35, A, C, J[0][0], J[0][1], J[0][2])  # N^-1 J^T, by columns
    Y1 = _n_inv(M33, M35, A, C, J[1][0], J[1][1], J[1][2])
    Y2 = _n_inv(M33, M35, A, C, J[2][0], J[2][1], J[2][2])
    im = 1.0 / m
    S00 = im + (J[0][0] * Y0[0] + J[0][1] * Y0[1] + J[0][2] * Y0[2])
    S01 = J[0][0] * Y1[0] + J[0][1] * Y1[1] + J[0][2] * Y1[2]
    S02 = J[0][0] * Y2[0] + J[0][1] * Y2[1] + J[0][2] * Y2[2]
    S11 = im + (J[1][0] * Y1[0] + J[1][1] * Y1[1] + J[1][2] * Y1[2])
    S12 = J[1][0] * Y2[0] + J[1][1] * Y2[1] + J[1][2] * Y2[2]
    S22 = im + (J[2][0] * Y2[0] + J[2][1] * Y2[1] + J[2][2] * Y2[2])
    r0 = g[0] - (f[0] * im + (J[0][0] * xa[0] + J[0][1] * xa[1] + J[0][2] * xa[2]))
    r1 = g[1] - (f[1] * im + (J[1][0] * xa[0] + J[1][1] * xa[1] + J[1][2] * xa[2]))
    r2 = g[2] - (f[2] * im + (J[2][0] * xa[0] + J[2][1] * xa[1] + J[2][2] * xa[2]))
    C00, C01, C02 = S11 * S22 - S12 * S12, S02 * S12 - S01 * S22, S01 * S12 - S02 * S11  # adjugate
    C11, C12, C22 = S00 * S22 - S02 * S02, S01 * S02 - S00 * S12, S00 * S11 - S01 * S01
    det = S00 * C00 + S01 * C01 + S02 * C02
    l0 = (C00 * r0 + C01 * r1 + C02 * r2) / det
    l1 = (C01 * r0 + C11 * r1 + C12 * r2) / det
    l2 = (C02 * r0 + C12 * r1 + C22 * r2) / det
    tr, tr_inv = S00 + S11 + S22, (C00 + C11 + C22) / det
    dN = M33 * C - M35 * M35
    ok = (m > 0.0) & (A > 0.0) & (M33 > 0.0) & (dN > 0.0) & (det > 0.0) & (tr * tr_inv * _constraints.RCOND < 1.0)
    ok = ok & np.isfinite(l0 + l1 + l2) & np.isfinite(xa[0] + xa[1] + xa[2]) & np.isfinite(f[0] + f[1] + f[2])
    a = (
        f[0] * im + l0 * im, f[1] * im + l1 * im, f[2] * im + l2 * im,
        xa[0] + Y0[0] * l0 + Y1[0] * l1 + Y2[0] * l2,
        xa[1] + Y0[1] * l0 + Y1[1] * l1 + Y2[1] * l2,
        xa[2] + Y0[2] * l0 + Y1[2] * l1 + Y2[2] * l2,
    )  # fmt: skip
    return a, (l0, l1, l2), ok


@njit
def energy_kernel(q, v, theta, E):  # pragma: no cover - compiled
    """Mechanical energy ``v^T M v / 2 + m g z`` [J] of a batch in columns (6, B); writes ``E`` (B,)."""
    T = _trig_columns(q)
    for b in range(q.shape[1]):
        m, A, C, M33, M35 = _mass_closed(T, theta, b)
        d3, d4, d5 = v[3, b], v[4, b], v[5, b]
        K = m * (v[0, b] * v[0, b] + v[1, b] * v[1, b] + v[2, b] * v[2, b])
        K += d3 * (M33 * d3 + M35 * d5) + d4 * (A * d4) + d5 * (M35 * d3 + C * d5)
        E[b] = 0.5 * K + m * theta[_G, b] * q[2, b]


#: ``|lean|`` beyond this is "flat" (:attr:`RollingDisk.flat_lean`)
FLAT_LEAN = np.pi / 2 - 0.05


@njit
def singular_kernel(q, flags):  # pragma: no cover - compiled
    """:meth:`RollingDisk.singular` of a batch in columns (6, B): sets ``flags[b]`` where ``|lean| > FLAT_LEAN``."""
    for b in range(q.shape[1]):
        flags[b] = flags[b] or abs(q[4, b]) > FLAT_LEAN


#: the rows of Psi that are the Jacobian of phi (the height)
_ROWS = np.array([2])
#: this module (its kernels passed on as module attributes are compile-time constants, see planar2r)
_this = sys.modules[__name__]


@njit
def general_acceleration(q, v, tau, theta, a):  # pragma: no cover - compiled
    """The general member path (:func:`mbs_envs.dynamics.constraints.constrained_acceleration_columns`)
    for the members the closed form leaves to it, called from object mode (compiled when first
    needed, see :func:`mbs_envs.models.fourbar.general_acceleration`)."""
    _constraints.constrained_acceleration_columns(_this.terms_member, 3, q, v, tau, theta, a)


@njit
def general_projection(q, v, theta, tol):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.constraints.project_columns` of members (see :func:`general_acceleration`)."""
    _constraints.project_columns(
        _this.residual_member, _this.jacobian_member, _this.mass_member, _ROWS, 3, q, v, theta, tol
    )


@njit
def general_constraint_info(q, v, tau, theta, res, lam):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.constraints.constraint_info_columns` of members (see :func:`general_acceleration`)."""
    _constraints.constraint_info_columns(_this.terms_member, _this.residual_member, q, v, tau, theta, res, lam)


@njit
def acceleration_kernel(q, v, tau, theta, a):  # pragma: no cover - compiled
    """Forward dynamics with the rolling constraints (Schur complement), a batch in columns (6, B)."""
    B = q.shape[1]
    T = _trig_columns(q)
    ok = np.empty(B, np.bool_)
    for b in range(B):
        m, A, C, M33, M35 = _mass_closed(T, theta, b)
        f = _force_closed(T, v, tau, theta, b, A, C)
        acc, _, ok[b] = _schur_closed(m, A, C, M33, M35, f, _jacobian_closed(T, theta, b), _bias_closed(T, v, theta, b))
        for i in range(6):
            a[i, b] = acc[i]
    for b in range(B):
        if not ok[b]:  # the general member path
            ab = np.empty((6, 1))
            qb, vb, tb, pb = (
                _constraints.column(q, b),
                _constraints.column(v, b),
                _constraints.column(tau, b),
                _constraints.column(theta, b),
            )
            with objmode():  # compiled on first use (see general_acceleration)
                _this.general_acceleration(qb, vb, tb, pb, ab)
            for i in range(6):
                a[i, b] = ab[i, 0]


@njit
def project_kernel(q, v, theta, tol):  # pragma: no cover - compiled
    """:meth:`RollingDisk.project` of a batch in columns, in place: Gauss-Newton on the height
    ``phi = z - r cos th2`` (its row of ``Psi`` has norm >= 1: always well conditioned; at most
    20 iterations), then ``v`` onto ``Psi v = 0`` in the kinetic-energy metric, closed form."""
    B = q.shape[1]
    q_in, v_in = q.copy(), v.copy()
    for it in range(20):
        T = _trig_columns(q)
        n_active = 0
        for b in range(B):  # selects, not branches: one SIMD pass
            phi = _residual_closed(T, q, theta, b)
            J2 = _jacobian_closed(T, theta, b)[2]  # the height row: (0, 0, 1, J2)
            active = abs(phi) > tol
            y = phi / (1.0 + (J2[0] * J2[0] + J2[1] * J2[1] + J2[2] * J2[2]))
            q[2, b] = q[2, b] - y if active else q[2, b]
            q[3, b] = q[3, b] - J2[0] * y if active else q[3, b]
            q[4, b] = q[4, b] - J2[1] * y if active else q[4, b]
            q[5, b] = q[5, b] - J2[2] * y if active else q[5, b]
            n_active += active
        if n_active == 0:  # q unchanged since T
            break
    if n_active > 0:
        T = _trig_columns(q)
    ok = np.empty(B, np.bool_)
    for b in range(B):
        m, A, C, M33, M35 = _mass_closed(T, theta, b)
        J = _jacobian_closed(T, theta, b)
        g = (
            -(v[0, b] + (J[0][0] * v[3, b] + J[0][1] * v[4, b] + J[0][2] * v[5, b])),
            -(v[1, b] + (J[1][0] * v[3, b] + J[1][1] * v[4, b] + J[1][2] * v[5, b])),
            -(v[2, b] + (J[2][0] * v[3, b] + J[2][1] * v[4, b] + J[2][2] * v[5, b])),
        )
        dv, _, okb = _schur_closed(m, A, C, M33, M35, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0), J, g)
        ok[b] = okb
        v[0, b] = v[0, b] + dv[0] if okb else v[0, b]
        v[1, b] = v[1, b] + dv[1] if okb else v[1, b]
        v[2, b] = v[2, b] + dv[2] if okb else v[2, b]
        v[3, b] = v[3, b] + dv[3] if okb else v[3, b]
        v[4, b] = v[4, b] + dv[4] if okb else v[4, b]
        v[5, b] = v[5, b] + dv[5] if okb else v[5, b]
    for b in range(B):
        if not ok[b]:  # the general member path, from the member's state as it came in
            qb, vb, pb = _constraints.column(q_in, b), _constraints.column(v_in, b), _constraints.column(theta, b)
            with objmode():
                _this.general_projection(qb, vb, pb, tol)
            for i in range(6):
                q[i, b], v[i, b] = qb[i, 0], vb[i, 0]


@njit
def constraint_info_kernel(q, v, tau, theta, res, lam):  # pragma: no cover - compiled
    """``|phi|`` and the contact force (B, 3) of a batch in columns (``lam`` without rows: ``|phi|`` only)."""
    B = q.shape[1]
    T = _trig_columns(q)
    for b in range(B):
        res[b] = abs(_residual_closed(T, q, theta, b))
    if lam.shape[0] == 0:
        return
    ok = np.empty(B, np.bool_)
    for b in range(B):
        m, A, C, M33, M35 = _mass_closed(T, theta, b)
        f = _force_closed(T, v, tau, theta, b, A, C)
        _, lb, ok[b] = _schur_closed(m, A, C, M33, M35, f, _jacobian_closed(T, theta, b), _bias_closed(T, v, theta, b))
        lam[b, 0], lam[b, 1], lam[b, 2] = lb
    for b in range(B):
        if not ok[b]:  # the general member path
            rb, lb2 = np.empty(1), np.empty((1, 3))
            qb, vb, tb, pb = (
                _constraints.column(q, b),
                _constraints.column(v, b),
                _constraints.column(tau, b),
                _constraints.column(theta, b),
            )
            with objmode():
                _this.general_constraint_info(qb, vb, tb, pb, rb, lb2)
            res[b], lam[b, 0], lam[b, 1], lam[b, 2] = rb[0], lb2[0, 0], lb2[0, 1], lb2[0, 2]


@njit
def advance_kernel(theta, stepper, q, v, tau):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.compiled.rk_run` with the projection after every step (cached on disk)."""
    rk_run(_this.acceleration_kernel, _this.project_kernel, theta, stepper, q, v, tau)


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
    #: ``|lean|`` beyond this is "flat": the Euler angles are near their singularity
    flat_lean: ClassVar[float] = FLAT_LEAN

    # -- compiled path (see :mod:`mbs_envs.dynamics.compiled`) -----------------------------
    kernels = (acceleration_kernel, energy_kernel)
    advance_kernel = staticmethod(advance_kernel)
    project_kernel = staticmethod(project_kernel)
    constraint_info_kernel = staticmethod(constraint_info_kernel)

    @property
    def inertias(self) -> tuple[float, float]:
        """``(A, C) = (m r^2 / 4, m r^2 / 2)`` [kg m^2]: diametral and axial."""
        return disk_inertias(self.params.m, self.params.r)

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
        M[..., 3, 3], M[..., 3, 5] = disk_mass_entries(s2, c2, A, C)
        M[..., 5, 3] = M[..., 3, 5]
        M[..., 4, 4] = A
        M[..., 5, 5] = C
        return M

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C v`` from the Christoffel symbols of ``M(th2)``, shape ``(..., 6)``."""
        q = as_vector(q, 6, "q")
        v = as_vector(v, 6, "v")
        A, C = self.inertias
        s2, c2 = np.sin(q[..., 4]), np.cos(q[..., 4])
        out = np.zeros(np.broadcast_shapes(q.shape, v.shape))
        out[..., 3], out[..., 4], out[..., 5] = disk_coriolis_entries(s2, c2, v[..., 3], v[..., 4], v[..., 5], A, C)
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
        return np.stack(
            np.broadcast_arrays(*angular_velocity_entries(*self._trig(q), v[..., 3], v[..., 4], v[..., 5])), axis=-1
        )

    def contact_offset(self, q: np.ndarray) -> np.ndarray:
        """Contact point relative to the centre, ``rC = -r (s1 s2, -c1 s2, c2)`` [m]."""
        q = as_vector(q, 6, "q")
        return np.stack(contact_offset_entries(*self._trig(q), self.params.r), axis=-1)

    def orientation(self, q: np.ndarray) -> np.ndarray:
        """The disk's rotation ``R = Rz(th1) Rx(th2) Ry(th3)`` (body to ground), shape ``(..., 3, 3)``:
        its columns ``R e_x`` and ``R e_z`` span the disk's plane, ``R e_y`` is :meth:`spin_axis`."""
        q = as_vector(q, 6, "q")
        s1, c1, s2, c2 = self._trig(q)
        s3, c3 = np.sin(q[..., 5]), np.cos(q[..., 5])
        zero, one = np.zeros_like(s1), np.ones_like(s1)

        def mat(*rows):
            return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)

        Rz = mat((c1, -s1, zero), (s1, c1, zero), (zero, zero, one))
        Rx = mat((one, zero, zero), (zero, c2, -s2), (zero, s2, c2))
        Ry = mat((c3, zero, s3), (zero, one, zero), (-s3, zero, c3))
        return Rz @ Rx @ Ry

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
        Psi = np.zeros(q.shape[:-1] + (3, 6))
        Psi[..., :, :3] = np.eye(3)
        # w x rC = -rC x w = -[rC]x Jw v_ang
        trig = self._trig(q)
        for i, row in enumerate(rolling_jacobian_entries(*trig, *contact_offset_entries(*trig, self.params.r))):
            for j, entry in enumerate(row):
                Psi[..., i, 3 + j] = entry
        return Psi

    def constraint_bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``dPsi v = (dJw v_ang) x rC + w x drC`` (velocity-squared terms), shape ``(..., 3)``."""
        q = as_vector(q, 6, "q")
        v = as_vector(v, 6, "v")
        trig, rates = self._trig(q), (v[..., 3], v[..., 4], v[..., 5])
        rC = contact_offset_entries(*trig, self.params.r)
        entries = rolling_bias_entries(*trig, *rates, self.params.r, rC, angular_velocity_entries(*trig, *rates))
        return np.stack(np.broadcast_arrays(*entries), axis=-1)

    # -- states -------------------------------------------------------------------

    def complete(self, q: np.ndarray, x_ind: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Full vector with the angular rates ``x_ind`` and ``Psi x = rhs``: as ``Psi = [I3, J]``,
        the centre's part is ``rhs - J x_ind`` (what the general pseudo-inverse gives, without it)."""
        q = as_vector(q, 6, "q")
        x_ind = as_vector(x_ind, 3, "independent values")
        J = self.constraint_jacobian(q)[..., :, 3:]
        x_dep = rhs - np.einsum("...ij,...j->...i", J, x_ind)
        return np.concatenate(np.broadcast_arrays(x_dep, x_ind), axis=-1)

    def moving_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Rolling at twice the critical spin, leaning 0.1 rad (:meth:`rolling_state`)."""
        return self.rolling_state(lean=0.1, dspin=2 * self.critical_spin)

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
        centre's velocity from the rolling constraints. Batched: every argument a float or an array
        of shape ``(...)`` (broadcast together, and with per-member parameters).

        Returns
        -------
        q, v : ndarray, shape (..., 6)
        """
        lean = np.asarray(lean, float)
        inside = np.abs(lean) < self.flat_lean
        if not np.all(inside):
            raise ValueError(
                f"lean must be within +-{self.flat_lean:.3f} rad of upright, got {float(lean[~inside].flat[0])!r}"
            )
        q = np.stack(
            np.broadcast_arrays(
                *(np.asarray(c, float) for c in (x, y, self.params.r * np.cos(lean), heading, lean, spin))
            ),
            axis=-1,
        )
        v = self.complete_velocity(
            q, np.stack(np.broadcast_arrays(*(np.asarray(c, float) for c in (dheading, dlean, dspin))), axis=-1)
        )
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
