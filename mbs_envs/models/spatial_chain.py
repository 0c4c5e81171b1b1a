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
from .base import Params, as_vector, param
from .serial_chain import RecursiveChain, link_count
from .spatial_recursions import (
    work_arrays,
    work_size,
    _work_views,
    frames_into,
    rnea_into,
    crba_into,
    aba_into,
    energy_member,
)
from .spatial_tiles import aba_tiles, TILE

#: the longest spatial chain the model takes (the lecture's proteins: up to 500 bodies)
MAX_SPATIAL_LINKS = 10_000


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
