"""The N-link serial chain in space: revolute joints about arbitrary axes, spatial-vector O(N) algorithms.

The lecture motivates O(N) algorithms with proteins, 100 to 500 rigid bodies in a chain in three
dimensions. Link ``i`` (``i = 0 .. N-1``) hangs from joint ``i``, a revolute about the unit axis
``a_i`` (in the parent link's frame, which is also the child's: a rotation keeps its own axis); the
joint sits at ``offset_i`` in the parent's frame (``offset_0`` in the world). Link ``i``: mass
``m_i``, centre of mass ``com_i`` and inertia tensor ``inertia_i`` about it (3 x 3, link frame),
joint damping ``b_i`` and the drive's armature (reflected rotor inertia, added to ``M``'s diagonal).
Gravity is the vector ``g_vec`` (default ``(0, 0, -9.81)``).

Kinematics: ``R_i = R_{i-1} Rot(a_i, q_i)``, ``p_i = p_{i-1} + R_{i-1} offset_i`` (``R_{-1} = 1``,
``p_{-1} = 0``), the world axis ``z_i = R_i a_i``, the centre of mass ``c_i = p_i + R_i com_i``.

**Spatial vectors** (Featherstone, *Rigid Body Dynamics Algorithms*, 2008, Plücker coordinates)
expressed in the **fixed world frame** (the book's "absolute" formulation, ch. 2 and §§ 5.3, 6.2,
7.3): motion ``V = (w, v_O)``, angular part first, ``v_O`` the velocity of the body point at the
world origin; force ``F = (n_O, f)``, the moment about the origin first. A revolute joint's motion
subspace is ``S_i = (z_i, p_i x z_i)``; a body's spatial inertia about the origin
``I_i = [[Ic + m [c]x [c]x^T, m [c]x], [m [c]x^T, m 1]]`` (``Ic = R_i inertia_i R_i^T``). In this
frame ``dS_i/dt = V_i x S_i`` and no coordinate transforms are needed between links:

- **RNEA** (inverse dynamics): ``V_i = V_{i-1} + S_i v_i``, ``A_i = A_{i-1} + S_i a_i + V_i x S_i v_i``
  with ``A_{-1} = (0, -g_vec)``; ``F_i = I_i A_i + V_i x* I_i V_i``, evaluated in 3 x 3 form (the centre's
  velocity ``v_c = v_O + w x c`` and acceleration ``a_c = a_O + al x c + w x v_c``, ``f = m a_c``,
  ``n_O = c x f + Ic al + w x Ic w``: a third of the 6 x 6 products' work); backwards
  ``tau_i = S_i^T F_i``, ``F_{i-1} += F_i``; plus ``armature_i a_i``. O(N).
- **CRBA** (mass matrix): composite inertias ``Ic_i = I_i + Ic_{i+1}``, ``M_ij = S_i^T Ic_j S_j`` for
  ``i <= j``; plus ``diag(armature)``. O(N^2) (the matrix).
- **ABA** (forward dynamics): the bias accelerations ``A0_i = A0_{i-1} + c_i`` outwards (``c_i = V_i x S_i v_i``,
  ``A0_{-1} = (0, -g_vec)``: each body's acceleration at ``a = 0``), the bias forces ``pA_i = I_i A0_i + V_i x*
  I_i V_i`` and articulated inertias ``IA_i`` inwards; ``U_i = IA_i S_i``, ``D_i = S_i^T U_i + armature_i``,
  ``u_i = tau_i - S_i^T pA_i``, passed to the parent as ``IA - U U^T / D`` and ``pA + U u_i / D``; forwards,
  relative to the bias accelerations, ``a_i = (u_i - U_i^T dA_{i-1}) / D_i``, ``dA_i = dA_{i-1} + S_i a_i``
  (``dA_{-1} = 0``). O(N).

Everything runs in numba kernels, one member at a time over a flattened batch, in work arrays
allocated once per call (:func:`work_arrays`); ``Ic_i = R_i inertia_i R_i^T`` as two 3 x 3 products. With all axes
parallel to z, offsets and centres along the links' x axes and gravity along -y it is the planar
:class:`~mbs_envs.models.serial_chain.SerialChain` (the fast special case; tested to 1e-12).
``tests/models/test_spatial_chain.py`` checks it against Pinocchio (``pin``) and a SymPy Lagrangian.
"""

from __future__ import annotations

import dataclasses
import sys
from typing import Any

import numpy as np

from .. import validation as check
from ..dynamics import compiled as _compiled
from ..dynamics.compiled import batch_theta, rk_run
from ..dynamics.jit import njit
from ..dynamics.trig import sincos_columns
from .base import Params, as_vector, param
from .serial_chain import RecursiveChain, link_count

#: the longest spatial chain the model takes (the lecture's proteins: up to 500 bodies)
MAX_SPATIAL_LINKS = 10_000


# ---------------------------------------------------------------------------------------------
# kernels (one member; spatial vectors as length-6 arrays, angular part first)


@njit(inline="always")
def _rot_entries(x, y, z, s, c):  # pragma: no cover - compiled
    """Rodrigues: the rotation about the unit axis ``(x, y, z)`` by the angle whose sine and cosine are ``s, c``,
    its nine entries by rows."""
    C = 1.0 - c
    return (c + x * x * C, x * y * C - z * s, x * z * C + y * s,
            y * x * C + z * s, c + y * y * C, y * z * C - x * s,
            z * x * C - y * s, z * y * C + x * s, c + z * z * C)  # fmt: skip


@njit(inline="always")
def _cross_motion_entries(w0, w1, w2, v0, v1, v2, a0, a1, a2, b0, b1, b2):  # pragma: no cover - compiled
    """``V x M`` of two motion vectors ``V = (w, v)``, ``M = (a, b)``: ``(w x a, w x b + v x a)``, six entries."""
    return (w1 * a2 - w2 * a1, w2 * a0 - w0 * a2, w0 * a1 - w1 * a0,
            w1 * b2 - w2 * b1 + v1 * a2 - v2 * a1, w2 * b0 - w0 * b2 + v2 * a0 - v0 * a2, w0 * b1 - w1 * b0 + v0 * a1 - v1 * a0)  # fmt: skip


@njit(inline="always")
def _dot6(a, i, b, j):  # pragma: no cover - compiled
    """``a[i] . b[j]`` of two rows of length 6, summed left to right (no views: numba counts a view's references)."""
    return (
        a[i, 0] * b[j, 0]
        + a[i, 1] * b[j, 1]
        + a[i, 2] * b[j, 2]
        + a[i, 3] * b[j, 3]
        + a[i, 4] * b[j, 4]
        + a[i, 5] * b[j, 5]
    )


@njit
def work_arrays(N):  # pragma: no cover - compiled
    """The work arrays of one member, views of one allocation made once per kernel call: frames ``R (N, 3, 3)``,
    joint positions ``p``, axes ``z``, centres ``c`` ``(N, 3)``, world inertias about the centres ``Ic (N, 3, 3)``,
    motion subspaces ``S (N, 6)``; the ABA's articulated inertia and the child's ``(2, 6, 6)``, bias forces
    ``pA``, ``U (N, 6)``, ``D``, ``u (N,)``; RNEA's forces ``F (N, 6)``; the joint angles' sines and cosines
    ``(N,)``; the ABA's child bias force (and CRBA's ``Ic S``) ``(2, 6)``; the rotation and its
    product ``(2, 3, 3)`` of :func:`frames_into`; the recursions' spatial vectors ``(4, 6)``."""
    return _work_views(np.empty(work_size(N)), N)


@njit(inline="always")
def work_size(N):  # pragma: no cover - compiled
    """The doubles :func:`work_arrays` takes for ``N`` links."""
    return 18 * N + 9 * N + 24 * N + 4 * N + 72 + 12 + 18 + 24


