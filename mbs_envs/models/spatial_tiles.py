"""The articulated-body algorithm over whole tiles of a batch (:func:`aba_tiles`): ``TILE`` members at a time with
the member index innermost (SIMD across members), every member's arithmetic that of
:func:`~mbs_envs.models.spatial_recursions.aba_into`, expression by expression (the same bits; tested).
"""

from __future__ import annotations


import numpy as np

from ..dynamics.jit import njit
from ..dynamics.trig import sincos_columns
from .spatial_recursions import (
    _rot_entries,
    _cross_motion_entries,
    _diagonal,
    _body_force_entries,
)


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
