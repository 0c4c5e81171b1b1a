"""A swing-up trajectory optimized under the torque limit, and the time-varying LQR along it (compiled).

For the 2R arm with one motor (Acrobot, Pendubot), per member, on a model given by its kernel
parameter column ``theta`` (:meth:`mbs_envs.models.planar2r.Planar2R.kernel_params`, e.g. an identified
one), from a state ``x0 = (q, v)``:

1. **Initial guess** (a shooting search over a family of feedback laws): the energy-pumping law of
   :mod:`controllers.swingup` (collocated partial feedback linearization, the driven joint's PD
   ``k_q, k_v``, the pumping gain ``k_E``) is rolled out for every row of a grid of gains; the guess is
   the rollout, and the step, that come closest to upright by the LQR's cost-to-go ``dx^T S dx``.
2. **Optimization**: control-limited iLQR (Tassa, Mansard & Todorov 2014; for one input the box QP of
   the backward pass is a clamp, and a clamped input has no feedback) on

       min_u  sum_k (w_u u_k^2 + dx_k^T W dx_k) dt / 2 + dx_H^T P_T dx_H / 2,     |u_k| <= u_max,

   with the horizon ``H`` the guess's arrival step plus a tail, ``dx = x - x_up`` with wrapped angles,
   ``P_T`` a large terminal weight and ``W`` a running one (zero in the shipped controller: a minimum-effort
   path that ends upright). The dynamics are the discrete map the environments integrate (``substeps`` classical RK4 steps
   of the model's forward dynamics with the input held; :func:`controllers.control_map.rk4_map` is its
   numpy twin, equal to round-off, which the tests check).
3. **Stabilization**: time-varying LQR along ``(X, U)``: the discrete Riccati recursion on the map's
   Jacobians (forward differences) with stage cost ``(dx^T Q dx + R du^2) dt`` and terminal ``S``, so the
   gains join the upright LQR's at the end.

Members are independent. Within a member's plan the map runs on lanes (:func:`step_lanes`: the pumping search's
125 gain sets, the Jacobians' time steps, the line search's step lengths, each a lane of SIMD loops), with the
environments' own sines and cosines (the project's ``sincos``, 1 ulp of libm's); the filter and the catch test keep
the scalar map :func:`step4` (libm). A plan costs about half what it did in scalar code
(docs/performance.md).
"""

from __future__ import annotations

import numpy as np

from mbs_envs.dynamics.jit import njit
from mbs_envs.dynamics.trig import fma, in_range, sincos, sincos_libm, wrap, wrap_fast
from mbs_envs.models.planar2r import _acceleration, _acceleration_of, _energy, _energy_of, _friction

#: line-search step lengths of the iLQR (rolled out together, one lane each)
ALPHAS = np.array([1.0, 0.5, 0.25, 0.1, 0.03])
#: time steps differenced at once by :func:`jacobians` (lanes)
CHUNK = 64
#: rows of the work array of :func:`step_lanes`
WORK_ROWS = 24


@njit
def rate(x0, x1, x2, x3, u, driven, theta):  # pragma: no cover - compiled
    """``dx/dt`` of the 2R arm at ``x = (q1, q2, v1, v2)`` (scalars), torque ``u`` [N m] on joint ``driven``:
    a tuple of 4 (no arrays: the loops below allocate nothing per call)."""
    s1, c1, s2, c2 = np.sin(x0), np.cos(x0), np.sin(x1), np.cos(x1)
    F1 = _friction(x2, theta[9, 0], theta[11, 0], theta[13, 0], theta[14, 0], theta[16, 0])
    F2 = _friction(x3, theta[10, 0], theta[12, 0], theta[13, 0], theta[15, 0], theta[16, 0])
    t1 = u if driven == 0 else 0.0
    t2 = u if driven == 1 else 0.0
    a1, a2 = _acceleration(s1, c1, s2, c2, x2, x3, F1, F2, t1, t2, theta, 0)
    return x2, x3, a1, a2


@njit
def step4(x0, x1, x2, x3, u, driven, theta, dt, substeps):  # pragma: no cover - compiled
    """:func:`step_map` on scalars: a tuple of 4."""
    h = dt / substeps
    for _ in range(substeps):
        a0, a1, a2, a3 = rate(x0, x1, x2, x3, u, driven, theta)
        b0, b1, b2, b3 = rate(
            x0 + 0.5 * h * a0, x1 + 0.5 * h * a1, x2 + 0.5 * h * a2, x3 + 0.5 * h * a3, u, driven, theta
        )
        c0, c1, c2, c3 = rate(
            x0 + 0.5 * h * b0, x1 + 0.5 * h * b1, x2 + 0.5 * h * b2, x3 + 0.5 * h * b3, u, driven, theta
        )
        d0, d1, d2, d3 = rate(x0 + h * c0, x1 + h * c1, x2 + h * c2, x3 + h * c3, u, driven, theta)
        x0 = x0 + (h / 6.0) * (a0 + 2.0 * b0 + 2.0 * c0 + d0)
        x1 = x1 + (h / 6.0) * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
        x2 = x2 + (h / 6.0) * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
        x3 = x3 + (h / 6.0) * (a3 + 2.0 * b3 + 2.0 * c3 + d3)
    return x0, x1, x2, x3