@njit(inline="always")
def _work_views(buf, N):  # pragma: no cover - compiled
    """:func:`work_arrays`' views of ``buf`` (at least :func:`work_size` doubles, C-contiguous)."""
    R = buf[: 18 * N].reshape((2, N, 3, 3))
    o = 18 * N
    P = buf[o : o + 9 * N].reshape((3, N, 3))
    o += 9 * N
    F = buf[o : o + 24 * N].reshape((4, N, 6))
    o += 24 * N
    s = buf[o : o + 4 * N].reshape((4, N))
    o += 4 * N
    IA = buf[o : o + 72].reshape((2, 6, 6))
    o += 72
    pa = buf[o : o + 12].reshape((2, 6))
    o += 12
    JT = buf[o : o + 18].reshape((2, 3, 3))
    o += 18
    VA = buf[o : o + 24].reshape((4, 6))
    return (R[0], P[0], P[1], P[2], R[1], F[0],
            IA, F[1], F[2], s[0], s[1],
            F[3], s[2], s[3], pa, JT, VA)  # fmt: skip


@njit(inline="always")
def _diagonal(inertia, i):  # pragma: no cover - compiled
    """Whether link ``i``'s inertia tensor is diagonal (it is symmetric by validation): ``inertia R^T`` is then a
    scaling (the terms the full product would add are zeros)."""
    return inertia[i, 0, 1] == 0.0 and inertia[i, 0, 2] == 0.0 and inertia[i, 1, 2] == 0.0


@njit(_nrt=False)
def frames_into(q, axis, offset, com, inertia, w):  # pragma: no cover - compiled
    """Forward kinematics into the work arrays ``w`` (:func:`work_arrays`): ``R_i = R_{i-1} Rot(a_i, q_i)``,
    ``p_i = p_{i-1} + R_{i-1} offset_i``, ``z_i = R_{i-1} a_i`` (= ``R_i a_i``: a rotation keeps its axis),
    ``c_i = p_i + R_i com_i``, ``S_i = (z_i, p_i x z_i)``, ``Ic_i = R_i inertia_i R_i^T`` (two 3 x 3 products, the
    second on the upper triangle; the first a scaling where ``inertia_i`` is diagonal, as the default rods');
    the sines and cosines of ``q`` by :func:`mbs_envs.dynamics.trig.sincos_columns` (1 ulp of libm's)."""
    R, p, z, c, Ic, S, sn, cs = w[0], w[1], w[2], w[3], w[4], w[5], w[12], w[13]
    N = q.shape[0]
    J, T = w[15][0], w[15][1]
    sincos_columns(q, sn, cs)  # one SIMD pass (libm for arguments out of its range)
    for i in range(N):
        J[0, 0], J[0, 1], J[0, 2], J[1, 0], J[1, 1], J[1, 2], J[2, 0], J[2, 1], J[2, 2] = _rot_entries(
            axis[i, 0], axis[i, 1], axis[i, 2], sn[i], cs[i]
        )
        for r in range(3):
            if i == 0:
                p[i, r] = offset[i, r]
                z[i, r] = axis[i, r]
                for k in range(3):
                    R[i, r, k] = J[r, k]
            else:
                a0, a1, a2 = R[i - 1, r, 0], R[i - 1, r, 1], R[i - 1, r, 2]
                p[i, r] = p[i - 1, r] + a0 * offset[i, 0] + a1 * offset[i, 1] + a2 * offset[i, 2]
                z[i, r] = a0 * axis[i, 0] + a1 * axis[i, 1] + a2 * axis[i, 2]
                for k in range(3):
                    R[i, r, k] = a0 * J[0, k] + a1 * J[1, k] + a2 * J[2, k]
        for r in range(3):
            c[i, r] = p[i, r] + R[i, r, 0] * com[i, 0] + R[i, r, 1] * com[i, 1] + R[i, r, 2] * com[i, 2]
        S[i, 0], S[i, 1], S[i, 2] = z[i, 0], z[i, 1], z[i, 2]
        S[i, 3] = p[i, 1] * z[i, 2] - p[i, 2] * z[i, 1]
        S[i, 4] = p[i, 2] * z[i, 0] - p[i, 0] * z[i, 2]
        S[i, 5] = p[i, 0] * z[i, 1] - p[i, 1] * z[i, 0]
        if _diagonal(inertia, i):  # T = inertia R^T
            for r in range(3):
                for k in range(3):
                    T[r, k] = inertia[i, r, r] * R[i, k, r]
        else:
            for r in range(3):
                for k in range(3):
                    T[r, k] = (
                        inertia[i, r, 0] * R[i, k, 0] + inertia[i, r, 1] * R[i, k, 1] + inertia[i, r, 2] * R[i, k, 2]
                    )
        for r in range(3):  # Ic = R T, the upper triangle mirrored
            for k in range(r, 3):
                x = R[i, r, 0] * T[0, k] + R[i, r, 1] * T[1, k] + R[i, r, 2] * T[2, k]
                Ic[i, r, k] = x
                Ic[i, k, r] = x


@njit(inline="always")
def spatial_inertia_into(mi, c, Ic, i, I):  # pragma: no cover - compiled
    """Body ``i``'s spatial inertia about the origin, ``I (6, 6)`` written, from its centre ``c[i]`` and world
    inertia ``Ic[i]``: ``[[Ic + m [c]x [c]x^T, m [c]x], [m [c]x^T, m 1]]`` (``[c]x [c]x^T = |c|^2 1 - c c^T``)."""
    cx, cy, cz = c[i, 0], c[i, 1], c[i, 2]
    cc = cx * cx + cy * cy + cz * cz
    for r in range(3):
        for k in range(3):
            I[r, k] = Ic[i, r, k] + mi * ((cc if r == k else 0.0) - c[i, r] * c[i, k])
            I[3 + r, 3 + k] = mi if r == k else 0.0
    I[0, 3], I[0, 4], I[0, 5] = 0.0, -mi * cz, mi * cy
    I[1, 3], I[1, 4], I[1, 5] = mi * cz, 0.0, -mi * cx
    I[2, 3], I[2, 4], I[2, 5] = -mi * cy, mi * cx, 0.0
    for r in range(3):
        for k in range(3):
            I[3 + k, r] = I[r, 3 + k]


@njit(inline="always")
def _body_force_entries(mi, cx, cy, cz, I00, I01, I02, I10, I11, I12, I20, I21, I22,
                        w0, w1, w2, v0, v1, v2, al0, al1, al2, a0, a1, a2):  # fmt: skip  # pragma: no cover - compiled
    """``F = I A + V x* I V`` of one body, its six entries, from its mass, centre ``(cx, cy, cz)`` and world
    inertia ``Ic`` about it (entries ``I_rk``), in 3 x 3 form: the centre's velocity ``v_c = v_O + w x c`` and
    acceleration ``a_c = a_O + al x c + w x v_c`` (``(al, a_O)`` the spatial acceleration), ``f = m a_c``,
    ``n_O = c x f + Ic al + w x (Ic w)``."""
    vc0 = v0 + w1 * cz - w2 * cy
    vc1 = v1 + w2 * cx - w0 * cz
    vc2 = v2 + w0 * cy - w1 * cx
    f0 = mi * (a0 + al1 * cz - al2 * cy + w1 * vc2 - w2 * vc1)
    f1 = mi * (a1 + al2 * cx - al0 * cz + w2 * vc0 - w0 * vc2)
    f2 = mi * (a2 + al0 * cy - al1 * cx + w0 * vc1 - w1 * vc0)
    h0 = I00 * w0 + I01 * w1 + I02 * w2
    h1 = I10 * w0 + I11 * w1 + I12 * w2
    h2 = I20 * w0 + I21 * w1 + I22 * w2
    return (cy * f2 - cz * f1 + I00 * al0 + I01 * al1 + I02 * al2 + w1 * h2 - w2 * h1,
            cz * f0 - cx * f2 + I10 * al0 + I11 * al1 + I12 * al2 + w2 * h0 - w0 * h2,
            cx * f1 - cy * f0 + I20 * al0 + I21 * al1 + I22 * al2 + w0 * h1 - w1 * h0,
            f0, f1, f2)  # fmt: skip


