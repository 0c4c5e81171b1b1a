"""The planar serial chain's compiled recursions (numba): the articulated-body algorithm of one member and over
tiles of a batch in columns (SIMD across members), the net joint torques, the energy and the link kinematics; the
formulas are those of :mod:`mbs_envs.models.serial_chain` (its docstring).
"""

from __future__ import annotations

import sys

import numpy as np
from numba import uint64

from ..dynamics.jit import njit
from ..dynamics import compiled as _compiled
from ..dynamics.compiled import aligned_empty, rk_run
from ..dynamics.trig import in_range, sincos, sincos_columns


@njit
def _aba_work(N):  # pragma: no cover - compiled
    """Work arrays of :func:`_aba_member` for an N-link chain (allocated once per kernel call)."""
    return (np.empty((N, 3, 3)), np.empty((N, 3)), np.empty((N, 3)), np.empty((N, 3)), np.empty((N, 3)),
            np.empty(N), np.empty(N), np.empty((3, 3)), np.empty(N), np.empty(N), np.empty(N),
            np.empty((N, 2)), np.empty((N, 2)))  # fmt: skip


@njit(inline="always")  # a call per member would pass 13 work arrays (refcounted) each time
def _aba_member(q, w, tau, l, r, m, Ic, arm, g, out, work):  # pragma: no cover - compiled
    """Articulated-body forward dynamics of one planar chain (world frame); writes ``out`` (N,).

    Spatial motion vectors are ``(w, vOx, vOy)`` (angular rate and the velocity
    of the body point at the world origin); the joint axis at ``p_i`` has
    ``s_i = (1, p_iy, -p_ix)``; body inertia about the origin
    ``[[Ic + m |c|^2, -m c_y, m c_x], [-m c_y, m, 0], [m c_x, 0, m]]``; gravity
    as a base acceleration ``(0, 0, g)``; the joint armature ``arm`` adds to
    each joint's articulated inertia ``D_i = s_i^T I^A_i s_i + arm_i``. The
    joint positions ``p_i`` and centres ``c_i`` come from :func:`_member_kinematics`.

    Parameters
    ----------
    q, w, tau : ndarray, shape (N,)
        Joint angles [rad], rates [rad/s] and torques [N m] (any strides).
    l, r, m, Ic, arm : ndarray, shape (N,)
        Link lengths and centre offsets [m], masses [kg], inertias about the
        centres and joint armatures [kg m^2].
    g : float
        [m/s^2] along -y.
    out : ndarray, shape (N,)
        Written: joint accelerations [rad/s^2].
    work : tuple
        :func:`_aba_work` ``(N)``.
    """
    IA, pA, v, c, U, D, u, Ia, th, sn, cs, P, C = work
    N = q.shape[0]
    _member_kinematics(q, l, r, th, sn, cs, P, C)
    vp0 = 0.0
    vp1 = 0.0
    vp2 = 0.0
    for i in range(N):  # pass 1: velocities, bias accelerations, body inertias and bias forces
        s0, s1, s2 = 1.0, P[i, 1], -P[i, 0]
        qd = w[i]
        # c_i = v_parent x (s_i qd)  (the joint axis moves with the parent)
        c[i, 0] = 0.0
        c[i, 1] = (-vp0 * s2 + s0 * vp2) * qd
        c[i, 2] = (vp0 * s1 - s0 * vp1) * qd
        v0 = vp0 + s0 * qd
        v1 = vp1 + s1 * qd
        v2 = vp2 + s2 * qd
        v[i, 0], v[i, 1], v[i, 2] = v0, v1, v2
        mi, x, y = m[i], C[i, 0], C[i, 1]
        I00 = Ic[i] + mi * (x * x + y * y)
        IA[i, 0, 0], IA[i, 0, 1], IA[i, 0, 2] = I00, -mi * y, mi * x
        IA[i, 1, 0], IA[i, 1, 1], IA[i, 1, 2] = -mi * y, mi, 0.0
        IA[i, 2, 0], IA[i, 2, 1], IA[i, 2, 2] = mi * x, 0.0, mi
        # momentum h = I v; its angular part does not enter the planar v x* h
        h1 = -mi * y * v0 + mi * v1
        h2 = mi * x * v0 + mi * v2
        # p = v x* h = (vx hy - vy hx, -w hy, w hx)
        pA[i, 0] = v1 * h2 - v2 * h1
        pA[i, 1] = -v0 * h2
        pA[i, 2] = v0 * h1
        vp0, vp1, vp2 = v0, v1, v2
    for i in range(N - 1, -1, -1):  # pass 2: articulated inertias
        s0, s1, s2 = 1.0, P[i, 1], -P[i, 0]
        for k in range(3):
            U[i, k] = IA[i, k, 0] * s0 + IA[i, k, 1] * s1 + IA[i, k, 2] * s2
        D[i] = 1.0 / (s0 * U[i, 0] + s1 * U[i, 1] + s2 * U[i, 2] + arm[i])  # the one division: 1 / D_i
        u[i] = tau[i] - (s0 * pA[i, 0] + s1 * pA[i, 1] + s2 * pA[i, 2])
        if i > 0:
            Dinv = D[i]  # U_r (U_k / D) (Pinocchio's UDinv)
            for r_ in range(3):
                for k in range(3):  # the upper triangle's product in both halves: Ia stays symmetric to the bit
                    Ia[r_, k] = IA[i, r_, k] - U[i, min(r_, k)] * (U[i, max(r_, k)] * Dinv)
            for r_ in range(3):
                pa = pA[i, r_] + (U[i, r_] * Dinv) * u[i]
                for k in range(1, 3):  # c_i0 = 0: its term is left out
                    pa += Ia[r_, k] * c[i, k]
                for k in range(3):
                    IA[i - 1, r_, k] += Ia[r_, k]
                pA[i - 1, r_] += pa
    a0, a1, a2 = 0.0, 0.0, g  # pass 3: accelerations (gravity as base acceleration)
    for i in range(N):
        s0, s1, s2 = 1.0, P[i, 1], -P[i, 0]
        a0 += c[i, 0]
        a1 += c[i, 1]
        a2 += c[i, 2]
        qdd = (u[i] - (U[i, 0] * a0 + U[i, 1] * a1 + U[i, 2] * a2)) * D[i]
        out[i] = qdd
        a0 += s0 * qdd
        a1 += s1 * qdd
        a2 += s2 * qdd