@njit
def step_map(x, u, driven, theta, dt, substeps):  # pragma: no cover - compiled
    """``F(x, u)``: ``substeps`` classical RK4 steps of ``dt / substeps`` [s] with ``u`` held; ``x`` (4,), shape (4,)."""
    out = np.empty(4)
    out[0], out[1], out[2], out[3] = step4(x[0], x[1], x[2], x[3], u, driven, theta, dt, substeps)
    return out


@njit
def map_rows(X, u, driven, theta, dt, substeps, out):  # pragma: no cover - compiled
    """:func:`step_map` for each row: ``X`` (B, 4), ``u`` (B,), ``theta`` (P, B) a column per row (or (P, 1) for
    all); ``out`` (B, 4) written."""
    n_p = theta.shape[0]
    col = np.empty((n_p, 1))
    for b in range(X.shape[0]):
        j = b if theta.shape[1] > 1 else 0
        for p in range(n_p):
            col[p, 0] = theta[p, j]
        out[b, 0], out[b, 1], out[b, 2], out[b, 3] = step4(
            X[b, 0], X[b, 1], X[b, 2], X[b, 3], u[b], driven, col, dt, substeps
        )


@njit
def wrapped(x, goal):  # pragma: no cover - compiled
    """``x - goal`` with the angles (entries 0, 1) wrapped to ``[-pi, pi)``; shape (4,)."""
    d = x - goal
    for i in range(2):
        d[i] = wrap(d[i])
    return d


@njit(inline="always")
def error4(x0, x1, x2, x3, r0, r1, r2, r3):  # pragma: no cover - compiled
    """:func:`wrapped` on scalars: ``x - r`` with the angles wrapped, a tuple of 4 (nothing allocated)."""
    return wrap(x0 - r0), wrap(x1 - r1), x2 - r2, x3 - r3


@njit
def energy(x, theta):  # pragma: no cover - compiled
    """Mechanical energy [J] of the state ``x`` (4,)."""
    return _energy(np.sin(x[0]), np.cos(x[0]), np.sin(x[1]), np.cos(x[1]), x[2], x[3], theta, 0)


# -- lanes: the planner's map on many states at once -------------------------------------------------
#
# The planner's own map (the pumping search over its gains, the line search over its step lengths, the
# Jacobians over the time steps) runs on "lanes": states in the columns of (4, L) arrays, each loop over the
# lanes written without calls so that LLVM vectorizes it. The sines and cosines are the project's
# straight-line ``sincos`` (1 ulp of libm's, as the environments' own kernels take them; libm beyond its
# range), the wrap :func:`mbs_envs.dynamics.trig.wrap_fast` (Python's bits; ``fmod`` beyond its range), in a
# second pass only where needed. Every lane's arithmetic is the same whatever the number of lanes: one lane
# gives the bits of that lane in many (tested).


@njit(_nrt=False)
def trig_lanes(q1, q2, T, L):  # pragma: no cover - compiled
    """``T[0..3, :L] = sin q1, cos q1, sin q2, cos q2`` of lanes ``:L`` (``q1, q2`` rows of a state array)."""
    ok = True
    for l in range(L):
        T[0, l], T[1, l] = sincos(q1[l])
        T[2, l], T[3, l] = sincos(q2[l])
        ok &= in_range(q1[l]) & in_range(q2[l])
    if not ok:
        for l in range(L):
            if not in_range(q1[l]):
                T[0, l], T[1, l] = sincos_libm(q1[l])
            if not in_range(q2[l]):
                T[2, l], T[3, l] = sincos_libm(q2[l])


@njit(_nrt=False)
def rate_lanes(X, u, driven, theta, T, out, L):  # pragma: no cover - compiled
    """:func:`rate` of lanes ``:L``: ``X`` (4, >= L) states, ``u`` (>= L,) torques on joint ``driven``, ``T`` their
    :func:`trig_lanes` (given), ``out`` (4, >= L) written with ``dx/dt``. The parameters are read once, as scalars,
    and the friction (a ``tanh`` where Coulomb or Stribeck terms are set) in a loop of its own."""
    m1, m2, l1, r1, r2 = theta[0, 0], theta[1, 0], theta[2, 0], theta[4, 0], theta[5, 0]
    I1, I2, g, b1, b2 = theta[6, 0], theta[7, 0], theta[8, 0], theta[9, 0], theta[10, 0]
    if theta[11, 0] != 0.0 or theta[12, 0] != 0.0 or theta[14, 0] != 0.0 or theta[15, 0] != 0.0:
        for l in range(L):
            out[2, l] = _friction(X[2, l], b1, theta[11, 0], theta[13, 0], theta[14, 0], theta[16, 0])
            out[3, l] = _friction(X[3, l], b2, theta[12, 0], theta[13, 0], theta[15, 0], theta[16, 0])
    else:  # _friction's value without its branches: viscous only
        for l in range(L):
            out[2, l] = b1 * X[2, l]
            out[3, l] = b2 * X[3, l]
    for l in range(L):
        t1 = u[l] if driven == 0 else 0.0
        t2 = u[l] if driven == 1 else 0.0
        a1, a2 = _acceleration_of(T[0, l], T[1, l], T[2, l], T[3, l], X[2, l], X[3, l], out[2, l], out[3, l], t1, t2,
                                  m1, m2, l1, r1, r2, I1, I2, g)  # fmt: skip
        out[0, l] = X[2, l]
        out[1, l] = X[3, l]
        out[2, l] = a1
        out[3, l] = a2