@njit(inline="always")
def _body_force(mi, c, Ic, i, w0, w1, w2, v0, v1, v2, al0, al1, al2, a0, a1, a2, F):  # pragma: no cover - compiled
    """:func:`_body_force_entries` of body ``i`` written into ``F[i] (6,)``, from its centre ``c[i]`` and ``Ic[i]``."""
    F[i, 0], F[i, 1], F[i, 2], F[i, 3], F[i, 4], F[i, 5] = _body_force_entries(
        mi, c[i, 0], c[i, 1], c[i, 2], Ic[i, 0, 0], Ic[i, 0, 1], Ic[i, 0, 2], Ic[i, 1, 0], Ic[i, 1, 1], Ic[i, 1, 2],
        Ic[i, 2, 0], Ic[i, 2, 1], Ic[i, 2, 2], w0, w1, w2, v0, v1, v2, al0, al1, al2, a0, a1, a2,
    )  # fmt: skip


@njit(_nrt=False)
def rnea_into(q, v, a, axis, offset, com, inertia, m, armature, g_vec, gravity, w, tau):  # pragma: no cover - compiled
    """``tau = M a + C v (+ G)`` by the RNEA (module docstring), written into ``tau (N,)``; ``gravity`` False
    leaves ``G`` out. Each body's force in 3 x 3 form (:func:`_body_force`)."""
    N = q.shape[0]
    frames_into(q, axis, offset, com, inertia, w)
    c, Ic, S, F = w[3], w[4], w[5], w[11]
    VA = w[16]
    VA[:, :] = 0.0
    V, A, Sv, tmp = VA[0], VA[1], VA[2], VA[3]
    if gravity:
        A[3], A[4], A[5] = -g_vec[0], -g_vec[1], -g_vec[2]
    for i in range(N):
        for k in range(6):
            Sv[k] = S[i, k] * v[i]
            V[k] += Sv[k]
        tmp[0], tmp[1], tmp[2], tmp[3], tmp[4], tmp[5] = _cross_motion_entries(
            V[0], V[1], V[2], V[3], V[4], V[5], Sv[0], Sv[1], Sv[2], Sv[3], Sv[4], Sv[5]
        )
        for k in range(6):
            A[k] += S[i, k] * a[i] + tmp[k]
        _body_force(m[i], c, Ic, i, V[0], V[1], V[2], V[3], V[4], V[5], A[0], A[1], A[2], A[3], A[4], A[5], F)
    for i in range(N - 1, -1, -1):
        tau[i] = _dot6(S, i, F, i) + armature[i] * a[i]
        if i > 0:
            for k in range(6):
                F[i - 1, k] += F[i, k]


@njit(_nrt=False)
def crba_into(q, axis, offset, com, inertia, m, armature, w, M):  # pragma: no cover - compiled
    """``M(q)`` by the CRBA (module docstring), written into ``M (N, N)``."""
    N = q.shape[0]
    frames_into(q, axis, offset, com, inertia, w)
    c, Ic, S = w[3], w[4], w[5]
    Icomp, I = w[6][0], w[6][1]  # noqa: E741
    Icomp[:, :] = 0.0
    F = w[14]
    for j in range(N - 1, -1, -1):
        spatial_inertia_into(m[j], c, Ic, j, I)
        for r in range(6):
            for k in range(6):
                Icomp[r, k] += I[r, k]
        for r in range(6):  # F = Icomp S_j
            x = 0.0
            for k in range(6):
                x += Icomp[r, k] * S[j, k]
            F[0, r] = x
        for i in range(j + 1):
            M[i, j] = _dot6(S, i, F, 0)
            M[j, i] = M[i, j]
        M[j, j] += armature[j]


@njit(_nrt=False)
def aba_into(q, v, tau, axis, offset, com, inertia, m, armature, g_vec, w, acc):  # pragma: no cover - compiled
    """Accelerations ``M^-1 (tau - C v - G)`` by the ABA (module docstring), written into ``acc (N,)``.

    The velocity products enter through the **bias accelerations** ``A0_i = A0_{i-1} + c_i`` (``A0_{-1} = (0,
    -g_vec)``: each body's acceleration at ``a = 0``, gravity included): the bias force ``pA_i = I_i A0_i + V_i x*
    I_i V_i`` is the body's force at that acceleration, so the accelerations relative to it, ``dA_i = dA_{i-1} +
    S_i a_i`` (``dA_{-1} = 0``), follow from the articulated inertias alone: ``F_i = IA_i dA_i + pA_i``, passed to
    the parent as ``Ia_i = IA_i - U_i U_i^T / D_i`` and ``pa_i = pA_i + U_i u_i / D_i``; forwards ``a_i = (u_i -
    U_i^T dA_{i-1}) / D_i``. (Featherstone's form with ``c_i`` in the inward pass, ``pa_i = pA_i + Ia_i c_i +
    U_i u_i / D_i``, costs a 6 x 6 product per link more.) ``Ia_i`` on its upper triangle, mirrored."""
    N = q.shape[0]
    frames_into(q, axis, offset, com, inertia, w)
    c, Ic, S, pA, U, D, u = w[3], w[4], w[5], w[7], w[8], w[9], w[10]
    VA = w[16]
    VA[:3, :] = 0.0
    V, Sv, A = VA[0], VA[1], VA[2]
    A[3], A[4], A[5] = -g_vec[0], -g_vec[1], -g_vec[2]
    for i in range(N):
        for k in range(6):
            Sv[k] = S[i, k] * v[i]
            V[k] += Sv[k]
        c0, c1, c2, c3, c4, c5 = _cross_motion_entries(
            V[0], V[1], V[2], V[3], V[4], V[5], Sv[0], Sv[1], Sv[2], Sv[3], Sv[4], Sv[5]
        )
        A[0] += c0
        A[1] += c1
        A[2] += c2
        A[3] += c3
        A[4] += c4
        A[5] += c5
        _body_force(m[i], c, Ic, i, V[0], V[1], V[2], V[3], V[4], V[5], A[0], A[1], A[2], A[3], A[4], A[5], pA)
    IA, Ia = w[6][0], w[6][1]  # the link's articulated inertia, and its child's as passed up
    pa = w[14][0]
    Ia[:] = 0.0
    pa[:] = 0.0
    for i in range(N - 1, -1, -1):
        spatial_inertia_into(m[i], c, Ic, i, IA)
        for r in range(6):
            for k in range(6):
                IA[r, k] += Ia[r, k]
        for r in range(6):
            U[i, r] = _dot6(IA, r, S, i)
        D[i] = _dot6(S, i, U, i) + armature[i]
        for k in range(6):
            pA[i, k] += pa[k]
        u[i] = tau[i] - _dot6(S, i, pA, i)
        if i > 0:
            inv = 1.0 / D[i]
            for r in range(6):
                ur = U[i, r] * inv
                for k in range(r, 6):
                    x = IA[r, k] - ur * U[i, k]
                    Ia[r, k] = x
                    Ia[k, r] = x
            s_ = u[i] * inv
            for k in range(6):
                pa[k] = pA[i, k] + U[i, k] * s_
    A[:] = 0.0
    for i in range(N):
        acc[i] = (u[i] - (U[i, 0] * A[0] + U[i, 1] * A[1] + U[i, 2] * A[2] + U[i, 3] * A[3] + U[i, 4] * A[4]
                          + U[i, 5] * A[5])) / D[i]  # fmt: skip
        for k in range(6):
            A[k] += S[i, k] * acc[i]


