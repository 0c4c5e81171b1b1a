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
        b0, b1, b2, b3 = rate(x0 + 0.5 * h * a0, x1 + 0.5 * h * a1, x2 + 0.5 * h * a2, x3 + 0.5 * h * a3, u, driven, theta)
        c0, c1, c2, c3 = rate(x0 + 0.5 * h * b0, x1 + 0.5 * h * b1, x2 + 0.5 * h * b2, x3 + 0.5 * h * b3, u, driven, theta)
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
        out[b, 0], out[b, 1], out[b, 2], out[b, 3] = step4(X[b, 0], X[b, 1], X[b, 2], X[b, 3], u[b], driven, col, dt, substeps)


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
# Jacobians over the time steps) runs on "lanes": :data:`LANES` states at a time, each a column of a block of
# rows in one flat buffer (:data:`WORK_SIZE` doubles; rows ``_X`` the states, ``_U`` the inputs, the rest
# scratch), stepped by loops without calls over a width and at row offsets known when compiling, so that LLVM
# vectorizes them without checking at run time whether arrays overlap (with separate arrays per quantity a step
# of five lanes paid about 750 such checks, docs/performance.md). The sines and cosines are the project's
# straight-line ``sincos`` (1 ulp of libm's, as the environments' own kernels take them; libm beyond its range),
# the wrap :func:`mbs_envs.dynamics.trig.wrap_fast` (Python's bits; ``fmod`` beyond its range), in a second pass
# only where needed. Every lane's arithmetic is the same whatever the other lanes hold: one state gives the bits
# of that state among many (tested).

#: states per block of lanes
LANES = 8
#: time steps differenced at once by :func:`jacobians`
CHUNK = LANES
# rows of a block: states, stage states, sines and cosines, the four RK4 rates, inputs, the pumping law's rates at
# u = 0 and 1, a wrapped angle, errors, gains (k_q, k_v, k_E), step lengths
_X, _Y, _T, _K0, _K1, _K2, _K3, _U, _R0, _R1, _W, _E, _G, _A = 0, 4, 8, 12, 16, 20, 24, 28, 29, 33, 37, 38, 42, 45
#: rows of a block
BLOCK_ROWS = 46
#: doubles of the work buffer of :func:`step_lanes` and the planner's lane kernels
WORK_SIZE = BLOCK_ROWS * LANES


@njit(inline="always")
def _lane_params(theta):  # pragma: no cover - compiled
    """The kernel parameter column ``theta`` (P, 1) as the scalars the lanes read: masses, lengths, centres,
    inertias, gravity, damping and the friction terms."""
    return (theta[0, 0], theta[1, 0], theta[2, 0], theta[4, 0], theta[5, 0], theta[6, 0], theta[7, 0], theta[8, 0], theta[9, 0],
            theta[10, 0], theta[11, 0], theta[12, 0], theta[13, 0], theta[14, 0], theta[15, 0], theta[16, 0])  # fmt: skip


@njit(_nrt=False, inline="always")
def _trig8(B, q1, q2, t):  # pragma: no cover - compiled
    """Rows ``t .. t+3`` of the block ``B`` = sin, cos of row ``q1``, sin, cos of row ``q2``."""
    ok = True
    for l in range(LANES):
        B[t * LANES + l], B[(t + 1) * LANES + l] = sincos(B[q1 * LANES + l])
        B[(t + 2) * LANES + l], B[(t + 3) * LANES + l] = sincos(B[q2 * LANES + l])
        ok &= in_range(B[q1 * LANES + l]) & in_range(B[q2 * LANES + l])
    if not ok:
        for l in range(LANES):
            if not in_range(B[q1 * LANES + l]):
                B[t * LANES + l], B[(t + 1) * LANES + l] = sincos_libm(B[q1 * LANES + l])
            if not in_range(B[q2 * LANES + l]):
                B[(t + 2) * LANES + l], B[(t + 3) * LANES + l] = sincos_libm(B[q2 * LANES + l])