@njit(_nrt=False)
def step_lanes(X, u, driven, theta, dt, substeps, work, L):  # pragma: no cover - compiled
    """:func:`step_map` of lanes ``:L`` in place: ``X`` (4, >= L), ``u`` (>= L,) held, ``work`` (:data:`WORK_ROWS`,
    >= L) scratch."""
    h = dt / substeps
    T, Y = work[0:4], work[4:8]
    K0, K1, K2, K3 = work[8:12], work[12:16], work[16:20], work[20:24]
    for _ in range(substeps):
        trig_lanes(X[0], X[1], T, L)
        rate_lanes(X, u, driven, theta, T, K0, L)
        for i in range(4):
            for l in range(L):
                Y[i, l] = X[i, l] + 0.5 * h * K0[i, l]
        trig_lanes(Y[0], Y[1], T, L)
        rate_lanes(Y, u, driven, theta, T, K1, L)
        for i in range(4):
            for l in range(L):
                Y[i, l] = X[i, l] + 0.5 * h * K1[i, l]
        trig_lanes(Y[0], Y[1], T, L)
        rate_lanes(Y, u, driven, theta, T, K2, L)
        for i in range(4):
            for l in range(L):
                Y[i, l] = X[i, l] + h * K2[i, l]
        trig_lanes(Y[0], Y[1], T, L)
        rate_lanes(Y, u, driven, theta, T, K3, L)
        for i in range(4):
            for l in range(L):
                X[i, l] = X[i, l] + (h / 6.0) * (K0[i, l] + 2.0 * K1[i, l] + 2.0 * K2[i, l] + K3[i, l])


@njit(_nrt=False)
def wrap_lanes(x, L):  # pragma: no cover - compiled
    """``x[:L] = wrap(x[:L])`` in place: :func:`wrap_fast` in one pass where every lane is in its range, else
    :func:`wrap` lane by lane."""
    ok = True
    for l in range(L):
        ok &= wrap_fast(x[l])[1]
    if ok:
        for l in range(L):
            x[l] = wrap_fast(x[l])[0]
    else:
        for l in range(L):
            x[l] = wrap(x[l])


@njit(_nrt=False)
def pumping_lanes(X, k_q, k_v, k_E, E_up, driven, theta, u_max, T, R0, R1, w, u, L):  # pragma: no cover - compiled
    """:func:`pumping_input` of lanes ``:L`` with gains ``k_q, k_v, k_E`` (>= L,) each, into ``u``; ``T`` is written
    with the states' :func:`trig_lanes`, ``R0, R1`` (4, >= L) with the rates at ``u = 0`` and ``1``, ``w`` scratch."""
    m1, m2, l1, r1, r2 = theta[0, 0], theta[1, 0], theta[2, 0], theta[4, 0], theta[5, 0]
    I1, I2, g = theta[6, 0], theta[7, 0], theta[8, 0]
    trig_lanes(X[0], X[1], T, L)
    for l in range(L):
        u[l] = 0.0
    rate_lanes(X, u, driven, theta, T, R0, L)
    for l in range(L):
        u[l] = 1.0
    rate_lanes(X, u, driven, theta, T, R1, L)
    for l in range(L):
        w[l] = X[1, l] if driven == 1 else X[0, l] - 0.5 * np.pi
    wrap_lanes(w, L)
    for l in range(L):
        E_err = _energy_of(T[0, l], T[1, l], T[2, l], T[3, l], X[2, l], X[3, l], m1, m2, l1, r1, r2, I1, I2, g) - E_up
        if driven == 1:  # acrobot
            y = -k_q[l] * w[l] - k_v[l] * X[3, l] + k_E[l] * E_err * X[2, l]
            a0, a1 = R0[3, l], R1[3, l]
        else:  # pendubot
            y = -k_q[l] * w[l] - k_v[l] * X[2, l] - k_E[l] * E_err * X[2, l]
            a0, a1 = R0[2, l], R1[2, l]
        u[l] = min(max((y - a0) / (a1 - a0), -u_max), u_max)