@njit(_nrt=False)
def energy_member(q, v, axis, offset, com, inertia, m, armature, g_vec, w):  # pragma: no cover - compiled
    """``(T, V)`` [J]: ``T = sum_i (m_i |v_ci|^2 + w_i . Ic_i w_i + armature_i v_i^2) / 2`` (the spatial
    ``V_i^T I_i V_i / 2`` about the centre), ``V = -sum_i m_i g_vec . c_i``."""
    N = q.shape[0]
    frames_into(q, axis, offset, com, inertia, w)
    c, Ic, S = w[3], w[4], w[5]
    Vel = w[16][0]
    Vel[:] = 0.0
    T = 0.0
    U = 0.0
    for i in range(N):
        for k in range(6):
            Vel[k] += S[i, k] * v[i]
        w0, w1, w2 = Vel[0], Vel[1], Vel[2]
        cx, cy, cz = c[i, 0], c[i, 1], c[i, 2]
        vc0 = Vel[3] + w1 * cz - w2 * cy
        vc1 = Vel[4] + w2 * cx - w0 * cz
        vc2 = Vel[5] + w0 * cy - w1 * cx
        rot = 0.0
        for r in range(3):
            rot += Vel[r] * (Ic[i, r, 0] * w0 + Ic[i, r, 1] * w1 + Ic[i, r, 2] * w2)
        T += 0.5 * (m[i] * (vc0 * vc0 + vc1 * vc1 + vc2 * vc2) + rot) + 0.5 * armature[i] * v[i] * v[i]
        U -= m[i] * (g_vec[0] * cx + g_vec[1] * cy + g_vec[2] * cz)
    return T, U


# The numpy path's row functions read the parameters from the kernels' own column (``theta (P, 1)``, unpacked
# into fresh arrays as the compiled step does), so that the member functions below compile once for both paths.


@njit
def _rows_rnea(q, v, a, theta, gravity):  # pragma: no cover - compiled
    N = q.shape[1]
    axis, offset, com, inertia, m, arm, b_, g = _unpack(theta, N)
    out = np.empty(q.shape)
    w = work_arrays(N)
    tau = np.empty(N)
    for b in range(q.shape[0]):
        rnea_into(q[b], v[b], a[b], axis, offset, com, inertia, m, arm, g, gravity, w, tau)
        out[b] = tau
    return out


@njit
def _rows_crba(q, theta):  # pragma: no cover - compiled
    N = q.shape[1]
    axis, offset, com, inertia, m, arm, b_, g = _unpack(theta, N)
    out = np.empty((q.shape[0], N, N))
    w = work_arrays(N)
    M = np.empty((N, N))
    for b in range(q.shape[0]):
        crba_into(q[b], axis, offset, com, inertia, m, arm, w, M)
        out[b] = M
    return out


@njit
def _rows_aba(q, v, tau, d, theta):  # pragma: no cover - compiled
    """:func:`aba_into` per row, with ``d`` ``(B, N)`` (or one row ``(1, N)`` for all) added to the armature."""
    B, N = q.shape
    axis, offset, com, inertia, m, arm0, b_, g = _unpack(theta, N)
    out = np.empty(q.shape)
    w = work_arrays(N)
    arm, acc = np.empty(N), np.empty(N)
    shared = d.shape[0] == 1
    for b in range(B):
        row = 0 if shared else b
        for i in range(N):
            arm[i] = arm0[i] + d[row, i]
        aba_into(q[b], v[b], tau[b], axis, offset, com, inertia, m, arm, g, w, acc)
        out[b] = acc
    return out


@njit
def _rows_energy(q, v, theta):  # pragma: no cover - compiled
    N = q.shape[1]
    axis, offset, com, inertia, m, arm, b_, g = _unpack(theta, N)
    T, U = np.empty(q.shape[0]), np.empty(q.shape[0])
    w = work_arrays(N)
    for b in range(q.shape[0]):
        T[b], U[b] = energy_member(q[b], v[b], axis, offset, com, inertia, m, arm, g, w)
    return T, U


@njit
def _rows_kinematics(q, theta):  # pragma: no cover - compiled
    B, N = q.shape
    axis, offset, com, inertia, m, arm, b_, g = _unpack(theta, N)
    p, c, z, R = np.empty((B, N, 3)), np.empty((B, N, 3)), np.empty((B, N, 3)), np.empty((B, N, 3, 3))
    w = work_arrays(N)
    for b in range(B):
        frames_into(q[b], axis, offset, com, inertia, w)
        R[b], p[b], z[b], c[b] = w[0], w[1], w[2], w[3]
    return R, p, z, c


# ---------------------------------------------------------------------------------------------
# the compiled path's kernels (see mbs_envs.dynamics.compiled): the batch in columns (N, B), the
# parameters theta (21 N + 3, 1), one column for every member (SpatialChain.kernel_params):
# axis (3 N), offset (3 N), com (3 N), inertia (9 N), row by row, then m, armature, b (N each), g_vec (3)


@njit(inline="always")
def _param_views(buf, N):  # pragma: no cover - compiled
    """The per-link arrays of a parameter column copied into ``buf`` (its first ``21 N + 3`` doubles), as views:
    ``axis, offset, com (N, 3), inertia (N, 3, 3), m, armature, b (N,), g_vec (3,)`` (the column's order)."""
    return (buf[: 3 * N].reshape((N, 3)), buf[3 * N : 6 * N].reshape((N, 3)), buf[6 * N : 9 * N].reshape((N, 3)),
            buf[9 * N : 18 * N].reshape((N, 3, 3)), buf[18 * N : 19 * N], buf[19 * N : 20 * N], buf[20 * N : 21 * N],
            buf[21 * N : 21 * N + 3])  # fmt: skip


@njit(inline="always")
def _copy_column(theta, k, buf):  # pragma: no cover - compiled
    """``buf[:P] = theta[:, k]`` (``P`` the column's length)."""
    for j in range(theta.shape[0]):
        buf[j] = theta[j, k]


@njit
def _unpack(theta, N):  # pragma: no cover - compiled
    """The per-link arrays of the first parameter column of ``theta`` (``(21 N + 3, C)``), copied out (one allocation)."""
    buf = np.empty(21 * N + 3)
    _copy_column(theta, 0, buf)
    return _param_views(buf, N)


@njit(inline="always")
def _member_size(N, rows):  # pragma: no cover - compiled
    """The doubles of :func:`_member_views`' buffer."""
    return 21 * N + 3 + rows * N + work_size(N)


@njit(inline="always")
def _member_views(theta, N, rows, buf):  # pragma: no cover - compiled
    """A kernel's member loop in one buffer (:func:`_member_size` doubles): the parameters of column 0
    (:func:`_param_views`, refilled in place by :func:`_copy_column` for per-member columns), ``rows`` scratch
    rows ``(rows, N)`` and the work arrays (:func:`work_arrays`)."""
    P = 21 * N + 3
    _copy_column(theta, 0, buf)
    return _param_views(buf, N), buf[P : P + rows * N].reshape((rows, N)), _work_views(buf[P + rows * N :], N)