@njit(_nrt=False, inline="always")
def _rate8(B, x, out, driven, p):  # pragma: no cover - compiled
    """:func:`rate` of the block's lanes: states in rows ``x .. x+3``, their sines and cosines in rows ``_T`` (given),
    the inputs in row ``_U``; ``dx/dt`` into rows ``out .. out+3``. A Coulomb or Stribeck term's ``tanh`` gets a loop
    of its own (without one the viscous loop has no branch)."""
    m1, m2, l1, r1, r2, I1, I2, g, b1, b2, f1, f2, v_s, df1, df2, v_st = p
    if f1 != 0.0 or f2 != 0.0 or df1 != 0.0 or df2 != 0.0:
        for l in range(LANES):
            B[(out + 2) * LANES + l] = _friction(B[(x + 2) * LANES + l], b1, f1, v_s, df1, v_st)
            B[(out + 3) * LANES + l] = _friction(B[(x + 3) * LANES + l], b2, f2, v_s, df2, v_st)
    else:  # _friction's value without its branches: viscous only
        for l in range(LANES):
            B[(out + 2) * LANES + l] = b1 * B[(x + 2) * LANES + l]
            B[(out + 3) * LANES + l] = b2 * B[(x + 3) * LANES + l]
    for l in range(LANES):
        t1 = B[_U * LANES + l] if driven == 0 else 0.0
        t2 = B[_U * LANES + l] if driven == 1 else 0.0
        a1, a2 = _acceleration_of(B[_T * LANES + l], B[(_T + 1) * LANES + l], B[(_T + 2) * LANES + l], B[(_T + 3) * LANES + l],
                                  B[(x + 2) * LANES + l], B[(x + 3) * LANES + l], B[(out + 2) * LANES + l], B[(out + 3) * LANES + l],
                                  t1, t2, m1, m2, l1, r1, r2, I1, I2, g)  # fmt: skip
        B[out * LANES + l] = B[(x + 2) * LANES + l]
        B[(out + 1) * LANES + l] = B[(x + 3) * LANES + l]
        B[(out + 2) * LANES + l] = a1
        B[(out + 3) * LANES + l] = a2


@njit(_nrt=False, inline="always")
def _step8(B, driven, p, dt, substeps):  # pragma: no cover - compiled
    """:func:`step_map` of the block's lanes in place: rows ``_X`` with the inputs of row ``_U`` held."""
    h = dt / substeps
    for _ in range(substeps):
        _trig8(B, _X, _X + 1, _T)
        _rate8(B, _X, _K0, driven, p)
        for i in range(4):
            for l in range(LANES):
                B[(_Y + i) * LANES + l] = B[(_X + i) * LANES + l] + 0.5 * h * B[(_K0 + i) * LANES + l]
        _trig8(B, _Y, _Y + 1, _T)
        _rate8(B, _Y, _K1, driven, p)
        for i in range(4):
            for l in range(LANES):
                B[(_Y + i) * LANES + l] = B[(_X + i) * LANES + l] + 0.5 * h * B[(_K1 + i) * LANES + l]
        _trig8(B, _Y, _Y + 1, _T)
        _rate8(B, _Y, _K2, driven, p)
        for i in range(4):
            for l in range(LANES):
                B[(_Y + i) * LANES + l] = B[(_X + i) * LANES + l] + h * B[(_K2 + i) * LANES + l]
        _trig8(B, _Y, _Y + 1, _T)
        _rate8(B, _Y, _K3, driven, p)
        for i in range(4):
            for l in range(LANES):
                B[(_X + i) * LANES + l] = B[(_X + i) * LANES + l] + (h / 6.0) * (
                    B[(_K0 + i) * LANES + l] + 2.0 * B[(_K1 + i) * LANES + l] + 2.0 * B[(_K2 + i) * LANES + l] + B[(_K3 + i) * LANES + l])