@njit
def rollout_lanes(
    x0, U, Xref, kff, K, alphas, u_max, driven, theta, dt, substeps, X, Un, ok
):  # pragma: no cover - compiled
    """:func:`_rollout` for every step length of ``alphas`` (A,) at once, a lane each: writes ``X`` (A, H+1, 4),
    ``Un`` (A, H) and ``ok`` (A,): whether the lane's states stayed finite (a lane that stops being finite is
    computed on, and its trajectory is not to be used)."""
    A, H = alphas.shape[0], U.shape[0]
    Z, D, u, work = np.empty((4, A)), np.empty((4, A)), np.empty(A), np.empty((WORK_ROWS, A))
    for a in range(A):
        ok[a] = True
        for i in range(4):
            Z[i, a] = x0[i]
            X[a, 0, i] = x0[i]
    for k in range(H):
        for a in range(A):
            D[0, a] = Z[0, a] - Xref[k, 0]
            D[1, a] = Z[1, a] - Xref[k, 1]
            D[2, a] = Z[2, a] - Xref[k, 2]
            D[3, a] = Z[3, a] - Xref[k, 3]
        wrap_lanes(D[0], A)
        wrap_lanes(D[1], A)
        for a in range(A):
            v = U[k] + alphas[a] * kff[k] + dot4(K[k, 0], K[k, 1], K[k, 2], K[k, 3], D[0, a], D[1, a], D[2, a], D[3, a])
            u[a] = min(max(v, -u_max), u_max)
            Un[a, k] = u[a]
        step_lanes(Z, u, driven, theta, dt, substeps, work, A)
        alive = False
        for a in range(A):
            for i in range(4):
                X[a, k + 1, i] = Z[i, a]
            ok[a] = (
                ok[a]
                and np.isfinite(Z[0, a])
                and np.isfinite(Z[1, a])
                and np.isfinite(Z[2, a])
                and np.isfinite(Z[3, a])
            )
            alive |= ok[a]
        if not alive:
            return


@njit
def pumping_input(x, k_q, k_v, k_E, E_up, driven, theta, u_max):  # pragma: no cover - compiled
    """The energy-pumping law of :class:`controllers.swingup.SwingUpLQR` (its module docstring), clipped to
    ``u_max``, at the state ``x`` (4,): one lane of :func:`pumping_lanes`. The driven joint's acceleration is affine
    in ``u``, so the partial feedback linearization's input is ``(y - a(0)) / (a(1) - a(0))``, from two
    forward-dynamics calls (no mass matrix needed)."""
    X = np.empty((4, 1))
    X[:, 0] = x
    T, R0, R1, w, u = np.empty((4, 1)), np.empty((4, 1)), np.empty((4, 1)), np.empty(1), np.empty(1)
    pumping_lanes(X, np.array([k_q]), np.array([k_v]), np.array([k_E]), E_up, driven, theta, u_max, T, R0, R1, w, u, 1)
    return u[0]


@njit
def _pump(
    X, k_q, k_v, k_E, E_up, u_max, driven, theta, dt, substeps, steps, U, search, goal, S, patience, best, when
):  # pragma: no cover - compiled
    """The pumping law with gains ``k_q, k_v, k_E`` (L,) from the states ``X`` (4, L), ``steps`` steps of ``dt``, a lane
    per gain set: writes the inputs of lane 0 into ``U`` (when its length is ``steps``) and, where ``search``, per
    lane the smallest weighted cost-to-go (:func:`pumping_search`) into ``best`` and its step into ``when``."""
    L = X.shape[1]
    T, R0, R1, E, w = np.empty((4, L)), np.empty((4, L)), np.empty((4, L)), np.empty((4, L)), np.empty(L)
    u, work, alive = np.empty(L), np.empty((WORK_ROWS, L)), np.ones(L, np.bool_)
    for l in range(L):
        best[l], when[l] = np.inf, 0
    for k in range(steps):
        pumping_lanes(X, k_q, k_v, k_E, E_up, driven, theta, u_max, T, R0, R1, w, u, L)
        if U.shape[0] == steps:
            U[k] = u[0]
        step_lanes(X, u, driven, theta, dt, substeps, work, L)
        if not search:
            continue
        for l in range(L):
            E[0, l] = X[0, l] - goal[0]
            E[1, l] = X[1, l] - goal[1]
            E[2, l] = X[2, l] - goal[2]
            E[3, l] = X[3, l] - goal[3]
        wrap_lanes(E[0], L)
        wrap_lanes(E[1], L)
        weight = np.exp(k / patience)
        for l in range(L):
            alive[l] = (
                alive[l]
                and np.isfinite(X[0, l])
                and np.isfinite(X[1, l])
                and np.isfinite(X[2, l])
                and np.isfinite(X[3, l])
            )
            c = 0.0
            for i in range(4):
                for j in range(4):
                    c += E[i, l] * S[i, j] * E[j, l]
            c *= weight
            if alive[l] and c < best[l]:
                best[l], when[l] = c, k


