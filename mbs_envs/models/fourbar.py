"""Scene 2: the planar four-bar linkage, a closed loop (docs/physics.md §4).

Ground pivots ``O1 = (0, 0)``, ``O4 = (l0, 0)``. The loop is cut at the joint B
between coupler (link 2) and rocker (link 3): a 2R chain (crank, coupler) plus
a 1R link (rocker). ``q = (th1, ph2, ph1)``: crank angle from +x, coupler angle
relative to the crank, absolute rocker angle about ``O4``. Only the crank is
driven, ``B = (1, 0, 0)^T``; one degree of freedom.

The 2R part's equations are :class:`~mbs_envs.models.planar2r.Planar2R`'s (the
model composes one), the rocker adds a block ``m3 r3^2 + I3``.
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
from ..dynamics.trig import sincos_columns
from . import planar2r as _p2r
from .base import Params, as_vector, param, smoothed_friction
from .constrained import ConstrainedModel
from .planar2r import Planar2R

#: Grashof classes by which link is shortest when s + l < p + q.
GRASHOF_BY_SHORTEST = {
    "l0": "double-crank",
    "l1": "crank-rocker",
    "l2": "double-rocker",
    "l3": "rocker-crank",
}


def grashof_class(l0: float, l1: float, l2: float, l3: float, rtol: float = 1e-12) -> str:
    """Grashof classification of a four-bar with ground ``l0``, crank ``l1``,
    coupler ``l2``, rocker ``l3``.

    With ``s``/``l`` the shortest/longest and ``p, q`` the others: ``s + l < p + q``
    is Grashof (the shortest link turns fully): ``"crank-rocker"`` (crank
    shortest), ``"double-crank"`` (ground shortest), ``"double-rocker"``
    (coupler shortest) or ``"rocker-crank"`` (rocker shortest, so it turns
    fully and the crank rocks); ``s + l = p + q`` (to ``rtol``) is
    ``"change-point"``; otherwise ``"triple-rocker"`` (non-Grashof).
    """
    lengths = {"l0": l0, "l1": l1, "l2": l2, "l3": l3}
    ordered = sorted(lengths.values())
    s, l = ordered[0], ordered[-1]
    pq = ordered[1] + ordered[2]
    if abs((s + l) - pq) <= rtol * (s + l):
        return "change-point"
    if s + l < pq:
        return GRASHOF_BY_SHORTEST[min(lengths, key=lengths.get)]
    return "triple-rocker"


@dataclasses.dataclass(frozen=True)
class FourBarParams(Params):
    """Parameters of :class:`FourBar`; defaults: a Grashof crank-rocker of
    uniform rods of 1 kg/m (``l0, l1, l2, l3 = 1, 0.3, 1, 0.8`` m).

    Friction acts at the crank pivot (``b1, f1``, rate ``dth1``), the
    crank-coupler joint (``b2, f2``, rate ``dph2``) and the rocker pivot
    (``b3, f3``, rate ``dph1``); the cut joint B is frictionless.
    """

    l0: float = param(1.0, "positive", "m", "ground link O1-O4")
    l1: float = param(0.3, "positive", "m", "crank")
    l2: float = param(1.0, "positive", "m", "coupler")
    l3: float = param(0.8, "positive", "m", "rocker")
    m1: float = param(0.3, "positive", "kg", "crank mass")
    m2: float = param(1.0, "positive", "kg", "coupler mass")
    m3: float = param(0.8, "positive", "kg", "rocker mass")
    r1: float = param(0.15, "nonnegative", "m", "O1 to crank COM")
    r2: float = param(0.5, "nonnegative", "m", "A to coupler COM")
    r3: float = param(0.4, "nonnegative", "m", "O4 to rocker COM")
    I1: float = param(0.3 * 0.3**2 / 12, "nonnegative", "kg m^2", "crank inertia about COM")
    I2: float = param(1.0 / 12, "nonnegative", "kg m^2", "coupler inertia about COM")
    I3: float = param(0.8 * 0.8**2 / 12, "nonnegative", "kg m^2", "rocker inertia about COM")
    g: float = param(9.81, "finite", "m/s^2", "gravity along -y")
    b1: float = param(0.0, "nonnegative", "N m s/rad", "viscous friction, crank pivot")
    b2: float = param(0.0, "nonnegative", "N m s/rad", "viscous friction, crank-coupler joint")
    b3: float = param(0.0, "nonnegative", "N m s/rad", "viscous friction, rocker pivot")
    f1: float = param(0.0, "nonnegative", "N m", "Coulomb friction, crank pivot")
    f2: float = param(0.0, "nonnegative", "N m", "Coulomb friction, crank-coupler joint")
    f3: float = param(0.0, "nonnegative", "N m", "Coulomb friction, rocker pivot")
    v_s: float = param(0.01, "positive", "rad/s", "Coulomb smoothing speed")
    df1: float = param(0.0, "nonnegative", "N m", "Stribeck excess (static above Coulomb friction), crank pivot")
    df2: float = param(0.0, "nonnegative", "N m", "Stribeck excess, crank-coupler joint")
    df3: float = param(0.0, "nonnegative", "N m", "Stribeck excess, rocker pivot")
    v_st: float = param(0.1, "positive", "rad/s", "Stribeck speed")

    def _check(self) -> None:
        lengths = {"l0": self.l0, "l1": self.l1, "l2": self.l2, "l3": self.l3}
        longest = max(lengths, key=lengths.get)
        others = sum(v for k, v in lengths.items() if k != longest)
        if not lengths[longest] < others:
            raise ValueError(
                f"parameter {longest}: the linkage cannot assemble, the longest link "
                f"({lengths[longest]:g} m) must be shorter than the sum of the others ({others:g} m)"
            )
        for i in (1, 2, 3):
            I, m, r = (getattr(self, f"{k}{i}") for k in ("I", "m", "r"))
            if not I + m * r**2 > 0:
                raise ValueError(f"parameters I{i}, r{i}: link {i} has no inertia about its joint")


# ---------------------------------------------------------------------------
# The loop closure, written once: floats or broadcasting arrays (the numpy
# methods of :class:`FourBar`) and one member's floats (the kernels below),
# from the cosines and sines of th1, th12 = th1 + ph2 and ph1.
# ---------------------------------------------------------------------------


def closure_residual(c1, s1, c12, s12, c3, s3, l0, l1, l2, l3):
    """``phi = (l1 c1 + l2 c12 - l0 - l3 c3, l1 s1 + l2 s12 - l3 s3)`` [m]."""
    return l1 * c1 + l2 * c12 - l0 - l3 * c3, l1 * s1 + l2 * s12 - l3 * s3


def closure_jacobian(c1, s1, c12, s12, c3, s3, l1, l2, l3):
    """The rows of ``Psi = d phi / d q``: ``((P00, P01, P02), (P10, P11, P12))`` [m]."""
    return (-l1 * s1 - l2 * s12, -l2 * s12, l3 * s3), (l1 * c1 + l2 * c12, l2 * c12, -l3 * c3)


def closure_bias(c1, s1, c12, s12, c3, s3, w1, w12, w3, l1, l2, l3):
    """``dPsi v`` [m/s^2] from the squared rates ``w1 = dth1^2``, ``w12 = (dth1 + dph2)^2``, ``w3 = dph1^2``."""
    return (
        -l1 * c1 * w1 - l2 * c12 * w12 + l3 * c3 * w3,
        -l1 * s1 * w1 - l2 * s12 * w12 + l3 * s3 * w3,
    )


_closure_residual = njit(closure_residual)
_closure_jacobian = njit(closure_jacobian)
_closure_bias = njit(closure_bias)

# kernel parameter rows (FourBarParams field order, :meth:`Model.kernel_params`)
_L0, _L1, _L2, _L3, _M1, _M2, _M3, _R1, _R2, _R3, _I1, _I2, _I3, _G = range(14)
_B1, _F1, _VS, _DF1, _VST = 14, 17, 20, 21, 24


# -- the batch in columns, closed form ------------------------------------------------
# The Schur solve of a 2 x 2 complement of a block-diagonal 3 x 3 M, written out by
# Cramer's rule, with the batch innermost so that LLVM vectorizes the loops (as
# Planar2R's kernels). A member whose M is not positive definite, whose inputs are not
# finite, or whose complement is not provably well conditioned (the criterion of
# :func:`mbs_envs.dynamics.constraints._cholesky_solve_if_well_conditioned`) is recomputed by the
# general member path (pseudo-inverse, NaN), so both give the numpy path's results.


@njit
def _trig_columns(q):  # pragma: no cover - compiled
    """Rows ``(c1, s1, c12, s12, c3, s3, c2, s2)`` of ``q`` (3, B) as an (8, B) array."""
    B = q.shape[1]
    T = np.empty((8, B))
    w = np.empty(B)
    for b in range(B):
        w[b] = q[0, b] + q[1, b]
    sincos_columns(q[0], T[1], T[0])
    sincos_columns(w, T[3], T[2])
    sincos_columns(q[2], T[5], T[4])
    sincos_columns(q[1], T[7], T[6])
    return T


@njit
def _friction_columns(v, theta):  # pragma: no cover - compiled
    """Joint friction (3, B) in a pass of its own (its tanh keeps a loop scalar)."""
    F = np.empty(v.shape)
    for b in range(v.shape[1]):
        for i in range(3):
            F[i, b] = _p2r._friction(
                v[i, b], theta[_B1 + i, b], theta[_F1 + i, b], theta[_VS, b], theta[_DF1 + i, b], theta[_VST, b]
            )
    return F


@njit
def _mass_closed(T, theta, b):  # pragma: no cover - compiled
    """``(M11, M12, M22, M33)`` of member ``b``."""
    m11, m12, m22 = _p2r._mass_entries(
        T[6, b], theta[_M1, b], theta[_M2, b], theta[_L1, b], theta[_R1, b], theta[_R2, b], theta[_I1, b], theta[_I2, b]
    )
    return m11, m12, m22, theta[_I3, b] + theta[_M3, b] * theta[_R3, b] ** 2


@njit
def _jacobian_closed(T, theta, b):  # pragma: no cover - compiled
    """The rows of ``Psi`` of member ``b``."""
    return _closure_jacobian(
        T[0, b], T[1, b], T[2, b], T[3, b], T[4, b], T[5, b], theta[_L1, b], theta[_L2, b], theta[_L3, b]
    )


@njit
def _force_closed(T, v, tau, F, theta, b):  # pragma: no cover - compiled
    """``f = tau - (C v + G + F)`` of member ``b`` (as :func:`terms_member`)."""
    h1, h2 = _p2r._coriolis_entries(T[7, b], v[0, b], v[1, b], theta[_M2, b], theta[_L1, b], theta[_R2, b])
    g1, g2 = _p2r._gravity_entries(
        T[0, b], T[2, b], theta[_M1, b], theta[_M2, b], theta[_L1, b], theta[_R1, b], theta[_R2, b], theta[_G, b]
    )
    g3 = theta[_M3, b] * theta[_G, b] * theta[_R3, b] * T[4, b]
    return tau[0, b] - (h1 + g1 + F[0, b]), tau[1, b] - (h2 + g2 + F[1, b]), tau[2, b] - (0.0 + g3 + F[2, b])


@njit
def _bias_closed(T, v, theta, b):  # pragma: no cover - compiled
    """``gamma = -dPsi v`` of member ``b``."""
    w12 = v[0, b] + v[1, b]
    d0, d1 = _closure_bias(
        T[0, b],
        T[1, b],
        T[2, b],
        T[3, b],
        T[4, b],
        T[5, b],
        v[0, b] ** 2,
        w12**2,
        v[2, b] ** 2,
        theta[_L1, b],
        theta[_L2, b],
        theta[_L3, b],
    )
    return -d0, -d1


@njit
def _residual_closed(T, theta, b):  # pragma: no cover - compiled
    """``phi`` of member ``b``."""
    return _closure_residual(
        T[0, b], T[1, b], T[2, b], T[3, b], T[4, b], T[5, b], theta[_L0, b], theta[_L1, b], theta[_L2, b], theta[_L3, b]
    )


# The member kernels of the general path (:mod:`mbs_envs.dynamics.constraints`): one member as a
# batch of one column, ``q, v, tau`` (3, 1) and ``p`` (P, 1), on the same formulas as the batch.


@njit
def mass_member(q, p, M):  # pragma: no cover - compiled
    """``M = blockdiag(M_2R, I3 + m3 r3^2)`` of one member into ``M`` (3, 3)."""
    m11, m12, m22, m33 = _mass_closed(_trig_columns(q), p, 0)
    M[:, :] = 0.0
    M[0, 0], M[0, 1], M[1, 0], M[1, 1], M[2, 2] = m11, m12, m12, m22, m33


@njit
def residual_member(q, p, phi):  # pragma: no cover - compiled
    """``phi(q)`` of one member into ``phi`` (2,)."""
    phi[0], phi[1] = _residual_closed(_trig_columns(q), p, 0)


@njit
def jacobian_member(q, p, Psi):  # pragma: no cover - compiled
    """``Psi(q)`` of one member into ``Psi`` (2, 3)."""
    r0, r1 = _jacobian_closed(_trig_columns(q), p, 0)
    Psi[0, 0], Psi[0, 1], Psi[0, 2] = r0
    Psi[1, 0], Psi[1, 1], Psi[1, 2] = r1


@njit
def terms_member(q, v, tau, p, M, f, Psi, gamma):  # pragma: no cover - compiled
    """One member's ``M``, ``f = tau - (C v + G + F)``, ``Psi`` and ``gamma = -dPsi v``
    (the kernel interface of :func:`mbs_envs.dynamics.constraints.constrained_acceleration_columns`)."""
    T = _trig_columns(q)
    mass_member(q, p, M)
    jacobian_member(q, p, Psi)
    f[0], f[1], f[2] = _force_closed(T, v, tau, _friction_columns(v, p), p, 0)
    gamma[0], gamma[1] = _bias_closed(T, v, p, 0)


@njit(forceinline=True)
def _schur_closed(m11, m12, m22, m33, f1, f2, f3, P0, P1, g0, g1):  # pragma: no cover - compiled
    """``M a = f + Psi^T lam``, ``Psi a = gamma`` for ``M = blockdiag([[m11, m12], [m12, m22]], m33)``
    and ``Psi`` rows ``P0, P1``; returns ``(a1, a2, a3, lam0, lam1, ok)``, ``ok`` False where the
    general path must decide (see above)."""
    det = m11 * m22 - m12 * m12
    x1, x2, x3 = (m22 * f1 - m12 * f2) / det, (m11 * f2 - m12 * f1) / det, f3 / m33
    y1, y2, y3 = (m22 * P0[0] - m12 * P0[1]) / det, (m11 * P0[1] - m12 * P0[0]) / det, P0[2] / m33
    z1, z2, z3 = (m22 * P1[0] - m12 * P1[1]) / det, (m11 * P1[1] - m12 * P1[0]) / det, P1[2] / m33
    S00 = P0[0] * y1 + P0[1] * y2 + P0[2] * y3
    S01 = P0[0] * z1 + P0[1] * z2 + P0[2] * z3
    S11 = P1[0] * z1 + P1[1] * z2 + P1[2] * z3
    r0 = g0 - (P0[0] * x1 + P0[1] * x2 + P0[2] * x3)
    r1 = g1 - (P1[0] * x1 + P1[1] * x2 + P1[2] * x3)
    dS = S00 * S11 - S01 * S01
    lam0 = (S11 * r0 - S01 * r1) / dS
    lam1 = (S00 * r1 - S01 * r0) / dS
    tr = S00 + S11
    ok = (m11 > 0.0) & (det > 0.0) & (m33 > 0.0) & (dS > 0.0) & (tr * tr * _constraints.RCOND < dS)
    ok = ok & np.isfinite(lam0) & np.isfinite(lam1) & np.isfinite(x1 + x2 + x3)
    return x1 + y1 * lam0 + z1 * lam1, x2 + y2 * lam0 + z2 * lam1, x3 + y3 * lam0 + z3 * lam1, lam0, lam1, ok


@njit
def energy_kernel(q, v, theta, E):  # pragma: no cover - compiled
    """Mechanical energy ``v^T M v / 2 + V`` [J] of a batch in columns: ``q, v`` (3, B); writes ``E`` (B,)."""
    T = _trig_columns(q)
    for b in range(q.shape[1]):
        m11, m12, m22, m33 = _mass_closed(T, theta, b)
        d1, d2, d3 = v[0, b], v[1, b], v[2, b]
        K = d1 * (m11 * d1 + m12 * d2) + d2 * (m12 * d1 + m22 * d2) + d3 * (m33 * d3)
        V = _p2r._potential_entry(
            T[1, b], T[3, b], theta[_M1, b], theta[_M2, b], theta[_L1, b], theta[_R1, b], theta[_R2, b], theta[_G, b]
        )
        E[b] = 0.5 * K + (V + theta[_M3, b] * theta[_G, b] * theta[_R3, b] * T[5, b])


#: the rows of Psi that are the Jacobian of phi (both)
_ROWS = np.array([0, 1])
#: this module (its kernels passed on as module attributes are compile-time constants, see planar2r)
_this = sys.modules[__name__]


@njit
def general_acceleration(q, v, tau, theta, a):  # pragma: no cover - compiled
    """The general member path (:func:`mbs_envs.dynamics.constraints.constrained_acceleration_columns`)
    for the members the closed form leaves to it. The batch kernels call the three ``general_*``
    kernels from object mode, so that numba compiles them only in a process that needs them."""
    _constraints.constrained_acceleration_columns(_this.terms_member, 2, q, v, tau, theta, a)


@njit
def general_projection(q, v, theta, tol):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.constraints.project_columns` of members (see :func:`general_acceleration`)."""
    _constraints.project_columns(
        _this.residual_member, _this.jacobian_member, _this.mass_member, _ROWS, 2, q, v, theta, tol
    )