@njit(_nrt=False, inline="always")
def _wrap8(B, r):  # pragma: no cover - compiled
    """Row ``r`` of the block wrapped in place: :func:`wrap_fast` in one pass where every lane is in its range, else
    :func:`wrap` lane by lane."""
    ok = True
    for l in range(LANES):
        ok &= wrap_fast(B[r * LANES + l])[1]
    if ok:
        for l in range(LANES):
            B[r * LANES + l] = wrap_fast(B[r * LANES + l])[0]
    else:
        for l in range(LANES):
            B[r * LANES + l] = wrap(B[r * LANES + l])


@njit(_nrt=False, inline="always")
def _pump8(B, E_up, driven, p, u_max):  # pragma: no cover - compiled
    """:func:`pumping_input` of the block's lanes (states rows ``_X``, gains rows ``_G``) into row ``_U``."""
    m1, m2, l1, r1, r2, I1, I2, g = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]
    _trig8(B, _X, _X + 1, _T)
    for l in range(LANES):
        B[_U * LANES + l] = 0.0
    _rate8(B, _X, _R0, driven, p)
    for l in range(LANES):
        B[_U * LANES + l] = 1.0
    _rate8(B, _X, _R1, driven, p)
    for l in range(LANES):
        B[_W * LANES + l] = B[(_X + 1) * LANES + l] if driven == 1 else B[_X * LANES + l] - 0.5 * np.pi
    _wrap8(B, _W)
    for l in range(LANES):
        q1, q2, v1, v2 = B[_X * LANES + l], B[(_X + 1) * LANES + l], B[(_X + 2) * LANES + l], B[(_X + 3) * LANES + l]
        E_err = _energy_of(B[_T * LANES + l], B[(_T + 1) * LANES + l], B[(_T + 2) * LANES + l], B[(_T + 3) * LANES + l], v1, v2,
                           m1, m2, l1, r1, r2, I1, I2, g) - E_up  # fmt: skip
        k_q, k_v, k_E, w = B[_G * LANES + l], B[(_G + 1) * LANES + l], B[(_G + 2) * LANES + l], B[_W * LANES + l]
        if driven == 1:  # acrobot
            y = -k_q * w - k_v * v2 + k_E * E_err * v1
            a0, a1 = B[(_R0 + 3) * LANES + l], B[(_R1 + 3) * LANES + l]
        else:  # pendubot
            y = -k_q * w - k_v * v1 - k_E * E_err * v1
            a0, a1 = B[(_R0 + 2) * LANES + l], B[(_R1 + 2) * LANES + l]
        B[_U * LANES + l] = min(max((y - a0) / (a1 - a0), -u_max), u_max)


@njit(_nrt=False)
def step_lanes(X, u, driven, theta, dt, substeps, B, L):  # pragma: no cover - compiled
    """:func:`step_map` of the columns ``:L`` of ``X`` (4, >= L) in place, inputs ``u`` (>= L,) held, :data:`LANES` at a
    time in the buffer ``B`` (:data:`WORK_SIZE`,)."""
    p = _lane_params(theta)
    for b0 in range(0, L, LANES):
        n = min(LANES, L - b0)
        for l in range(LANES):
            j = b0 + min(l, n - 1)  # a short block repeats its last state
            for i in range(4):
                B[(_X + i) * LANES + l] = X[i, j]
            B[_U * LANES + l] = u[j]
        _step8(B, driven, p, dt, substeps)
        for l in range(n):
            for i in range(4):
                X[i, b0 + l] = B[(_X + i) * LANES + l]