@njit
def pumping_search(
    x0, gains, E_up, goal, S, u_max, driven, theta, dt, substeps, steps, patience
):  # pragma: no cover - compiled
    """Step 1 (module docstring): the row of ``gains`` (G, 3: ``k_q, k_v, k_E``) whose rollout from ``x0``
    comes closest to upright within ``steps`` steps of ``dt``, by the cost-to-go ``dx^T S dx`` weighted by
    ``exp(k / patience)`` at step ``k`` (an approach ``e`` times as far is as good ``patience`` steps sooner); a
    rollout counts up to its last finite state. Every row is a lane (:func:`_pump`); ties go to the first row, and
    within a row to the first step. Returns ``(row, step, weighted cost)``: the chosen state is reached after
    ``step + 1`` inputs."""
    G = gains.shape[0]
    X = np.empty((4, G))
    for i in range(4):
        X[i, :] = x0[i]
    best, when = np.empty(G), np.empty(G, np.int64)
    k_q, k_v, k_E = gains[:, 0].copy(), gains[:, 1].copy(), gains[:, 2].copy()
    _pump(
        X,
        k_q,
        k_v,
        k_E,
        E_up,
        u_max,
        driven,
        theta,
        dt,
        substeps,
        steps,
        np.empty(0),
        True,
        goal,
        S,
        patience,
        best,
        when,
    )
    row = 0
    for g in range(1, G):
        if best[g] < best[row]:
            row = g
    return row, when[row], best[row]


@njit
def pumping_rollout(x0, k_q, k_v, k_E, E_up, u_max, driven, theta, dt, substeps, U):  # pragma: no cover - compiled
    """The pumping law's inputs ``U`` (H,) from ``x0``, written in place: one lane (the bits of that row's lane in
    :func:`pumping_search`)."""
    X = np.empty((4, 1))
    X[:, 0] = x0
    _pump(X, np.array([k_q]), np.array([k_v]), np.array([k_E]), E_up, u_max, driven, theta, dt, substeps, U.shape[0], U, False,
          np.zeros(4), np.zeros((4, 4)), 1.0, np.empty(1), np.empty(1, np.int64))  # fmt: skip


@njit
def _cost(X, U, goal, w_u, W, S_T, dt):  # pragma: no cover - compiled
    e = 0.0  # sum(U * U) in numba's order (sequential), without the temporary
    for k in range(U.shape[0]):
        e += U[k] * U[k]
    J = 0.5 * w_u * dt * e
    if np.any(W != 0.0):  # the running state cost (zero in the shipped controllers: each of its terms adds an exact 0)
        for k in range(U.shape[0]):
            d = wrapped(X[k], goal)
            J += 0.5 * dt * (d @ W @ d)
    d = wrapped(X[U.shape[0]], goal)
    return J + 0.5 * (d @ S_T @ d)


@njit(inline="always")
def dot4(a0, a1, a2, a3, b0, b1, b2, b3):  # pragma: no cover - compiled
    """``a . b`` of two 4-vectors as ``a0 b0`` then three fused multiply-adds: the rounding of the BLAS ``ddot``
    (OpenBLAS's loop over a short vector) that ``a @ b`` calls for 4 entries, without its call and allocation."""
    return fma(a3, b3, fma(a2, b2, fma(a1, b1, a0 * b0)))


@njit
def _rollout(x0, U, Xref, kff, K, alpha, u_max, driven, theta, dt, substeps, X, Un):  # pragma: no cover - compiled
    """``u_k = clip(U_k + alpha kff_k + K_k (x_k - Xref_k))`` from ``x0``; writes ``X`` (H+1, 4), ``Un`` (H,): one
    lane of :func:`rollout_lanes`. False if the state stops being finite."""
    H = U.shape[0]
    ok = np.empty(1, np.bool_)
    rollout_lanes(x0, U, Xref, kff, K, np.array([alpha]), u_max, driven, theta, dt, substeps, X.reshape((1, H + 1, 4)),
                  Un.reshape((1, H)), ok)  # fmt: skip
    return ok[0]


@njit
def jacobians(X, U, driven, theta, dt, substeps, A, b):  # pragma: no cover - compiled
    """``A_k = dF/dx`` and ``b_k = dF/du`` along ``(X, U)`` by forward differences (step 1e-7, from the stored
    ``X_{k+1} = F(X_k, U_k)``: five map calls per step, :data:`CHUNK` steps at a time as lanes), written into ``A``
    (>= H, 4, 4) and ``b`` (>= H, 4)."""
    eps = 1e-7
    H = U.shape[0]
    Z, v, work = np.empty((4, CHUNK)), np.empty(CHUNK), np.empty((WORK_ROWS, CHUNK))
    for k0 in range(0, H, CHUNK):
        n = min(CHUNK, H - k0)
        for j in range(5):
            for l in range(n):
                k = k0 + l
                Z[0, l] = X[k, 0] + (eps if j == 0 else 0.0)
                Z[1, l] = X[k, 1] + (eps if j == 1 else 0.0)
                Z[2, l] = X[k, 2] + (eps if j == 2 else 0.0)
                Z[3, l] = X[k, 3] + (eps if j == 3 else 0.0)
                v[l] = U[k] + (eps if j == 4 else 0.0)
            step_lanes(Z, v, driven, theta, dt, substeps, work, n)
            for l in range(n):
                k = k0 + l
                for i in range(4):
                    d = (Z[i, l] - X[k + 1, i]) / eps
                    if j < 4:
                        A[k, i, j] = d
                    else:
                        b[k, i] = d