@njit
def acceleration_kernel(q, v, tau, theta, a):  # pragma: no cover - compiled
    """Accelerations of a batch in columns by :func:`aba_into`, the joint damping ``b v`` included.

    Parameters
    ----------
    q, v, tau : ndarray, shape (N, B)
        Joint angles [rad], rates [rad/s] and torques [N m], one column per member.
    theta : ndarray, shape (21 N + 3, B) or (21 N + 3, 1)
        :meth:`SpatialChain.kernel_params` in columns (one for every member when shared).
    a : ndarray, shape (N, B)
        Written: ``a = ABA(q, v, tau - b v)`` [rad/s^2].
    """
    _acceleration_members(q, v, tau, theta, np.empty(_member_size(q.shape[0], 4)), a)


@njit(_nrt=False)
def _acceleration_members(q, v, tau, theta, buf, a):  # pragma: no cover - compiled
    """:func:`acceleration_kernel`'s member loop in the buffer ``buf`` (:func:`_member_views`). Compiled without
    numba's reference counting (``_nrt=False``), as are :func:`aba_into` and the other member functions: they
    allocate nothing, and the counts of their array views and arguments (atomic operations) were half of a
    10-link chain's single-member time (docs/performance.md)."""
    N, B = q.shape
    C = theta.shape[1]
    (axis, offset, com, inertia, m, arm, b, g), x, w = _member_views(theta, N, 4, buf)
    qk, vk, net, acc = x[0], x[1], x[2], x[3]
    for k in range(B):
        if C > 1 and k > 0:
            _copy_column(theta, k, buf)
        for i in range(N):
            qk[i] = q[i, k]
            vk[i] = v[i, k]
            net[i] = tau[i, k] - b[i] * v[i, k]
        aba_into(qk, vk, net, axis, offset, com, inertia, m, arm, g, w, acc)
        for i in range(N):
            a[i, k] = acc[i]


#: members per tile of :func:`aba_tiles` (the tile's work arrays, about 32 N TILE doubles: 0.8 MB at N = 100)
TILE = 32