@njit
def rollout_lanes(x0, U, Xref, kff, K, alphas, u_max, driven, theta, dt, substeps, X, Un, ok):  # pragma: no cover - compiled
    """:func:`_rollout` for every step length of ``alphas`` (A <= :data:`LANES`) at once, a lane each: writes ``X``
    (A, H+1, 4), ``Un`` (A, H) and ``ok`` (A,): whether the lane's states stayed finite (a lane that stops being
    finite is computed on, and its trajectory is not to be used)."""
    if alphas.shape[0] > LANES:
        raise ValueError("rollout_lanes: more step lengths than lanes")
    _rollout8(x0, U, Xref, kff, K, alphas, u_max, driven, theta, dt, substeps, X, Un, ok, np.empty(WORK_SIZE))


@njit(_nrt=False)
def _rollout8(x0, U, Xref, kff, K, alphas, u_max, driven, theta, dt, substeps, X, Un, ok, B):  # pragma: no cover - compiled
    """:func:`rollout_lanes` in the buffer ``B`` (:data:`WORK_SIZE`,)."""
    A, H = alphas.shape[0], U.shape[0]
    p = _lane_params(theta)
    for l in range(LANES):
        B[_A * LANES + l] = alphas[min(l, A - 1)]  # spare lanes repeat the last step length
        for i in range(4):
            B[(_X + i) * LANES + l] = x0[i]
    for a in range(A):
        ok[a] = True
        for i in range(4):
            X[a, 0, i] = x0[i]
    for k in range(H):
        r0, r1, r2, r3 = Xref[k, 0], Xref[k, 1], Xref[k, 2], Xref[k, 3]
        for l in range(LANES):  # the error to the reference, in the stage-state rows (free before the step)
            B[_Y * LANES + l] = B[_X * LANES + l] - r0
            B[(_Y + 1) * LANES + l] = B[(_X + 1) * LANES + l] - r1
            B[(_Y + 2) * LANES + l] = B[(_X + 2) * LANES + l] - r2
            B[(_Y + 3) * LANES + l] = B[(_X + 3) * LANES + l] - r3
        _wrap8(B, _Y)
        _wrap8(B, _Y + 1)
        Uk, fk, K0, K1, K2, K3 = U[k], kff[k], K[k, 0], K[k, 1], K[k, 2], K[k, 3]
        for l in range(LANES):
            v = Uk + B[_A * LANES + l] * fk + dot4(K0, K1, K2, K3, B[_Y * LANES + l], B[(_Y + 1) * LANES + l], B[(_Y + 2) * LANES + l],
                                                    B[(_Y + 3) * LANES + l])  # fmt: skip
            B[_U * LANES + l] = min(max(v, -u_max), u_max)
        _step8(B, driven, p, dt, substeps)
        alive = False
        for a in range(A):
            Un[a, k] = B[_U * LANES + a]
            for i in range(4):
                X[a, k + 1, i] = B[(_X + i) * LANES + a]
            ok[a] = ok[a] and np.isfinite(X[a, k + 1, 0]) and np.isfinite(X[a, k + 1, 1]) and np.isfinite(X[a, k + 1, 2]) and np.isfinite(
                X[a, k + 1, 3])
            alive |= ok[a]
        if not alive:
            return


@njit
def pumping_input(x, k_q, k_v, k_E, E_up, driven, theta, u_max):  # pragma: no cover - compiled
    """The energy-pumping law of :class:`controllers.swingup.SwingUpLQR` (its module docstring), clipped to
    ``u_max``, at the state ``x`` (4,): one lane of the planner's blocks. The driven joint's acceleration is affine
    in ``u``, so the partial feedback linearization's input is ``(y - a(0)) / (a(1) - a(0))``, from two
    forward-dynamics calls (no mass matrix needed)."""
    B = np.empty(WORK_SIZE)
    for l in range(LANES):
        for i in range(4):
            B[(_X + i) * LANES + l] = x[i]
        B[_G * LANES + l], B[(_G + 1) * LANES + l], B[(_G + 2) * LANES + l] = k_q, k_v, k_E
    _pump8(B, E_up, driven, _lane_params(theta), u_max)
    return B[_U * LANES]