@njit
def _backward(X, U, goal, w_u, W, S_T, u_max, mu, A, b, dt, kff, K):  # pragma: no cover - compiled
    """The control-limited backward pass (module docstring, step 2); writes ``kff`` (H,) and ``K`` (H, 4).
    Explicit loops over the 4 x 4 blocks: nothing is allocated per step."""
    H = U.shape[0]
    d = wrapped(X[H], goal)
    Vx = S_T @ d
    Vxx = S_T.copy()
    r = w_u * dt
    Vb, Qx, Qux, gain, dk, VA = np.empty(4), np.empty(4), np.empty(4), np.empty(4), np.empty(4), np.empty((4, 4))
    for k in range(H - 1, -1, -1):
        Ak, bk = A[k], b[k]
        for i in range(4):
            Vb[i] = Vxx[i, 0] * bk[0] + Vxx[i, 1] * bk[1] + Vxx[i, 2] * bk[2] + Vxx[i, 3] * bk[3]
        Qu = r * U[k] + bk[0] * Vx[0] + bk[1] * Vx[1] + bk[2] * Vx[2] + bk[3] * Vx[3]
        Quu = r + bk[0] * Vb[0] + bk[1] * Vb[1] + bk[2] * Vb[2] + bk[3] * Vb[3] + mu
        dk[0], dk[1], dk[2], dk[3] = error4(X[k, 0], X[k, 1], X[k, 2], X[k, 3], goal[0], goal[1], goal[2], goal[3])
        for i in range(4):
            Qx[i] = Ak[0, i] * Vx[0] + Ak[1, i] * Vx[1] + Ak[2, i] * Vx[2] + Ak[3, i] * Vx[3]
            Qx[i] += dt * (W[i, 0] * dk[0] + W[i, 1] * dk[1] + W[i, 2] * dk[2] + W[i, 3] * dk[3])
            Qux[i] = Ak[0, i] * Vb[0] + Ak[1, i] * Vb[1] + Ak[2, i] * Vb[2] + Ak[3, i] * Vb[3]
        step = -Qu / Quu
        clamped = abs(U[k] + step) > u_max  # the box QP in one dimension: clamp, no feedback on a clamped input
        if clamped:
            step = np.sign(U[k] + step) * u_max - U[k]
        for i in range(4):
            gain[i] = 0.0 if clamped else -Qux[i] / Quu
        kff[k] = step
        K[k] = gain
        for i in range(4):
            Vx[i] = Qx[i] + gain[i] * (Quu * step) + gain[i] * Qu + Qux[i] * step
        for i in range(4):  # VA = Vxx A
            for j in range(4):
                VA[i, j] = Vxx[i, 0] * Ak[0, j] + Vxx[i, 1] * Ak[1, j] + Vxx[i, 2] * Ak[2, j] + Vxx[i, 3] * Ak[3, j]
        for i in range(4):  # Vxx = A^T Vxx A + Quu g g^T + g Qux^T + Qux g^T (symmetric)
            for j in range(i, 4):
                v = Ak[0, i] * VA[0, j] + Ak[1, i] * VA[1, j] + Ak[2, i] * VA[2, j] + Ak[3, i] * VA[3, j]
                v += Quu * gain[i] * gain[j] + gain[i] * Qux[j] + Qux[i] * gain[j] + dt * W[i, j]
                Vxx[i, j] = v
        for i in range(4):
            for j in range(i):
                Vxx[i, j] = Vxx[j, i]


@njit
def ilqr(
    x0, U, X_ref, K_ref, goal, w_u, W, S_T, u_max, driven, theta, dt, substeps, iterations, alphas
):  # pragma: no cover - compiled
    """Step 2 (module docstring): improve the inputs ``U`` (H,) from ``x0`` in place, starting from the rollout
    of ``u_k = U_k + K_ref_k (x_k - X_ref_k)`` (``K_ref = 0``: open loop; a plan's own gains and states: the
    closed-loop rollout, a far better start from a state off the plan). Returns ``(X, J, A, b, current)``: the
    states (H+1, 4) along the result and its cost (inf if its rollout was not finite), and the map's Jacobians
    ``A`` (H, 4, 4), ``b`` (H, 4) of the last iteration, ``current`` when they are those along the result.

    An iteration whose line search finds no lower cost leaves ``(X, U)`` as they were, so the next one takes the
    Jacobians it has instead of differencing the same trajectory again (the same numbers: a third of the
    iterations on the protocol's plans, where the Jacobians are a quarter of an iteration's work)."""
    H = U.shape[0]
    X = np.empty((H + 1, 4))
    Xn = np.empty((alphas.shape[0], H + 1, 4))  # the line search's rollouts, a lane per step length
    Un = np.empty((alphas.shape[0], H))
    ok = np.empty(alphas.shape[0], np.bool_)
    kff = np.zeros(H)
    K = np.zeros((H, 4))
    A = np.empty((H, 4, 4))
    b = np.empty((H, 4))
    if not _rollout(x0, U, X_ref, kff, K_ref, 0.0, u_max, driven, theta, dt, substeps, X, Un[0]):
        return X, np.inf, A, b, False
    U[:] = Un[0]
    J = _cost(X, U, goal, w_u, W, S_T, dt)
    mu = 1e-6
    current = False  # whether A, b are the Jacobians along (X, U)
    for _ in range(iterations):
        if not current:
            jacobians(X, U, driven, theta, dt, substeps, A, b)
            current = True
        _backward(X, U, goal, w_u, W, S_T, u_max, mu, A, b, dt, kff, K)
        improved = False
        rollout_lanes(x0, U, X, kff, K, alphas, u_max, driven, theta, dt, substeps, Xn, Un, ok)
        for a in range(alphas.shape[0]):  # the first step length, in order, that lowers the cost
            if ok[a]:
                Jn = _cost(Xn[a], Un[a], goal, w_u, W, S_T, dt)
                if Jn < J:
                    J = Jn
                    X[:] = Xn[a]
                    U[:] = Un[a]
                    improved = True
                    current = False
                    break
        mu = max(mu / 4.0, 1e-9) if improved else mu * 10.0
    return X, J, A, b, current