@njit
def _aba_kernel(q, w, l, r, m, Ic, arm, tau, g):  # pragma: no cover - compiled
    """:func:`_aba_member` for rows ``q, w, m, Ic, arm, tau`` (B, N); ``l, r`` (N,). Returns ddq (B, N)."""
    B, N = q.shape
    out = np.empty((B, N))
    work = _aba_work(N)
    for b in range(B):
        _aba_member(q[b], w[b], tau[b], l, r, m[b], Ic[b], arm[b], g, out[b], work)
    return out


@njit
def _energy_member(q, w, l, r, m, Ic, arm, g, work):  # pragma: no cover - compiled
    """Kinetic and potential energy ``(T, V)`` [J] of one chain.

    ``T = sum_i m_i |v_Ci|^2 / 2 + Ic_i om_i^2 / 2 + arm_i w_i^2 / 2`` with the link
    rates ``om_i = w_1 + ... + w_i`` and centre velocities ``v_Ci = sum_{j<i} l_j om_j n_j
    + r_i om_i n_i`` (``n_j = (-sin th_j, cos th_j)``), from the link velocities, O(N);
    ``V = g sum_i m_i y_Ci``. Arrays as in :func:`_aba_member`.
    """
    IA, pA, v, c, U, D, u, Ia, th, sn, cs, P, C = work
    _member_kinematics(q, l, r, th, sn, cs, P, C)
    T = 0.0
    V = 0.0
    om = 0.0
    jx, jy = 0.0, 0.0  # velocity of joint i
    for i in range(q.shape[0]):
        om += w[i]
        nx, ny = -sn[i] * om, cs[i] * om
        vx, vy = jx + r[i] * nx, jy + r[i] * ny
        T += m[i] * (vx * vx + vy * vy) + Ic[i] * om * om + arm[i] * w[i] * w[i]
        V += m[i] * C[i, 1]
        jx += l[i] * nx
        jy += l[i] * ny
    return 0.5 * T, g * V