@njit(_nrt=False)
def _pump_block(B, E_up, u_max, driven, theta, dt, substeps, steps, U, search, goal, S, patience, best, when, alive):  # pragma: no cover - compiled
    """The pumping law for ``steps`` control steps from the block's states (rows ``_X``) with its gains (rows ``_G``):
    writes the inputs of lane 0 into ``U`` (when its length is ``steps``) and, where ``search``, per lane the smallest
    weighted cost-to-go (:func:`pumping_search`) into ``best`` and its step into ``when`` (``alive`` all True on entry)."""
    p = _lane_params(theta)
    for l in range(LANES):
        best[l], when[l] = np.inf, 0
    for k in range(steps):
        _pump8(B, E_up, driven, p, u_max)
        if U.shape[0] == steps:
            U[k] = B[_U * LANES]
        _step8(B, driven, p, dt, substeps)
        if not search:
            continue
        for l in range(LANES):
            for i in range(4):
                B[(_E + i) * LANES + l] = B[(_X + i) * LANES + l] - goal[i]
        _wrap8(B, _E)
        _wrap8(B, _E + 1)
        weight = np.exp(k / patience)
        for l in range(LANES):
            alive[l] = alive[l] and np.isfinite(B[_X * LANES + l]) and np.isfinite(B[(_X + 1) * LANES + l]) and np.isfinite(
                B[(_X + 2) * LANES + l]) and np.isfinite(B[(_X + 3) * LANES + l])
            c = 0.0
            for i in range(4):
                for j in range(4):
                    c += B[(_E + i) * LANES + l] * S[i, j] * B[(_E + j) * LANES + l]
            c *= weight
            if alive[l] and c < best[l]:
                best[l], when[l] = c, k


@njit
def pumping_search(x0, gains, E_up, goal, S, u_max, driven, theta, dt, substeps, steps, patience):  # pragma: no cover - compiled
    """Step 1 (module docstring): the row of ``gains`` (G, 3: ``k_q, k_v, k_E``) whose rollout from ``x0``
    comes closest to upright within ``steps`` control steps, by the cost-to-go ``dx^T S dx`` weighted by
    ``exp(k / patience)`` at step ``k`` (an approach ``e`` times as far is as good ``patience`` steps sooner); a
    rollout counts up to its last finite state. The rows are lanes, :data:`LANES` at a time (:func:`_pump_block`);
    ties go to the first row, and within a row to the first step. Returns ``(row, step, weighted cost)``: the
    chosen state is reached after ``step + 1`` inputs."""
    G = gains.shape[0]
    B = np.empty(WORK_SIZE)
    best, when, alive = np.empty(LANES), np.empty(LANES, np.int64), np.empty(LANES, np.bool_)
    bests, whens = np.full(G, np.inf), np.zeros(G, np.int64)
    for b0 in range(0, G, LANES):
        n = min(LANES, G - b0)
        for l in range(LANES):
            j = b0 + min(l, n - 1)  # a short block repeats its last row
            for i in range(4):
                B[(_X + i) * LANES + l] = x0[i]
            B[_G * LANES + l], B[(_G + 1) * LANES + l], B[(_G + 2) * LANES + l] = gains[j, 0], gains[j, 1], gains[j, 2]
            alive[l] = True
        _pump_block(B, E_up, u_max, driven, theta, dt, substeps, steps, np.empty(0), True, goal, S, patience, best, when, alive)
        for l in range(n):
            bests[b0 + l], whens[b0 + l] = best[l], when[l]
    row = 0
    for g in range(1, G):
        if bests[g] < bests[row]:
            row = g
    return row, whens[row], bests[row]