@njit
def tvlqr(X, U, Q, R, S_T, driven, theta, dt, substeps):  # pragma: no cover - compiled
    """Step 3 (module docstring): the gains ``K`` (H, 4) of ``u_k = U_k + K_k (x_k - X_k)``."""
    H = U.shape[0]
    A = np.empty((H, 4, 4))
    b = np.empty((H, 4))
    jacobians(X, U, driven, theta, dt, substeps, A, b)
    return riccati_gains(A, b, Q, R, S_T, dt)


@njit
def riccati_gains(A, b, Q, R, S_T, dt):  # pragma: no cover - compiled
    """The time-varying LQR's gains ``K`` (H, 4) from the map's Jacobians ``A`` (>= H, 4, 4), ``b`` (H, 4): the
    discrete Riccati recursion with stage cost ``(dx^T Q dx + R du^2) dt`` and terminal ``S_T``."""
    H = b.shape[0]
    K = np.empty((H, 4))
    P = S_T.copy()
    Qd = Q * dt
    for k in range(H - 1, -1, -1):
        Pb = P @ b[k]
        quu = R * dt + b[k] @ Pb
        qux = A[k].T @ Pb
        K[k] = -qux / quu
        P = Qd + A[k].T @ P @ A[k] - np.outer(qux, qux) / quu
        P = 0.5 * (P + P.T)
    return K


@njit(nogil=True)  # members plan on threads of their own (controllers.planned_swingup)
def plan(x0, gains, E_up, goal, S, w_u, W, P_T, Q, R, u_max, u_plan, driven, theta, dt, substeps, steps, tail, patience, iterations,
         alphas, U_out, X_out, K_out):  # pragma: no cover - compiled  # fmt: skip
    """Steps 1-3 (module docstring) from ``x0`` within ``steps`` steps of ``dt`` (the plan's knots), the plan's inputs within
    ``u_plan`` (<= ``u_max``, the feedback's margin), its gains' within ``u_max``: writes the inputs
    ``U_out[:H]``, states ``X_out[:H + 1]`` and gains ``K_out[:H]`` and returns ``(H, the largest entry of the
    wrapped terminal error |x_H - x_up|)``; ``H = 0`` where no finite plan was found."""
    row, step, _ = pumping_search(x0, gains, E_up, goal, S, u_plan, driven, theta, dt, substeps, steps - tail, patience)
    H = min(step + 1 + tail, steps)
    U = np.empty(H)
    pumping_rollout(x0, gains[row, 0], gains[row, 1], gains[row, 2], E_up, u_plan, driven, theta, dt, substeps, U)
    return refine(x0, U, np.zeros((H + 1, 4)), np.zeros((H, 4)), goal, S, w_u, W, P_T, Q, R, u_plan, driven, theta, dt, substeps,
                  iterations, alphas, U_out, X_out, K_out)  # fmt: skip


@njit(nogil=True)  # members plan on threads of their own (controllers.planned_swingup)
def refine(x0, U, X_ref, K_ref, goal, S, w_u, W, P_T, Q, R, u_plan, driven, theta, dt, substeps, iterations, alphas, U_out, X_out,
           K_out):  # pragma: no cover - compiled  # fmt: skip
    """Steps 2-3 (module docstring) from the guess ``U`` (H,) with feedback ``K_ref`` about ``X_ref`` (:func:`ilqr`):
    as :func:`plan`, whose return it gives."""
    H = U.shape[0]
    X, J, A, b, current = ilqr(
        x0, U, X_ref, K_ref, goal, w_u, W, P_T, u_plan, driven, theta, dt, substeps, iterations, alphas
    )
    if not np.isfinite(J):
        return 0, np.inf
    U_out[:H] = U
    X_out[: H + 1] = X
    # the last iteration's Jacobians where they are along the result (its line search found nothing lower)
    K_out[:H] = riccati_gains(A, b, Q, R, S, dt) if current else tvlqr(X, U, Q, R, S, driven, theta, dt, substeps)
    return H, np.abs(wrapped(X[H], goal)).max()


