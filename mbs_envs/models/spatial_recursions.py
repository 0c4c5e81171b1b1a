"""The spatial-vector recursions of one member of a :class:`~mbs_envs.models.spatial_chain.SpatialChain`
(numba kernels; spatial vectors as length-6 arrays, angular part first): the frames, the recursive Newton-Euler
inverse dynamics (RNEA), the composite-rigid-body mass matrix (CRBA), the articulated-body forward dynamics (ABA)
and the energy, written into work arrays allocated once per call (:func:`work_arrays`). The formulas are those of
:mod:`mbs_envs.models.spatial_chain` (its docstring).
"""

from __future__ import annotations


import numpy as np

from ..dynamics.jit import njit
from ..dynamics.trig import sincos_columns


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