@njit
def _energy_rows(q, w, l, r, m, Ic, arm, g):  # pragma: no cover - compiled
    """:func:`_energy_member` for rows ``q, w`` (B, N): returns ``T, V`` (B,)."""
    B, N = q.shape
    T, V = np.empty(B), np.empty(B)
    work = _aba_work(N)
    for b in range(B):
        T[b], V[b] = _energy_member(q[b], w[b], l, r, m, Ic, arm, g, work)
    return T, V


# -- the compiled path's kernels (see mbs_envs.dynamics.compiled): columns, parameters theta (7 N + 2, B)
#    = (l, r, m, I, armature, b, f) per link, then g, v_s (SerialChain.kernel_params), or (7 N + 2, 1):
#    the same parameters for every member (batch_theta gives that for this model: one column instead
#    of B identical ones, 590 kB fewer to read per evaluation at 1024 members)


@njit(inline="always")
def _col(theta, k):  # pragma: no cover - compiled
    """The column of ``theta`` that holds member ``k``'s parameters (0 when one column serves all)."""
    return k if theta.shape[1] > 1 else 0


@njit(inline="always")
def _member_acceleration(q, v, tau, theta, a, k, work, net):  # pragma: no cover - compiled
    """Member ``k`` of :func:`acceleration_kernel` by :func:`_aba_member` (scalar code)."""
    N = q.shape[0]
    th = theta[:, _col(theta, k)]
    for i in range(N):
        net[i] = tau[i, k]
    _aba_member(q[:, k], v[:, k], net, th[0:N], th[N : 2 * N], th[2 * N : 3 * N], th[3 * N : 4 * N],
                th[4 * N : 5 * N], th[7 * N], a[:, k], work)  # fmt: skip


@njit
def _net_torque(v, tau, theta, net):  # pragma: no cover - compiled
    """``net = tau - F(v)`` of a batch in columns (N, B), ``F`` the smoothed friction
    (:func:`mbs_envs.models.base.smoothed_friction`; the ``tanh`` only for a member with some
    ``f != 0``, as the numpy path). Without Coulomb friction in the batch, one SIMD pass."""
    N, B = v.shape
    coulomb = False
    for i in range(N):
        for k in range(theta.shape[1]):
            coulomb |= theta[6 * N + i, k] != 0.0
    if not coulomb:
        vf, tf, pf, nf = (
            np.ascontiguousarray(v).ravel(),
            np.ascontiguousarray(tau).ravel(),
            np.ascontiguousarray(theta).ravel(),
            net.ravel(),
        )
        if theta.shape[1] == 1:
            for i in range(N):
                bi = pf[5 * N + i]
                for k in range(B):
                    nf[uint64(i * B + k)] = tf[uint64(i * B + k)] - bi * vf[uint64(i * B + k)]
            return
        for i in range(N):
            for k in range(B):
                nf[uint64(i * B + k)] = tf[uint64(i * B + k)] - pf[uint64((5 * N + i) * B + k)] * vf[uint64(i * B + k)]
        return
    for k in range(B):
        c = _col(theta, k)
        b, f, v_s = theta[5 * N : 6 * N, c], theta[6 * N : 7 * N, c], theta[7 * N + 1, c]
        member = False
        for i in range(N):
            member |= f[i] != 0.0
        for i in range(N):
            F = b[i] * v[i, k] + f[i] * np.tanh(v[i, k] / v_s) if member else b[i] * v[i, k]
            net[i, k] = tau[i, k] - F


#: members per tile of :func:`_aba_tile` (a compile-time constant: the work slots' offsets are then
#: known to LLVM, which proves them disjoint and vectorizes the member loops)
TILE = 32
#: work slots per link and member in :func:`_aba_tile`
_SLOTS = 18


@njit(inline="always")
def _at(o, slot, b):  # pragma: no cover - compiled
    """Flat index of work ``slot`` of member ``b`` at link offset ``o`` (unsigned: no negative-index
    wraparound in the address, which would hide it from the vectorizer)."""
    return uint64(o + slot * TILE + b)