@njit
def lqr_catches(x0, K, goal, u_max, driven, theta, dt, substeps, steps, tol, bound):  # pragma: no cover - compiled
    """Whether the saturated LQR ``u = clip(-K dx)`` brings ``x0`` within ``tol`` of upright (largest wrapped entry
    [rad, rad/s]) and keeps it there for the last tenth of ``steps`` control steps, with neither angle ever more than
    ``bound`` [rad] off upright on the way (``inf``: no bound), simulated on the map: one point of the LQR's region of
    attraction under the torque limit, by simulation."""
    x0_, x1, x2, x3 = x0[0], x0[1], x0[2], x0[3]
    hold = max(1, steps // 10)
    for k in range(steps):
        d0, d1, d2, d3 = error4(x0_, x1, x2, x3, goal[0], goal[1], goal[2], goal[3])
        if k >= steps - hold and max(abs(d0), abs(d1), abs(d2), abs(d3)) > tol:
            return False
        if max(abs(d0), abs(d1)) > bound:
            return False
        u = min(max(-(K[0] * d0 + K[1] * d1 + K[2] * d2 + K[3] * d3), -u_max), u_max)
        x0_, x1, x2, x3 = step4(x0_, x1, x2, x3, u, driven, theta, dt, substeps)
        if not (np.isfinite(x0_) and np.isfinite(x1) and np.isfinite(x2) and np.isfinite(x3)):
            return False
    return True


@njit
def ekf_steps(X, P, u, Y, theta, driven, dt, substeps, Q_w, R_n, eps, X_out, P_out):  # pragma: no cover - compiled
    """One extended Kalman filter step per member on the 2R arm's map (:func:`controllers.estimator.ekf_step`,
    the same arithmetic compiled; the model's map :func:`step4`, ``F_x`` by central differences of ``eps``):

        predict:  x- = F(x+, u),              P- = F_x P+ F_x^T + Q_w
        update:   L = P- (P- + R_n)^-1,       x+ = x- + L (y - x-),   P+ = (I - L) P-  (symmetrized)

    Parameters
    ----------
    X, P : ndarray, shapes (B, 4) and (B, 4, 4)
        Last estimates ``(q, v)`` [rad, rad/s] and covariances.
    u : ndarray, shape (B,)
        The input applied since [N m].
    Y : ndarray, shape (B, 4)
        New observations.
    theta : ndarray, shape (P, B)
        Each member's kernel parameters (a column each).
    Q_w : ndarray, shape (B, 4, 4)
    R_n : ndarray, shape (4, 4)
    X_out, P_out : ndarray, shapes of ``X`` and ``P``
        Written with the new estimates (angles wrapped) and covariances; NaN for a member whose prediction is
        not finite.
    """
    B, n_p = X.shape[0], theta.shape[0]
    col = np.empty((n_p, 1))
    F = np.empty((4, 4))
    z = np.empty(4)
    for b in range(B):
        for p in range(n_p):
            col[p, 0] = theta[p, b]
        x0, x1, x2, x3 = step4(X[b, 0], X[b, 1], X[b, 2], X[b, 3], u[b], driven, col, dt, substeps)
        for j in range(4):
            z[:] = X[b]
            z[j] += eps
            p0, p1, p2, p3 = step4(z[0], z[1], z[2], z[3], u[b], driven, col, dt, substeps)
            z[:] = X[b]
            z[j] -= eps
            m0, m1, m2, m3 = step4(z[0], z[1], z[2], z[3], u[b], driven, col, dt, substeps)
            F[0, j], F[1, j] = (p0 - m0) / (2 * eps), (p1 - m1) / (2 * eps)
            F[2, j], F[3, j] = (p2 - m2) / (2 * eps), (p3 - m3) / (2 * eps)
        P_pred = F @ P[b] @ F.T + Q_w[b]
        if not (
            np.isfinite(P_pred).all() and np.isfinite(x0) and np.isfinite(x1) and np.isfinite(x2) and np.isfinite(x3)
        ):
            X_out[b], P_out[b] = np.nan, np.nan  # a lost member: the caller restarts it
            continue
        L = np.linalg.solve(P_pred + R_n, P_pred).T
        e0, e1, e2, e3 = wrap(Y[b, 0] - x0), wrap(Y[b, 1] - x1), Y[b, 2] - x2, Y[b, 3] - x3
        X_out[b, 0] = wrap(x0 + (L[0, 0] * e0 + L[0, 1] * e1 + L[0, 2] * e2 + L[0, 3] * e3))
        X_out[b, 1] = wrap(x1 + (L[1, 0] * e0 + L[1, 1] * e1 + L[1, 2] * e2 + L[1, 3] * e3))
        X_out[b, 2] = x2 + (L[2, 0] * e0 + L[2, 1] * e1 + L[2, 2] * e2 + L[2, 3] * e3)
        X_out[b, 3] = x3 + (L[3, 0] * e0 + L[3, 1] * e1 + L[3, 2] * e2 + L[3, 3] * e3)
        P_new = P_pred - L @ P_pred
        P_out[b] = 0.5 * (P_new + P_new.T)