@njit
def general_constraint_info(q, v, tau, theta, res, lam):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.constraints.constraint_info_columns` of members (see :func:`general_acceleration`)."""
    _constraints.constraint_info_columns(_this.terms_member, _this.residual_member, q, v, tau, theta, res, lam)


@njit
def acceleration_kernel(q, v, tau, theta, a):  # pragma: no cover - compiled
    """Forward dynamics with the loop closed (Schur complement), a batch in columns (3, B)."""
    B = q.shape[1]
    T, F = _trig_columns(q), _friction_columns(v, theta)
    ok = np.empty(B, np.bool_)
    for b in range(B):
        m11, m12, m22, m33 = _mass_closed(T, theta, b)
        f1, f2, f3 = _force_closed(T, v, tau, F, theta, b)
        P0, P1 = _jacobian_closed(T, theta, b)
        g0, g1 = _bias_closed(T, v, theta, b)
        a[0, b], a[1, b], a[2, b], _, _, ok[b] = _schur_closed(m11, m12, m22, m33, f1, f2, f3, P0, P1, g0, g1)
    for b in range(B):
        if not ok[b]:  # the general member path
            ab = np.empty((3, 1))
            qb, vb, tb, pb = (
                _constraints.column(q, b),
                _constraints.column(v, b),
                _constraints.column(tau, b),
                _constraints.column(theta, b),
            )
            with objmode():  # compiled on first use (see general_acceleration)
                _this.general_acceleration(qb, vb, tb, pb, ab)
            for i in range(3):
                a[i, b] = ab[i, 0]


@njit
def project_kernel(q, v, theta, tol):  # pragma: no cover - compiled
    """:meth:`FourBar.project` of a batch in columns, in place: Gauss-Newton on ``phi`` (at most
    20 iterations, a member stops when ``max |phi| <= tol``), then ``v`` onto ``Psi v = 0`` in
    the kinetic-energy metric: :func:`mbs_envs.dynamics.constraints.project_columns` in closed form."""
    B = q.shape[1]
    q_in, v_in = q.copy(), v.copy()
    general = np.zeros(B, np.bool_)
    active = np.empty(B, np.bool_)
    for it in range(21):
        T = _trig_columns(q)
        n_active = 0
        for b in range(B):
            phi0, phi1 = _residual_closed(T, theta, b)
            active[b] = ((abs(phi0) > tol) | (abs(phi1) > tol)) & (not general[b]) & (it < 20)
            n_active += active[b]
            if active[b]:  # q -= P^T (P P^T)^-1 phi
                P0, P1 = _jacobian_closed(T, theta, b)
                G00 = P0[0] * P0[0] + P0[1] * P0[1] + P0[2] * P0[2]
                G01 = P0[0] * P1[0] + P0[1] * P1[1] + P0[2] * P1[2]
                G11 = P1[0] * P1[0] + P1[1] * P1[1] + P1[2] * P1[2]
                dG = G00 * G11 - G01 * G01
                trG = G00 + G11
                if dG > 0.0 and trG * trG * _constraints.RCOND < dG:
                    y0 = (G11 * phi0 - G01 * phi1) / dG
                    y1 = (G00 * phi1 - G01 * phi0) / dG
                    for i in range(3):
                        q[i, b] -= P0[i] * y0 + P1[i] * y1
                else:
                    general[b] = True
        if n_active == 0:  # q unchanged since T
            break
    if n_active > 0:
        T = _trig_columns(q)
    for b in range(B):
        m11, m12, m22, m33 = _mass_closed(T, theta, b)
        P0, P1 = _jacobian_closed(T, theta, b)
        g0 = -(P0[0] * v[0, b] + P0[1] * v[1, b] + P0[2] * v[2, b])
        g1 = -(P1[0] * v[0, b] + P1[1] * v[1, b] + P1[2] * v[2, b])
        d1, d2, d3, _, _, ok = _schur_closed(m11, m12, m22, m33, 0.0, 0.0, 0.0, P0, P1, g0, g1)
        if ok and not general[b]:
            v[0, b] += d1
            v[1, b] += d2
            v[2, b] += d3
        else:  # the general member path, from the member's state as it came in
            qb, vb, pb = _constraints.column(q_in, b), _constraints.column(v_in, b), _constraints.column(theta, b)
            with objmode():
                _this.general_projection(qb, vb, pb, tol)
            for i in range(3):
                q[i, b], v[i, b] = qb[i, 0], vb[i, 0]


@njit
def constraint_info_kernel(q, v, tau, theta, res, lam):  # pragma: no cover - compiled
    """``max |phi|`` and the multipliers (B, 2) of a batch in columns (``lam`` without rows: ``max |phi|`` only)."""
    B = q.shape[1]
    T = _trig_columns(q)
    for b in range(B):
        phi0, phi1 = _residual_closed(T, theta, b)
        x0, x1 = abs(phi0), abs(phi1)
        res[b] = x0 if (x0 > x1 or x0 != x0) else x1
    if lam.shape[0] == 0:
        return
    F = _friction_columns(v, theta)
    ok = np.empty(B, np.bool_)
    for b in range(B):
        m11, m12, m22, m33 = _mass_closed(T, theta, b)
        f1, f2, f3 = _force_closed(T, v, tau, F, theta, b)
        P0, P1 = _jacobian_closed(T, theta, b)
        g0, g1 = _bias_closed(T, v, theta, b)
        _, _, _, lam[b, 0], lam[b, 1], ok[b] = _schur_closed(m11, m12, m22, m33, f1, f2, f3, P0, P1, g0, g1)
    for b in range(B):
        if not ok[b]:  # the general member path
            rb, lb = np.empty(1), np.empty((1, 2))
            qb, vb, tb, pb = (
                _constraints.column(q, b),
                _constraints.column(v, b),
                _constraints.column(tau, b),
                _constraints.column(theta, b),
            )
            with objmode():
                _this.general_constraint_info(qb, vb, tb, pb, rb, lb)
            res[b], lam[b, 0], lam[b, 1] = rb[0], lb[0, 0], lb[0, 1]


@njit
def advance_kernel(theta, stepper, q, v, tau):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.compiled.rk_run` with the projection after every step (cached on disk)."""
    rk_run(_this.acceleration_kernel, _this.project_kernel, theta, stepper, q, v, tau)


class FourBar(ConstrainedModel):
    """Four-bar linkage as a DAE with Lagrange multipliers (docs/physics.md §4).

    The loop closure::

        phi(q) = (l1 c1 + l2 cos(th1 + ph2) - l0 - l3 cos ph1,
                  l1 s1 + l2 sin(th1 + ph2) - l3 sin ph1)

    is the position of joint B reached through the chain minus through the rocker.
    The multipliers ``lam`` are then the force [N] the rocker exerts on the
    coupler at B (the rocker feels ``-lam``).
    """

    Params = FourBarParams
    nq = 3
    nv = 3
    nu = 1
    nc = 2
    independent: ClassVar[tuple[int, ...]] = (0,)

    # -- compiled path (see :mod:`mbs_envs.dynamics.compiled`) -----------------------------
    kernels = (acceleration_kernel, energy_kernel)
    advance_kernel = staticmethod(advance_kernel)
    project_kernel = staticmethod(project_kernel)
    constraint_info_kernel = staticmethod(constraint_info_kernel)

    def __init__(self, params=None, **overrides):
        super().__init__(params, **overrides)
        p = self.params
        self.chain = Planar2R(
            m1=p.m1, m2=p.m2, l1=p.l1, l2=p.l2, r1=p.r1, r2=p.r2, I1=p.I1, I2=p.I2, g=p.g, v_s=p.v_s,
            b1=p.b1, b2=p.b2, f1=p.f1, f2=p.f2, df1=p.df1, df2=p.df2, v_st=p.v_st,
        )  # fmt: skip

    @property
    def grashof(self) -> str:
        """Grashof class of the linkage (see :func:`grashof_class`)."""
        p = self.params
        return grashof_class(p.l0, p.l1, p.l2, p.l3)

    @property
    def actuation(self) -> np.ndarray:
        """``B = (1, 0, 0)^T``: the crank torque."""
        return np.array([[1.0], [0.0], [0.0]])

    def _rocker_inertia(self) -> float:
        p = self.params
        return p.I3 + p.m3 * p.r3**2

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``blockdiag(M_2R(th1, ph2), m3 r3^2 + I3)``, shape ``(..., 3, 3)``."""
        q = as_vector(q, 3, "q")
        M = np.zeros(q.shape[:-1] + (3, 3))
        M[..., :2, :2] = self.chain.mass_matrix(q[..., :2])
        M[..., 2, 2] = self._rocker_inertia()
        return M

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The 2R chain's ``C v`` and zero for the rocker, shape ``(..., 3)``."""
        q = as_vector(q, 3, "q")
        v = as_vector(v, 3, "v")
        cv = self.chain.coriolis(q[..., :2], v[..., :2])
        return np.concatenate([cv, np.zeros(cv.shape[:-1] + (1,))], axis=-1)

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """The 2R chain's ``G`` and ``m3 g r3 cos ph1``, shape ``(..., 3)``."""
        q = as_vector(q, 3, "q")
        p = self.params
        g3 = p.m3 * p.g * p.r3 * np.cos(q[..., 2:3])
        return np.concatenate([self.chain.gravity(q[..., :2]), g3], axis=-1)

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        """Chain potential plus ``m3 g r3 sin ph1`` [J], shape ``(...)``."""
        q = as_vector(q, 3, "q")
        p = self.params
        return self.chain.potential_energy(q[..., :2]) + p.m3 * p.g * p.r3 * np.sin(q[..., 2])

    def friction(self, v: np.ndarray) -> np.ndarray:
        """Joint friction at O1, A and O4, shape ``(..., 3)`` [N m]."""
        p = self.params
        v = as_vector(v, 3, "v")
        return smoothed_friction(v, np.array([p.b1, p.b2, p.b3]), np.array([p.f1, p.f2, p.f3]), p.v_s,
                                 np.array([p.df1, p.df2, p.df3]), p.v_st)  # fmt: skip

    # -- loop closure ----------------------------------------------------------

    def _angles(self, q: np.ndarray):
        q = as_vector(q, 3, "q")
        th1, th12, ph1 = q[..., 0], q[..., 0] + q[..., 1], q[..., 2]
        return (np.cos(th1), np.sin(th1), np.cos(th12), np.sin(th12), np.cos(ph1), np.sin(ph1))

    def constraint_residual(self, q: np.ndarray) -> np.ndarray:
        """``phi(q)`` [m], shape ``(..., 2)``."""
        p = self.params
        return np.stack(closure_residual(*self._angles(q), p.l0, p.l1, p.l2, p.l3), axis=-1)

    def constraint_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``Psi = d phi / d q``, shape ``(..., 2, 3)``."""
        p = self.params
        angles = self._angles(q)
        Psi = np.empty(angles[0].shape + (2, 3))
        for i, row in enumerate(closure_jacobian(*angles, p.l1, p.l2, p.l3)):
            for j, entry in enumerate(row):
                Psi[..., i, j] = entry
        return Psi

    def constraint_bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``dPsi v`` (the velocity-squared part of ``d^2 phi / dt^2``), shape ``(..., 2)``."""
        p = self.params
        v = as_vector(v, 3, "v")
        w1, w12, w3 = v[..., 0] ** 2, (v[..., 0] + v[..., 1]) ** 2, v[..., 2] ** 2
        return np.stack(np.broadcast_arrays(*closure_bias(*self._angles(q), w1, w12, w3, p.l1, p.l2, p.l3)), axis=-1)

    # -- consistent states ------------------------------------------------------

    def motion_from_tracked(self, q_t, v_t, a_t, branch: int = 1):
        """The whole motion from the crank's ``(th1, dth1, ddth1)``, each shape ``(T, 1)``:
        ``q`` by :meth:`assemble` on ``branch``, ``v`` and ``a`` through the constraints."""
        q = np.stack([self.assemble(th[0], branch) for th in q_t])
        v = self.complete_velocity(q, v_t)
        return q, v, self.complete_acceleration(q, v, a_t)

    def assemble(self, th1: np.ndarray, branch: int = 1) -> np.ndarray:
        """Coordinates ``q = (th1, ph2, ph1)`` closing the loop at crank angle ``th1``.

        Joint B is the intersection of the circle of radius ``l2`` about the
        crank tip A and the circle of radius ``l3`` about ``O4``. ``branch=+1``
        takes the intersection to the left of the directed line A -> O4
        (counter-clockwise side; for the default crank-rocker, the usual "open"
        assembly with B above the ground line), ``branch=-1`` the other one.

        Parameters
        ----------
        th1 : float or ndarray, shape (...)
        branch : {+1, -1}

        Returns
        -------
        q : ndarray, shape (..., 3)

        Raises
        ------
        ValueError
            If the loop cannot close at this crank angle, or for a bad branch.
        """
        if branch not in (1, -1):
            raise ValueError(f"branch must be +1 or -1, got {branch!r}")
        p = self.params
        th1 = np.asarray(th1, float)
        A = np.stack([p.l1 * np.cos(th1), p.l1 * np.sin(th1)], axis=-1)
        d_vec = np.array([p.l0, 0.0]) - A
        d = np.linalg.norm(d_vec, axis=-1)
        if np.any(d > p.l2 + p.l3) or np.any(d < abs(p.l2 - p.l3)):
            raise ValueError(f"the linkage ({self.grashof}) cannot assemble at crank angle th1 = {th1.tolist()}")
        e = d_vec / d[..., None]
        e_perp = np.stack([-e[..., 1], e[..., 0]], axis=-1)
        x = (d**2 + p.l2**2 - p.l3**2) / (2 * d)
        h = np.sqrt(np.maximum(p.l2**2 - x**2, 0.0))
        B = A + x[..., None] * e + branch * h[..., None] * e_perp
        th12 = np.arctan2(B[..., 1] - A[..., 1], B[..., 0] - A[..., 0])
        ph1 = np.arctan2(B[..., 1], B[..., 0] - p.l0)
        ph2 = (th12 - th1 + np.pi) % (2 * np.pi) - np.pi
        return np.stack([th1, ph2, ph1], axis=-1)

    def moving_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The crank at 0.3 rad turning at 2 rad/s, the loop closed (:meth:`consistent_state`)."""
        return self.consistent_state(0.3, 2.0)

    def consistent_state(self, th1: float, dth1: float = 0.0, branch: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """A state on the constraints from a crank angle and rate (see :meth:`assemble`).

        Returns
        -------
        q, v : ndarray, shape (..., 3)
        """
        q = self.assemble(th1, branch)
        v = self.complete_velocity(q, np.asarray(dth1, float)[..., None])
        return q, v

    def effective_inertia(self, q: np.ndarray) -> np.ndarray:
        """Reduced inertia of the crank ``J(q) = T^T M T`` [kg m^2], shape ``(...)``.

        ``T = dv/d(dth1)`` spans the motions allowed by the loop (``Psi T = 0``,
        ``T_0 = 1``): the kinetic energy is ``J(q) dth1^2 / 2``.
        """
        q = as_vector(q, 3, "q")
        T = self.complete_velocity(q, np.ones(q.shape[:-1] + (1,)))
        return np.einsum("...i,...ij,...j->...", T, self.mass_matrix(q), T)

    # -- reactions and drawing -----------------------------------------------------

    def joint_positions(self, q: np.ndarray) -> np.ndarray:
        """``O1, A, B (through the chain), O4`` [m], shape ``(..., 4, 2)``."""
        p = self.params
        pts = self.chain.joint_positions(as_vector(q, 3, "q")[..., :2])
        O4 = np.broadcast_to(np.array([p.l0, 0.0]), pts.shape[:-2] + (1, 2))
        return np.concatenate([pts, O4], axis=-2)

    def joint_forces(self, q: np.ndarray, v: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Reaction forces in the four joints [N] from the multipliers and Newton's law per link.

        Rows: force of the ground on the crank at O1, of the crank on the
        coupler at A, of the rocker on the coupler at B (``= lam``), of the
        ground on the rocker at O4. From ``m_i a_Ci = sum of joint forces + m_i g``
        with the centre-of-mass accelerations of the constrained motion.

        Returns
        -------
        ndarray, shape (..., 4, 2)
        """
        p = self.params
        q = as_vector(q, 3, "q")
        v = as_vector(v, 3, "v")
        a, lam, _ = self.solve(q, v, u)
        th1, th12, ph1 = q[..., 0], q[..., 0] + q[..., 1], q[..., 2]
        w1, w12, w3 = v[..., 0], v[..., 0] + v[..., 1], v[..., 2]
        al1, al12, al3 = a[..., 0], a[..., 0] + a[..., 1], a[..., 2]

        def point_acc(radius, angle, w, alpha):
            """Acceleration of a point at ``radius`` along a link at ``angle`` rotating about a fixed-rate origin."""
            e = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
            e_perp = np.stack([-np.sin(angle), np.cos(angle)], axis=-1)
            return radius * (alpha[..., None] * e_perp - (w**2)[..., None] * e)

        gvec = np.array([0.0, -p.g])
        a_c1 = point_acc(p.r1, th1, w1, al1)
        a_c2 = point_acc(p.l1, th1, w1, al1) + point_acc(p.r2, th12, w12, al12)
        a_c3 = point_acc(p.r3, ph1, w3, al3)
        F_B = lam
        F_A = p.m2 * (a_c2 - gvec) - F_B
        F_O1 = p.m1 * (a_c1 - gvec) + F_A
        F_O4 = p.m3 * (a_c3 - gvec) + F_B
        return np.stack([F_O1, F_A, F_B, F_O4], axis=-2)