@njit
def _aba_tile(q, v, tau, theta, N, B, b0, W, S, A, tB, tb0):  # pragma: no cover - compiled
    """:func:`_aba_member` of the members ``b0 .. b0 + TILE - 1`` at once, the member loops innermost
    (SIMD), every operation in the same order as :func:`_aba_member` (bit for bit the same result).

    Parameters
    ----------
    q, v, tau : ndarray, shape (N B,)
        The batch's columns (N, B) flattened; ``tau`` the net torque (:func:`_net_torque`).
    theta : ndarray, shape ((7 N + 2) tB,)
        Parameter columns flattened, rows of ``tB``; the tile's members are columns ``tb0 ..
        tb0 + TILE - 1`` (:func:`_tile_params`).
    N, B, b0 : int
    W : ndarray, shape (N * 18 * TILE,)
        Work: per link and member the axis ``(s1, s2)``, bias acceleration ``(c1, c2)``, articulated
        inertia (6) and bias force (3), ``U`` (3), ``D``, ``u``.
    S : ndarray, shape (10 * TILE,)
        Work: what the passes carry from link to link (absolute angle, joint position, velocity,
        acceleration); slot 9 ends as whether every absolute angle was inside
        :data:`mbs_envs.dynamics.trig.SINCOS_RANGE` (1.0) or not (0.0).
    A : ndarray, shape (N B,)
        Written: the tile's accelerations [rad/s^2] in the flattened columns.
    tB, tb0 : int
    """
    for b in range(TILE):  # pass 1: kinematics, velocities, bias accelerations, inertias, bias forces
        for j in range(6):
            S[j * TILE + b] = 0.0
        S[9 * TILE + b] = 1.0
    for i in range(N):
        o = i * _SLOTS * TILE
        for b in range(TILE):
            m = b0 + b
            th = S[b] + q[uint64(i * B + m)]
            S[b] = th
            sn, cs = sincos(th)
            li, ri = theta[uint64(i * tB + tb0 + b)], theta[uint64((N + i) * tB + tb0 + b)]
            mi, Ici = theta[uint64((2 * N + i) * tB + tb0 + b)], theta[uint64((3 * N + i) * tB + tb0 + b)]
            x, y = S[TILE + b], S[2 * TILE + b]
            cx, cy = x + ri * cs, y + ri * sn
            S[TILE + b] = x + li * cs
            S[2 * TILE + b] = y + li * sn
            s1, s2 = y, -x
            qd = v[uint64(i * B + m)]
            vp0, vp1, vp2 = S[3 * TILE + b], S[4 * TILE + b], S[5 * TILE + b]
            c1 = (-vp0 * s2 + 1.0 * vp2) * qd
            c2 = (vp0 * s1 - 1.0 * vp1) * qd
            v0 = vp0 + 1.0 * qd
            v1 = vp1 + s1 * qd
            v2 = vp2 + s2 * qd
            S[3 * TILE + b], S[4 * TILE + b], S[5 * TILE + b] = v0, v1, v2
            h1 = -mi * cy * v0 + mi * v1
            h2 = mi * cx * v0 + mi * v2
            W[_at(o, 0, b)], W[_at(o, 1, b)], W[_at(o, 2, b)], W[_at(o, 3, b)] = s1, s2, c1, c2
            W[_at(o, 4, b)] = Ici + mi * (cx * cx + cy * cy)
            W[_at(o, 5, b)], W[_at(o, 6, b)] = -mi * cy, mi * cx
            W[_at(o, 7, b)], W[_at(o, 8, b)], W[_at(o, 9, b)] = mi, 0.0, mi
            W[_at(o, 10, b)], W[_at(o, 11, b)], W[_at(o, 12, b)] = v1 * h2 - v2 * h1, -v0 * h2, v0 * h1
            S[9 * TILE + b] = S[9 * TILE + b] if in_range(th) else 0.0
    for i in range(N - 1, -1, -1):  # pass 2: articulated inertias (a loop without branches each)
        o = i * _SLOTS * TILE
        for b in range(TILE):
            s1, s2 = W[_at(o, 0, b)], W[_at(o, 1, b)]
            U0 = W[_at(o, 4, b)] * 1.0 + W[_at(o, 5, b)] * s1 + W[_at(o, 6, b)] * s2
            U1 = W[_at(o, 5, b)] * 1.0 + W[_at(o, 7, b)] * s1 + W[_at(o, 8, b)] * s2
            U2 = W[_at(o, 6, b)] * 1.0 + W[_at(o, 8, b)] * s1 + W[_at(o, 9, b)] * s2
            W[_at(o, 13, b)], W[_at(o, 14, b)], W[_at(o, 15, b)] = U0, U1, U2
            W[_at(o, 16, b)] = 1.0 / (1.0 * U0 + s1 * U1 + s2 * U2 + theta[uint64((4 * N + i) * tB + tb0 + b)])
            W[_at(o, 17, b)] = tau[uint64(i * B + b0 + b)] - (
                1.0 * W[_at(o, 10, b)] + s1 * W[_at(o, 11, b)] + s2 * W[_at(o, 12, b)]
            )
        if i > 0:
            p = o - _SLOTS * TILE
            for b in range(TILE):
                U0, U1, U2, Dinv, u = (
                    W[_at(o, 13, b)],
                    W[_at(o, 14, b)],
                    W[_at(o, 15, b)],
                    W[_at(o, 16, b)],
                    W[_at(o, 17, b)],
                )
                c1, c2 = W[_at(o, 2, b)], W[_at(o, 3, b)]
                V0, V1, V2 = U0 * Dinv, U1 * Dinv, U2 * Dinv
                A00 = W[_at(o, 4, b)] - U0 * V0
                A01 = W[_at(o, 5, b)] - U0 * V1
                A02 = W[_at(o, 6, b)] - U0 * V2
                A11 = W[_at(o, 7, b)] - U1 * V1
                A12 = W[_at(o, 8, b)] - U1 * V2
                A22 = W[_at(o, 9, b)] - U2 * V2
                pa0 = W[_at(o, 10, b)] + V0 * u
                pa0 += A01 * c1
                pa0 += A02 * c2
                pa1 = W[_at(o, 11, b)] + V1 * u
                pa1 += A11 * c1
                pa1 += A12 * c2
                pa2 = W[_at(o, 12, b)] + V2 * u
                pa2 += A12 * c1
                pa2 += A22 * c2
                W[_at(p, 4, b)] += A00
                W[_at(p, 5, b)] += A01
                W[_at(p, 6, b)] += A02
                W[_at(p, 7, b)] += A11
                W[_at(p, 8, b)] += A12
                W[_at(p, 9, b)] += A22
                W[_at(p, 10, b)] += pa0
                W[_at(p, 11, b)] += pa1
                W[_at(p, 12, b)] += pa2
    for b in range(TILE):  # pass 3: accelerations (gravity as base acceleration)
        S[6 * TILE + b], S[7 * TILE + b], S[8 * TILE + b] = 0.0, 0.0, theta[uint64(7 * N * tB + tb0 + b)]
    for i in range(N):
        o = i * _SLOTS * TILE
        for b in range(TILE):
            s1, s2 = W[_at(o, 0, b)], W[_at(o, 1, b)]
            a0 = S[6 * TILE + b] + 0.0
            a1 = S[7 * TILE + b] + W[_at(o, 2, b)]
            a2 = S[8 * TILE + b] + W[_at(o, 3, b)]
            qdd = (W[_at(o, 17, b)] - (W[_at(o, 13, b)] * a0 + W[_at(o, 14, b)] * a1 + W[_at(o, 15, b)] * a2)) * W[
                _at(o, 16, b)
            ]
            A[uint64(i * B + b0 + b)] = qdd
            S[6 * TILE + b] = a0 + 1.0 * qdd
            S[7 * TILE + b] = a1 + s1 * qdd
            S[8 * TILE + b] = a2 + s2 * qdd