@njit
def aba_tiles(q, v, tau, axis, offset, com, inertia, m, armature, b, g_vec, a):  # pragma: no cover - compiled
    """:func:`aba_into` of the whole tiles of a batch in columns with shared parameters, ``TILE`` members at a time
    with the member index innermost (SIMD across members): every member's arithmetic is :func:`aba_into`'s,
    expression by expression (the same bits; tested; the tile leaves out its additions of exact zeros), on the net
    torque ``tau - b v``. A tile keeps one link's frame at a time (the outward pass computes each link's frame, then
    its velocities, bias accelerations and bias force) and the articulated inertia by its upper triangle, updated in
    place from child to parent: 32 doubles of arrays per link and member instead of about 53. The members beyond the
    last whole tile are left to the caller (:func:`tiled_acceleration_kernel`): every member loop runs exactly
    ``TILE`` times, a constant LLVM unrolls and vectorizes without remainders (about a fifth faster than loops
    over a tile's run-time length).

    Parameters
    ----------
    q, v, tau : ndarray, shape (N, B)
    axis, offset, com : ndarray, shape (N, 3)
    inertia : ndarray, shape (N, 3, 3)
    m, armature, b : ndarray, shape (N,)
    g_vec : ndarray, shape (3,)
    a : ndarray, shape (N, B)
        Written.
    """
    N, B = q.shape
    W = TILE
    sn, cs, net = np.empty((N, W)), np.empty((N, W)), np.empty((N, W))
    R, p, z, T = np.empty((3, 3, W)), np.empty((3, W)), np.empty((3, W)), np.empty((3, 3, W))  # link i's frame
    c, Ic = np.empty((N, 3, W)), np.empty((N, 6, W))  # Ic by its upper triangle, row by row
    S, pA, U = np.empty((N, 6, W)), np.empty((N, 6, W)), np.empty((N, 6, W))
    D, u = np.empty((N, W)), np.empty((N, W))
    V, A, pa = np.empty((6, W)), np.empty((6, W)), np.empty((6, W))
    Ia = np.empty((21, W))  # the articulated inertia by its upper triangle (_S6)
    for b0 in range(0, B - B % W, W):
        for i in range(N):
            sincos_columns(q[i, b0 : b0 + W], sn[i], cs[i])
            for l in range(W):
                net[i, l] = tau[i, b0 + l] - b[i] * v[i, b0 + l]
        for l in range(W):
            for k in range(6):
                V[k, l] = 0.0
            A[0, l], A[1, l], A[2, l] = 0.0, 0.0, 0.0
            A[3, l], A[4, l], A[5, l] = -g_vec[0], -g_vec[1], -g_vec[2]
        # outwards, one link at a time: frames_into's frame, then aba_into's velocities, bias accelerations and forces
        for i in range(N):
            x, y, zz = axis[i, 0], axis[i, 1], axis[i, 2]
            o0, o1, o2 = offset[i, 0], offset[i, 1], offset[i, 2]
            if i == 0:
                for l in range(W):
                    J00, J01, J02, J10, J11, J12, J20, J21, J22 = _rot_entries(x, y, zz, sn[i, l], cs[i, l])
                    p[0, l], p[1, l], p[2, l] = o0, o1, o2
                    z[0, l], z[1, l], z[2, l] = x, y, zz
                    R[0, 0, l], R[0, 1, l], R[0, 2, l] = J00, J01, J02
                    R[1, 0, l], R[1, 1, l], R[1, 2, l] = J10, J11, J12
                    R[2, 0, l], R[2, 1, l], R[2, 2, l] = J20, J21, J22
            else:
                for l in range(W):
                    J00, J01, J02, J10, J11, J12, J20, J21, J22 = _rot_entries(x, y, zz, sn[i, l], cs[i, l])
                    for r in range(3):  # row r of R_i from row r of R_{i-1}, in place
                        a0, a1, a2 = R[r, 0, l], R[r, 1, l], R[r, 2, l]
                        p[r, l] = p[r, l] + a0 * o0 + a1 * o1 + a2 * o2
                        z[r, l] = a0 * x + a1 * y + a2 * zz
                        R[r, 0, l] = a0 * J00 + a1 * J10 + a2 * J20
                        R[r, 1, l] = a0 * J01 + a1 * J11 + a2 * J21
                        R[r, 2, l] = a0 * J02 + a1 * J12 + a2 * J22
            if _diagonal(inertia, i):
                for l in range(W):
                    for r in range(3):
                        for k in range(3):
                            T[r, k, l] = inertia[i, r, r] * R[k, r, l]
            else:
                for l in range(W):
                    for r in range(3):
                        for k in range(3):
                            T[r, k, l] = (
                                inertia[i, r, 0] * R[k, 0, l]
                                + inertia[i, r, 1] * R[k, 1, l]
                                + inertia[i, r, 2] * R[k, 2, l]
                            )
            mi = m[i]
            for l in range(W):
                for r in range(3):
                    c[i, r, l] = p[r, l] + R[r, 0, l] * com[i, 0] + R[r, 1, l] * com[i, 1] + R[r, 2, l] * com[i, 2]
                S[i, 0, l], S[i, 1, l], S[i, 2, l] = z[0, l], z[1, l], z[2, l]
                S[i, 3, l] = p[1, l] * z[2, l] - p[2, l] * z[1, l]
                S[i, 4, l] = p[2, l] * z[0, l] - p[0, l] * z[2, l]
                S[i, 5, l] = p[0, l] * z[1, l] - p[1, l] * z[0, l]
                for r in range(3):
                    for k in range(r, 3):
                        Ic[i, _SYM[r][k], l] = (
                            R[r, 0, l] * T[0, k, l] + R[r, 1, l] * T[1, k, l] + R[r, 2, l] * T[2, k, l]
                        )
                vi = v[i, b0 + l]
                Sv0, Sv1, Sv2 = S[i, 0, l] * vi, S[i, 1, l] * vi, S[i, 2, l] * vi
                Sv3, Sv4, Sv5 = S[i, 3, l] * vi, S[i, 4, l] * vi, S[i, 5, l] * vi
                w0, w1, w2 = V[0, l] + Sv0, V[1, l] + Sv1, V[2, l] + Sv2
                v0, v1, v2 = V[3, l] + Sv3, V[4, l] + Sv4, V[5, l] + Sv5
                V[0, l], V[1, l], V[2, l], V[3, l], V[4, l], V[5, l] = w0, w1, w2, v0, v1, v2
                c0, c1, c2, c3, c4, c5 = _cross_motion_entries(w0, w1, w2, v0, v1, v2, Sv0, Sv1, Sv2, Sv3, Sv4, Sv5)
                al0, al1, al2 = A[0, l] + c0, A[1, l] + c1, A[2, l] + c2
                ac0, ac1, ac2 = A[3, l] + c3, A[4, l] + c4, A[5, l] + c5
                A[0, l], A[1, l], A[2, l], A[3, l], A[4, l], A[5, l] = al0, al1, al2, ac0, ac1, ac2
                I00, I01, I02, I11, I12, I22 = (
                    Ic[i, 0, l],
                    Ic[i, 1, l],
                    Ic[i, 2, l],
                    Ic[i, 3, l],
                    Ic[i, 4, l],
                    Ic[i, 5, l],
                )
                pA[i, 0, l], pA[i, 1, l], pA[i, 2, l], pA[i, 3, l], pA[i, 4, l], pA[i, 5, l] = _body_force_entries(
                    mi, c[i, 0, l], c[i, 1, l], c[i, 2, l], I00, I01, I02, I01, I11, I12, I02, I12, I22,
                    w0, w1, w2, v0, v1, v2, al0, al1, al2, ac0, ac1, ac2,
                )  # fmt: skip
        # articulated inertias and bias forces inwards: IA_i = I_i + Ia_{i+1} in place, by its upper triangle (Ia, 21
        # entries, _S6's order); the sum and U written out entry by entry, the downdate row by row through an inlined
        # function (the two loops of a triangle written in place were not unrolled, and lost the SIMD: about 3x slower)
        Ia[:, :] = 0.0
        pa[:, :] = 0.0
        for i in range(N - 1, -1, -1):
            mi = m[i]
            for l in range(W):  # spatial_inertia_into, then + the child's
                cx, cy, cz = c[i, 0, l], c[i, 1, l], c[i, 2, l]
                cc = cx * cx + cy * cy + cz * cz
                Ia[0, l] = (Ic[i, 0, l] + mi * (cc - cx * cx)) + Ia[0, l]
                Ia[1, l] = (Ic[i, 1, l] + mi * (0.0 - cx * cy)) + Ia[1, l]
                Ia[2, l] = (Ic[i, 2, l] + mi * (0.0 - cx * cz)) + Ia[2, l]
                Ia[6, l] = (Ic[i, 3, l] + mi * (cc - cy * cy)) + Ia[6, l]
                Ia[7, l] = (Ic[i, 4, l] + mi * (0.0 - cy * cz)) + Ia[7, l]
                Ia[11, l] = (Ic[i, 5, l] + mi * (cc - cz * cz)) + Ia[11, l]
                Ia[15, l] = mi + Ia[15, l]  # the lower right block m 1 (its zeros add nothing)
                Ia[18, l] = mi + Ia[18, l]
                Ia[20, l] = mi + Ia[20, l]
                Ia[4, l] = -mi * cz + Ia[4, l]  # the block m [c]x (its zeros add nothing)
                Ia[5, l] = mi * cy + Ia[5, l]
                Ia[8, l] = mi * cz + Ia[8, l]
                Ia[10, l] = -mi * cx + Ia[10, l]
                Ia[12, l] = -mi * cy + Ia[12, l]
                Ia[13, l] = mi * cx + Ia[13, l]
                S0, S1, S2, S3, S4, S5 = S[i, 0, l], S[i, 1, l], S[i, 2, l], S[i, 3, l], S[i, 4, l], S[i, 5, l]
                U[i, 0, l] = (
                    Ia[0, l] * S0 + Ia[1, l] * S1 + Ia[2, l] * S2 + Ia[3, l] * S3 + Ia[4, l] * S4 + Ia[5, l] * S5
                )
                U[i, 1, l] = (
                    Ia[1, l] * S0 + Ia[6, l] * S1 + Ia[7, l] * S2 + Ia[8, l] * S3 + Ia[9, l] * S4 + Ia[10, l] * S5
                )
                U[i, 2, l] = (
                    Ia[2, l] * S0 + Ia[7, l] * S1 + Ia[11, l] * S2 + Ia[12, l] * S3 + Ia[13, l] * S4 + Ia[14, l] * S5
                )
                U[i, 3, l] = (
                    Ia[3, l] * S0 + Ia[8, l] * S1 + Ia[12, l] * S2 + Ia[15, l] * S3 + Ia[16, l] * S4 + Ia[17, l] * S5
                )
                U[i, 4, l] = (
                    Ia[4, l] * S0 + Ia[9, l] * S1 + Ia[13, l] * S2 + Ia[16, l] * S3 + Ia[18, l] * S4 + Ia[19, l] * S5
                )
                U[i, 5, l] = (
                    Ia[5, l] * S0 + Ia[10, l] * S1 + Ia[14, l] * S2 + Ia[17, l] * S3 + Ia[19, l] * S4 + Ia[20, l] * S5
                )
                D[i, l] = (
                    S0 * U[i, 0, l]
                    + S1 * U[i, 1, l]
                    + S2 * U[i, 2, l]
                    + S3 * U[i, 3, l]
                    + S4 * U[i, 4, l]
                    + S5 * U[i, 5, l]
                ) + armature[i]
                for k in range(6):
                    pA[i, k, l] += pa[k, l]
                u[i, l] = net[i, l] - (S0 * pA[i, 0, l] + S1 * pA[i, 1, l] + S2 * pA[i, 2, l] + S3 * pA[i, 3, l] + S4 * pA[i, 4, l]
                                       + S5 * pA[i, 5, l])  # fmt: skip
            if i > 0:  # Ia_i = IA_i - U_i U_i^T / D_i, in place
                for l in range(W):
                    inv = 1.0 / D[i, l]
                    for r in range(6):  # row r of the triangle starts at entry _S6[r][r]
                        _downdate_row(Ia, U, i, l, inv, r, _S6[r][r])
                    s_ = u[i, l] * inv
                    for k in range(6):
                        pa[k, l] = pA[i, k, l] + U[i, k, l] * s_
        # accelerations outwards, relative to the bias accelerations
        for l in range(W):
            for k in range(6):
                A[k, l] = 0.0
        for i in range(N):
            for l in range(W):
                acc = (u[i, l] - (U[i, 0, l] * A[0, l] + U[i, 1, l] * A[1, l] + U[i, 2, l] * A[2, l] + U[i, 3, l] * A[3, l]
                                  + U[i, 4, l] * A[4, l] + U[i, 5, l] * A[5, l])) / D[i, l]  # fmt: skip
                a[i, b0 + l] = acc
                for k in range(6):
                    A[k, l] += S[i, k, l] * acc


@njit(inline="always")
def _downdate_row(Ia, U, i, l, inv, r, n0):  # pragma: no cover - compiled
    """Row ``r`` of ``Ia - U U^T / D`` in place on member ``l`` of a tile (``Ia`` by its upper triangle, the row's
    first entry ``n0``; ``inv = 1 / D``), each entry as :func:`aba_into` computes it."""
    ur = U[i, r, l] * inv
    for k in range(r, 6):
        Ia[n0 + k - r, l] = Ia[n0 + k - r, l] - ur * U[i, k, l]