@njit
def pumping_rollout(x0, k_q, k_v, k_E, E_up, u_max, driven, theta, dt, substeps, U):  # pragma: no cover - compiled
    """The pumping law's inputs ``U`` (H,) from ``x0``, written in place: lane 0 of a block (the bits of that row's
    lane in :func:`pumping_search`)."""
    B = np.empty(WORK_SIZE)
    for l in range(LANES):
        for i in range(4):
            B[(_X + i) * LANES + l] = x0[i]
        B[_G * LANES + l], B[(_G + 1) * LANES + l], B[(_G + 2) * LANES + l] = k_q, k_v, k_E
    _pump_block(B, E_up, u_max, driven, theta, dt, substeps, U.shape[0], U, False, np.zeros(4), np.zeros((4, 4)), 1.0, np.empty(LANES),
                np.empty(LANES, np.int64), np.ones(LANES, np.bool_))  # fmt: skip


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
    _jacobians8(X, U, driven, theta, dt, substeps, A, b, np.empty(WORK_SIZE))


@njit(_nrt=False)
def _jacobians8(X, U, driven, theta, dt, substeps, A, b, B):  # pragma: no cover - compiled
    """:func:`jacobians` in the buffer ``B`` (:data:`WORK_SIZE`,)."""
    eps = 1e-7
    H = U.shape[0]
    p = _lane_params(theta)
    for k0 in range(0, H, LANES):
        n = min(LANES, H - k0)
        for j in range(5):
            for l in range(LANES):
                k = k0 + min(l, n - 1)  # a short block repeats its last step
                B[_X * LANES + l] = X[k, 0] + (eps if j == 0 else 0.0)
                B[(_X + 1) * LANES + l] = X[k, 1] + (eps if j == 1 else 0.0)
                B[(_X + 2) * LANES + l] = X[k, 2] + (eps if j == 2 else 0.0)
                B[(_X + 3) * LANES + l] = X[k, 3] + (eps if j == 3 else 0.0)
                B[_U * LANES + l] = U[k] + (eps if j == 4 else 0.0)
            _step8(B, driven, p, dt, substeps)
            for l in range(n):
                k = k0 + l
                for i in range(4):
                    d = (B[(_X + i) * LANES + l] - X[k + 1, i]) / eps
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
def ilqr(x0, U, X_ref, K_ref, goal, w_u, W, S_T, u_max, driven, theta, dt, substeps, iterations, alphas):  # pragma: no cover - compiled
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
    """Steps 1-3 (module docstring) from ``x0`` within ``steps`` control steps, the plan's inputs within
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
    X, J, A, b, current = ilqr(x0, U, X_ref, K_ref, goal, w_u, W, P_T, u_plan, driven, theta, dt, substeps, iterations, alphas)
    if not np.isfinite(J):
        return 0, np.inf
    U_out[:H] = U
    X_out[: H + 1] = X
    # the last iteration's Jacobians where they are along the result (its line search found nothing lower)
    K_out[:H] = riccati_gains(A, b, Q, R, S, dt) if current else tvlqr(X, U, Q, R, S, driven, theta, dt, substeps)
    return H, np.abs(wrapped(X[H], goal)).max()


@njit
def lqr_catches(x0, K, goal, u_max, driven, theta, dt, substeps, steps, tol):  # pragma: no cover - compiled
    """Whether the saturated LQR ``u = clip(-K dx)`` brings ``x0`` within ``tol`` of upright (largest wrapped entry
    [rad, rad/s]) and keeps it there for the last tenth of ``steps`` control steps, simulated on the map: one point of
    the LQR's region of attraction under the torque limit, by simulation."""
    x0_, x1, x2, x3 = x0[0], x0[1], x0[2], x0[3]
    hold = max(1, steps // 10)
    for k in range(steps):
        d0, d1, d2, d3 = error4(x0_, x1, x2, x3, goal[0], goal[1], goal[2], goal[3])
        if k >= steps - hold and max(abs(d0), abs(d1), abs(d2), abs(d3)) > tol:
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
        if not (np.isfinite(P_pred).all() and np.isfinite(x0) and np.isfinite(x1) and np.isfinite(x2) and np.isfinite(x3)):
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