@njit
def _tile_params(theta):  # pragma: no cover - compiled
    """``(pf, tB, shared)``: the parameters as the tiles read them, rows of ``tB`` in one flat array.
    One column for every member (``theta`` (P, 1)): that column repeated :data:`TILE` times
    (``shared``; every tile reads columns ``0 .. TILE - 1``); else ``theta``'s own columns."""
    P, C = theta.shape
    if C > 1:
        return np.ascontiguousarray(theta).ravel(), C, False
    pf = aligned_empty(P * TILE)
    for r_ in range(P):
        x = theta[r_, 0]
        for b in range(TILE):
            pf[r_ * TILE + b] = x
    return pf, TILE, True


@njit
def acceleration_kernel(q, v, tau, theta, a):  # pragma: no cover - compiled
    """Forward dynamics of a batch in columns: ``a = ABA(q, v, tau - F(v))``, ``F`` the
    smoothed friction of :func:`mbs_envs.models.base.smoothed_friction`.

    Whole tiles of :data:`TILE` members go through :func:`_aba_tile` (SIMD over the members);
    the rest of the batch, and a member with an absolute angle beyond
    :data:`mbs_envs.dynamics.trig.SINCOS_RANGE` (or not finite), through :func:`_aba_member`.
    Both give the same bits (tested).

    Parameters
    ----------
    q, v, tau : ndarray, shape (N, B)
    theta : ndarray, shape (7 N + 2, B) or (7 N + 2, 1)
        Per member, or one column for all.
    a : ndarray, shape (N, B)
        Written [rad/s^2].
    """
    N, B = q.shape
    net = np.empty((N, B))
    _net_torque(v, tau, theta, net)
    tiled = B - B % TILE
    scalar = np.ones(B, np.bool_)  # the members the member path takes: the rest of the batch, and
    if tiled > 0:  # those with an angle beyond the SIMD sincos's range (libm's there)
        qf, vf, nf = np.ascontiguousarray(q).ravel(), np.ascontiguousarray(v).ravel(), net.ravel()
        pf, tB, shared = _tile_params(theta)
        W, S = aligned_empty(N * _SLOTS * TILE), aligned_empty(10 * TILE)
        # the tiles write flat columns: a itself when ravel gives a view, else a buffer copied back
        # (numba's ravel copies an array typed non-contiguous even when it is contiguous at run time)
        af = a.ravel() if a.flags.c_contiguous else aligned_empty(N * B)
        for b0 in range(0, tiled, TILE):
            _aba_tile(qf, vf, nf, pf, N, B, b0, W, S, af, tB, 0 if shared else b0)
            for b in range(TILE):
                scalar[b0 + b] = S[9 * TILE + b] == 0.0
        if af.ctypes.data != a.ctypes.data:
            for i in range(N):
                for b in range(tiled):
                    a[i, b] = af[i * B + b]
    if scalar.any():  # its work arrays only when some member takes it
        work, one = _aba_work(N), np.empty(N)
        for k in range(B):  # one call site: the member path is inlined once
            if scalar[k]:
                _member_acceleration(q, v, net, theta, a, k, work, one)