#: the upper triangle's index of entry ``(r, k)`` of a symmetric 3 x 3 stored as ``00 01 02 11 12 22``
_SYM = ((0, 1, 2), (1, 3, 4), (2, 4, 5))

#: the same for a symmetric 6 x 6 (21 entries, row by row)
_S6 = tuple(tuple((min(r, k) * (11 - min(r, k))) // 2 + max(r, k) for k in range(6)) for r in range(6))


@njit
def energy_kernel(q, v, theta, E):  # pragma: no cover - compiled
    """``E = T + V`` [J] of a batch in columns (:func:`energy_member`); ``E`` shape ``(B,)``, written."""
    _energy_members(q, v, theta, np.empty(_member_size(q.shape[0], 2)), E)


@njit(_nrt=False)
def _energy_members(q, v, theta, buf, E):  # pragma: no cover - compiled
    """:func:`energy_kernel`'s member loop in the buffer ``buf`` (as :func:`_acceleration_members`)."""
    N, B = q.shape
    C = theta.shape[1]
    (axis, offset, com, inertia, m, arm, b, g), x, w = _member_views(theta, N, 2, buf)
    qk, vk = x[0], x[1]
    for k in range(B):
        if C > 1 and k > 0:
            _copy_column(theta, k, buf)
        for i in range(N):
            qk[i] = q[i, k]
            vk[i] = v[i, k]
        T, U = energy_member(qk, vk, axis, offset, com, inertia, m, arm, g, w)
        E[k] = T + U


_this = sys.modules[__name__]


@njit
def advance_kernel(theta, stepper, q, v, tau):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.compiled.rk_run` with this model's :func:`acceleration_kernel` (cached on disk)."""
    rk_run(_this.acceleration_kernel, _compiled.no_projection, theta, stepper, q, v, tau)


@njit
def tiled_acceleration_kernel(q, v, tau, theta, a):  # pragma: no cover - compiled
    """:func:`acceleration_kernel` for batches: with shared parameters the whole tiles by :func:`aba_tiles` (SIMD
    across members, each member's bits those of :func:`acceleration_kernel`) and the rest member by member; with
    per-member parameters member by member. Its own kernel, so that a
    single env compiles no tile code (the first step's compile time)."""
    N, B = q.shape
    if theta.shape[1] > 1:
        acceleration_kernel(q, v, tau, theta, a)
        return
    axis, offset, com, inertia, m, arm, b, g = _unpack(theta, N)
    aba_tiles(q, v, tau, axis, offset, com, inertia, m, arm, b, g, a)
    rest = B - B % TILE
    if rest < B:  # the members beyond the last whole tile, one by one
        a_rest = np.empty((N, B - rest))
        acceleration_kernel(
            np.ascontiguousarray(q[:, rest:]),
            np.ascontiguousarray(v[:, rest:]),
            np.ascontiguousarray(tau[:, rest:]),
            theta,
            a_rest,
        )
        for i in range(N):
            for k in range(B - rest):
                a[i, rest + k] = a_rest[i, k]


@njit
def tiled_advance_kernel(theta, stepper, q, v, tau):  # pragma: no cover - compiled
    """:func:`advance_kernel` with :func:`tiled_acceleration_kernel` (the vector env's step)."""
    rk_run(_this.tiled_acceleration_kernel, _compiled.no_projection, theta, stepper, q, v, tau)


# ---------------------------------------------------------------------------------------------
# parameters and model


def alternating_axes(n: int) -> np.ndarray:
    """The default joint axes: z, y, z, y, ... (a backbone of alternating bends), shape ``(n, 3)``."""
    a = np.zeros((n, 3))
    a[0::2, 2] = 1.0
    a[1::2, 1] = 1.0
    return a


def rod_inertia(m: np.ndarray, l: np.ndarray, radius: np.ndarray) -> np.ndarray:  # noqa: E741
    """A solid cylinder of mass ``m``, length ``l`` and ``radius`` along its x axis, about its centre:
    ``diag(m rho^2 / 2, m l^2 / 12 + m rho^2 / 4, same)``, shape ``(n, 3, 3)``."""
    out = np.zeros((len(m), 3, 3))
    out[:, 0, 0] = m * radius**2 / 2
    out[:, 1, 1] = out[:, 2, 2] = m * l**2 / 12 + m * radius**2 / 4
    return out


def _per_link(value: Any, n: int, tail: tuple, name: str) -> np.ndarray:
    """``value`` as a float array ``(n,) + tail`` (one entry of shape ``tail`` broadcast to every link)."""
    x = check.reals(value, f"parameter '{name}'")
    if x.shape == tail:
        x = np.broadcast_to(x, (n,) + tail)
    if x.shape != (n,) + tail:
        raise ValueError(f"parameter '{name}' must have shape {(n,) + tail} or {tail}, got {x.shape}")
    if not np.all(np.isfinite(x)) or np.any(np.abs(x) > check.PARAM_MAX):
        raise ValueError(f"parameter '{name}' must be finite and at most {check.PARAM_MAX:g} in magnitude")
    return np.ascontiguousarray(x, dtype=float)


@dataclasses.dataclass(frozen=True)
class SpatialChainParams(Params):
    """Parameters of :class:`SpatialChain`, per link (a single value broadcast to every link).

    Defaults: a 1 kg, 1 m chain of equal solid cylinders (radius 5 % of their length) along each
    link's x axis, joints about z, y, z, y, ... (:func:`alternating_axes`), gravity along -z.
    """

    n_links: int = param(2, "positive", "", "number of links")
    m: Any = param(None, "positive", "kg", "link masses (n,)")
    l: Any = param(None, "positive", "m", "link lengths (n,): joint i+1 at (l_i, 0, 0) in link i's frame")  # noqa: E741
    axis: Any = param(None, "finite", "", "joint axes (n, 3), unit, in the parent's frame")
    offset: Any = param(
        None, "finite", "m", "joint positions (n, 3) in the parent's frame (default (0, l_{i-1}) along x)"
    )
    com: Any = param(None, "finite", "m", "centres of mass (n, 3) in the link frame (default (l_i / 2, 0, 0))")
    inertia: Any = param(None, "finite", "kg m^2", "inertia tensors about the centres of mass (n, 3, 3), link frame")
    g_vec: Any = param((0.0, 0.0, -9.81), "finite", "m/s^2", "gravity (3,)")
    armature: Any = param(0.0, "nonnegative", "kg m^2", "reflected rotor inertia at each joint (n,)")
    b: Any = param(0.0, "nonnegative", "N m s/rad", "viscous joint damping (n,)")

    def __post_init__(self) -> None:
        n = link_count(self.n_links, MAX_SPATIAL_LINKS, "parameter 'n_links'")
        object.__setattr__(self, "n_links", n)
        m = _per_link(1.0 / n if self.m is None else self.m, n, (), "m")
        l = _per_link(1.0 / n if self.l is None else self.l, n, (), "l")  # noqa: E741
        for name, value in (("m", m), ("l", l)):
            if np.any(value <= 0):
                raise ValueError(f"parameter {name!r} must be > 0 for every link, got {value.tolist()}")
        axis = _per_link(alternating_axes(n) if self.axis is None else self.axis, n, (3,), "axis")
        norm = np.linalg.norm(axis, axis=1)
        if np.any(norm < 1e-12):
            raise ValueError(f"parameter 'axis': joint {int(np.argmin(norm))} has a zero axis")
        axis = axis / norm[:, None]
        if self.offset is None:
            offset = np.zeros((n, 3))
            offset[1:, 0] = l[:-1]
        else:
            offset = _per_link(self.offset, n, (3,), "offset")
        com = (
            np.stack([l / 2, np.zeros(n), np.zeros(n)], axis=1)
            if self.com is None
            else _per_link(self.com, n, (3,), "com")
        )
        inertia = rod_inertia(m, l, 0.05 * l) if self.inertia is None else _per_link(self.inertia, n, (3, 3), "inertia")
        if not np.allclose(
            inertia, np.swapaxes(inertia, 1, 2), rtol=0, atol=1e-12 * max(1.0, float(np.abs(inertia).max()))
        ):
            raise ValueError("parameter 'inertia': every tensor must be symmetric")
        inertia = 0.5 * (inertia + np.swapaxes(inertia, 1, 2))
        if np.any(np.linalg.eigvalsh(inertia)[:, 0] < -1e-12 * max(1.0, float(np.abs(inertia).max()))):
            raise ValueError("parameter 'inertia': every tensor must be positive semidefinite")
        g_vec = _per_link(self.g_vec, 1, (3,), "g_vec")[0] if np.shape(self.g_vec) == (3,) else None
        if g_vec is None:
            raise ValueError(f"parameter 'g_vec' must have shape (3,), got {np.shape(self.g_vec)}")
        armature = _per_link(self.armature, n, (), "armature")
        b = _per_link(self.b, n, (), "b")
        if np.any(armature < 0) or np.any(b < 0):
            raise ValueError("parameters 'armature' and 'b' must be >= 0")
        # every link must have inertia about its own joint axis (else M is singular at some state)
        d = com
        about_joint = inertia + m[:, None, None] * (
            np.einsum("i,jk->ijk", np.sum(d * d, axis=1), np.eye(3)) - np.einsum("ij,ik->ijk", d, d)
        )
        own = np.einsum("ij,ijk,ik->i", axis, about_joint, axis) + armature
        if np.any(own <= 0):
            raise ValueError(f"parameters: link {int(np.argmin(own))} has no inertia about its joint axis")
        for name, value in (("m", m), ("l", l), ("axis", axis), ("offset", offset), ("com", com), ("inertia", inertia),
                            ("g_vec", g_vec), ("armature", armature), ("b", b)):  # fmt: skip
            value = np.ascontiguousarray(value)
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def replace(self, **overrides: Any) -> "SpatialChainParams":
        """A validated copy; with a new ``n_links`` the per-link parameters not given go back to their defaults."""
        if "n_links" in overrides:
            per_link = ("m", "l", "axis", "offset", "com", "inertia", "armature", "b")
            overrides = {
                **{k: None for k in per_link if k not in ("armature", "b")},
                "armature": 0.0,
                "b": 0.0,
                **overrides,
            }
        return super().replace(**overrides)


class SpatialChain(RecursiveChain):
    """N rigid links in space, each on a revolute joint about its own axis; every joint driven.

    See the module docstring for the coordinates, conventions and algorithms.
    ``SpatialChain(n_links=N, axis=..., offset=..., com=..., inertia=..., m=..., g_vec=..., armature=..., b=...)``.
    """

    Params = SpatialChainParams

    # -- the batch: leading dimensions flattened to rows for the kernels --------------------

    def _rows(self, *arrays: np.ndarray) -> tuple[tuple, list[np.ndarray]]:
        n = self.n_links
        arrays = [as_vector(x, n, name) for x, name in arrays]
        shape = arrays[0].shape
        if all(
            x.shape == shape and x.flags.c_contiguous and x.dtype == np.float64 for x in arrays
        ):  # the common case: views
            return shape, [x.reshape(-1, n) for x in arrays]
        shape = np.broadcast_shapes(*(x.shape for x in arrays))
        return shape, [np.ascontiguousarray(np.broadcast_to(x, shape).reshape(-1, n), dtype=float) for x in arrays]

    def _theta(self) -> np.ndarray:
        """The kernels' parameter column ``(21 N + 3, 1)`` (read only, cached for the current parameters)."""
        return batch_theta(self, 1)

    def kinematics(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """World rotations ``R (..., N, 3, 3)``, joint positions ``p``, axes ``z`` and centres of mass ``c`` (``(..., N, 3)``)."""
        shape, (qr,) = self._rows((q, "q"))
        R, p, z, c = _rows_kinematics(qr, self._theta())
        lead = shape[:-1]
        return {"R": R.reshape(lead + R.shape[1:]), "p": p.reshape(lead + p.shape[1:]), "z": z.reshape(lead + z.shape[1:]),
                "c": c.reshape(lead + c.shape[1:])}  # fmt: skip

    def joint_positions(self, q: np.ndarray) -> np.ndarray:
        """Joints and the last link's tip (``(l_N, 0, 0)`` in its frame) [m], shape ``(..., N + 1, 3)``."""
        k = self.kinematics(q)
        tip = k["p"][..., -1, :] + np.einsum(
            "...ij,j->...i", k["R"][..., -1, :, :], np.array([self.params.l[-1], 0.0, 0.0])
        )
        return np.concatenate([k["p"], tip[..., None, :]], axis=-2)

    def rnea(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, gravity: bool = True) -> np.ndarray:
        """``M a + C v (+ G)`` by the recursive Newton-Euler algorithm, O(N) per member; shape ``(..., N)``."""
        shape, (qr, vr, ar) = self._rows((q, "q"), (v, "v"), (a, "a"))
        out = _rows_rnea(qr, vr, ar, self._theta(), bool(gravity))
        return out.reshape(shape)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``M(q)`` by the composite-rigid-body algorithm, shape ``(..., N, N)``."""
        shape, (qr,) = self._rows((q, "q"))
        return _rows_crba(qr, self._theta()).reshape(shape + (self.n_links,))

    def friction(self, v: np.ndarray) -> np.ndarray:
        """Viscous joint damping ``b v``."""
        return self.params.b * as_vector(v, self.n_links, "v")

    def aba(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Accelerations for joint torques ``tau`` (damping not included) by the articulated-body algorithm, O(N)."""
        shape, (qr, vr, tr) = self._rows((q, "q"), (v, "v"), (tau, "tau"))
        return _rows_aba(qr, vr, tr, np.zeros((1, self.n_links)), self._theta()).reshape(shape)

    def shifted_forward_dynamics(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, d: np.ndarray) -> np.ndarray:
        """``(M + diag(d))^-1 (tau - C v - G)`` in O(N): the articulated-body algorithm with ``d`` added to
        the armature (which enters ``M`` the same way); see
        :meth:`mbs_envs.models.base.Model.shifted_forward_dynamics`."""
        shape, (qr, vr, tr, dr) = self._rows((q, "q"), (v, "v"), (tau, "tau"), (d, "d"))
        return _rows_aba(qr, vr, tr, dr, self._theta()).reshape(shape)

    def _energies(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        shape, (qr, vr) = self._rows((q, "q"), (v, "v"))
        T, U = _rows_energy(qr, vr, self._theta())
        return T.reshape(shape[:-1]), U.reshape(shape[:-1])

    # -- compiled path (see :mod:`mbs_envs.dynamics.compiled`) -----------------------------

    kernels = (acceleration_kernel, energy_kernel)
    advance_kernel = staticmethod(advance_kernel)
    #: the kernels take one parameter column for every member (:func:`mbs_envs.dynamics.compiled.batch_theta`)
    shared_theta = True

    def kernel_params(self) -> np.ndarray:
        """``(axis, offset, com, inertia)`` row by row, then ``(m, armature, b)`` per link, then ``g_vec``:
        shape ``(21 N + 3,)``."""
        p = self.params
        return np.concatenate(
            [p.axis.ravel(), p.offset.ravel(), p.com.ravel(), p.inertia.ravel(), p.m, p.armature, p.b, p.g_vec]
        )