@njit
def _energy_tile(q, v, theta, N, B, b0, S, tB, tb0):  # pragma: no cover - compiled
    """:func:`_energy_member` of the members ``b0 .. b0 + TILE - 1`` at once (SIMD over the members,
    the operations in :func:`_energy_member`'s order: the same bits). The link loop's first lines
    are :func:`_aba_tile`'s, written out: through a shared inline function LLVM no longer
    vectorized this loop (docs/performance.md). Arrays flattened as in
    :func:`_aba_tile` (``theta`` rows of ``tB``, as :func:`_tile_params` gives them); ``S`` (10 * TILE,) work (slots: absolute angle, unused, joint height, link rate,
    joint velocity (2), the sums ``T``, ``V``, unused), whose slots 6, 7 end as ``T``, ``V`` and slot 9
    as whether every absolute angle was inside :data:`mbs_envs.dynamics.trig.SINCOS_RANGE`."""
    for b in range(TILE):
        for j in range(9):
            S[j * TILE + b] = 0.0
        S[9 * TILE + b] = 1.0
    for i in range(N):
        for b in range(TILE):
            m = b0 + b
            th = S[b] + q[uint64(i * B + m)]
            S[b] = th
            sn, cs = sincos(th)
            li, ri = theta[uint64(i * tB + tb0 + b)], theta[uint64((N + i) * tB + tb0 + b)]
            mi, Ici, arm = (
                theta[uint64((2 * N + i) * tB + tb0 + b)],
                theta[uint64((3 * N + i) * tB + tb0 + b)],
                theta[uint64((4 * N + i) * tB + tb0 + b)],
            )
            w = v[uint64(i * B + m)]
            y = S[2 * TILE + b]
            cy = y + ri * sn
            S[2 * TILE + b] = y + li * sn
            om = S[3 * TILE + b] + w
            S[3 * TILE + b] = om
            nx, ny = -sn * om, cs * om
            jx, jy = S[4 * TILE + b], S[5 * TILE + b]
            vx, vy = jx + ri * nx, jy + ri * ny
            S[6 * TILE + b] = S[6 * TILE + b] + (mi * (vx * vx + vy * vy) + Ici * om * om + arm * w * w)
            S[7 * TILE + b] = S[7 * TILE + b] + mi * cy
            S[4 * TILE + b] = jx + li * nx
            S[5 * TILE + b] = jy + li * ny
            S[9 * TILE + b] = S[9 * TILE + b] if in_range(th) else 0.0


@njit
def energy_kernel(q, v, theta, E):  # pragma: no cover - compiled
    """Mechanical energy ``T + V`` [J] of a batch in columns (:func:`_energy_member`); writes ``E`` (B,).
    Whole tiles by :func:`_energy_tile` (SIMD), the rest and members with an angle beyond
    the SIMD sincos's range by :func:`_energy_member` (the same bits, tested)."""
    N, B = q.shape
    tiled = B - B % TILE
    scalar = np.ones(B, np.bool_)
    if tiled > 0:
        qf, vf = np.ascontiguousarray(q).ravel(), np.ascontiguousarray(v).ravel()
        pf, tB, shared = _tile_params(theta)
        S = aligned_empty(10 * TILE)
        for b0 in range(0, tiled, TILE):
            _energy_tile(qf, vf, pf, N, B, b0, S, tB, 0 if shared else b0)
            for b in range(TILE):
                E[b0 + b] = 0.5 * S[6 * TILE + b] + theta[7 * N, _col(theta, b0 + b)] * S[7 * TILE + b]
                scalar[b0 + b] = S[9 * TILE + b] == 0.0
    work = _aba_work(N)
    for k in range(B):
        if scalar[k]:
            _energy_one(q, v, theta, E, k, work)


@njit(inline="always")
def _energy_one(q, v, theta, E, k, work):  # pragma: no cover - compiled
    """Member ``k`` of :func:`energy_kernel` by :func:`_energy_member` (scalar code)."""
    N = q.shape[0]
    th = theta[:, _col(theta, k)]
    T, V = _energy_member(q[:, k], v[:, k], th[0:N], th[N : 2 * N], th[2 * N : 3 * N], th[3 * N : 4 * N],
                          th[4 * N : 5 * N], th[7 * N], work)  # fmt: skip
    E[k] = T + V


@njit
def _member_kinematics(q, l, r, th, sn, cs, p, c):  # pragma: no cover - compiled
    """Kinematics of one chain: ``q, l, r`` (N,) joint angles [rad], link lengths and
    centre-of-mass offsets [m]; writes the work arrays ``th, sn, cs`` (N,) and ``p, c`` (N, 2).

    ``th_i = q_1 + ... + q_i`` (a running sum, in ``np.cumsum``'s order);
    ``(sn_i, cs_i) = (sin th_i, cos th_i)`` (:func:`mbs_envs.dynamics.trig.sincos_columns`, a SIMD pass);
    joint positions ``p_1 = 0``, ``p_{i+1} = p_i + l_i e_i`` with ``e_i = (cs_i, sn_i)``;
    centres ``c_i = p_i + r_i e_i``.
    """
    a = 0.0
    for i in range(q.shape[0]):
        a += q[i]
        th[i] = a
    sincos_columns(th, sn, cs)
    x, y = 0.0, 0.0
    for i in range(q.shape[0]):
        p[i, 0], p[i, 1] = x, y
        c[i, 0], c[i, 1] = x + r[i] * cs[i], y + r[i] * sn[i]
        x += l[i] * cs[i]
        y += l[i] * sn[i]


#: this module: a kernel passed on as a module attribute is a compile-time constant (a bare
#: global would be embedded as a Python object pointer, which numba cannot cache)
_this = sys.modules[__name__]


@njit
def advance_kernel(theta, stepper, q, v, tau):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.compiled.rk_run` with this model's :func:`acceleration_kernel` (cached on disk)."""
    rk_run(_this.acceleration_kernel, _compiled.no_projection, theta, stepper, q, v, tau)
