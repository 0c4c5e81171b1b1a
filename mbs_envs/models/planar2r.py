"""Scene 1: the planar 2R manipulator (double pendulum), docs/physics.md §3.

``q = (th1, th2)``: ``th1`` angle of link 1 from the fixed +x axis
(counter-clockwise), ``th2`` angle of link 2 relative to link 1. Gravity acts
along -y. Both joints are driven (``B = I``) unless ``driven`` selects one:
``Planar2R(driven=(1,))`` is the acrobot (elbow only), ``driven=(0,)`` the pendubot.
"""

from __future__ import annotations

import dataclasses
import sys

from ..dynamics.jit import njit
import numpy as np

from ..dynamics import compiled as _compiled
from ..dynamics.compiled import rk_run
from ..dynamics.trig import sincos_checked, sincos_rows
from .base import Model, Params, as_vector, friction_law, param, smoothed_friction, stribeck_law


@dataclasses.dataclass(frozen=True)
class Planar2RParams(Params):
    """Parameters of :class:`Planar2R`; defaults are two uniform 1 kg, 1 m rods.

    ``r_i`` is the distance of link i's centre of mass from its proximal joint,
    ``I_i`` its moment of inertia about the centre of mass (z axis).
    """

    m1: float = param(1.0, "positive", "kg", "mass of link 1")
    m2: float = param(1.0, "positive", "kg", "mass of link 2")
    l1: float = param(1.0, "positive", "m", "length of link 1")
    l2: float = param(1.0, "positive", "m", "length of link 2")
    r1: float = param(0.5, "nonnegative", "m", "joint 1 to centre of mass of link 1")
    r2: float = param(0.5, "nonnegative", "m", "joint 2 to centre of mass of link 2")
    I1: float = param(1.0 / 12.0, "nonnegative", "kg m^2", "inertia of link 1 about its COM")
    I2: float = param(1.0 / 12.0, "nonnegative", "kg m^2", "inertia of link 2 about its COM")
    g: float = param(9.81, "finite", "m/s^2", "gravitational acceleration along -y")
    b1: float = param(0.0, "nonnegative", "N m s/rad", "viscous friction, joint 1")
    b2: float = param(0.0, "nonnegative", "N m s/rad", "viscous friction, joint 2")
    f1: float = param(0.0, "nonnegative", "N m", "smoothed Coulomb friction, joint 1")
    f2: float = param(0.0, "nonnegative", "N m", "smoothed Coulomb friction, joint 2")
    v_s: float = param(0.01, "positive", "rad/s", "Coulomb smoothing speed")
    df1: float = param(0.0, "nonnegative", "N m", "Stribeck excess (static above Coulomb friction), joint 1")
    df2: float = param(0.0, "nonnegative", "N m", "Stribeck excess (static above Coulomb friction), joint 2")
    v_st: float = param(0.1, "positive", "rad/s", "Stribeck speed")

    def _check(self) -> None:
        # M is positive definite for all q iff each link has rotational inertia
        # about its joint: I_i + m_i r_i^2 > 0 (see the determinant of M).
        for i in (1, 2):
            I, m, r = (getattr(self, f"{k}{i}") for k in ("I", "m", "r"))
            if not I + m * r**2 > 0:
                raise ValueError(
                    f"parameters I{i}, r{i}: link {i} has no inertia about its joint (I{i} + m{i} r{i}^2 = 0)"
                )


# ---------------------------------------------------------------------------
# The equations, written once. Each formula takes floats or broadcasting
# arrays: the numpy methods of :class:`Planar2R` call them with batches, the
# compiled kernels below with one member's floats.
# ---------------------------------------------------------------------------


def mass_entries(c2, m1, m2, l1, r1, r2, I1, I2):
    """Entries ``(M11, M12, M22)`` of ``M(q)`` [kg m^2] from ``c2 = cos th2``."""
    m22 = I2 + m2 * r2**2
    m12 = m22 + m2 * l1 * r2 * c2
    m11 = I1 + m1 * r1**2 + I2 + m2 * (l1**2 + r2**2) + 2 * m2 * l1 * r2 * c2
    return m11, m12, m22


def coriolis_entries(s2, d1, d2, m2, l1, r2):
    """``C(q, v) v`` [N m] from ``s2 = sin th2`` and the joint rates ``d1, d2``."""
    h = m2 * l1 * r2 * s2
    return -h * (2 * d1 * d2 + d2**2), h * d1**2


def gravity_entries(c1, c12, m1, m2, l1, r1, r2, g):
    """``G(q)`` [N m] from ``c1 = cos th1`` and ``c12 = cos(th1 + th2)``."""
    g12 = m2 * r2 * g * c12
    return (m1 * r1 + m2 * l1) * g * c1 + g12, g12


def potential_entry(s1, s12, m1, m2, l1, r1, r2, g):
    """``V(q)`` [J] from ``s1 = sin th1`` and ``s12 = sin(th1 + th2)``."""
    return g * (m1 * r1 * s1 + m2 * (l1 * s1 + r2 * s12))


_mass_entries = njit(mass_entries)
_coriolis_entries = njit(coriolis_entries)
_gravity_entries = njit(gravity_entries)
_potential_entry = njit(potential_entry)
_friction_law = njit(friction_law)
_stribeck_law = njit(stribeck_law)


@njit
def _friction(v, b, f, v_s, df, v_st):  # pragma: no cover - compiled
    """:func:`friction_law` for one joint, skipping the costly tanh when ``f = 0`` (as the numpy path),
    plus :func:`stribeck_law` where ``df != 0`` (:func:`~mbs_envs.models.base.smoothed_friction`)."""
    F = _friction_law(v, b, f, v_s) if f != 0.0 else b * v
    return F + _stribeck_law(v, df, v_st, v_s) if df != 0.0 else F


@njit(inline="always")
def _acceleration_of(
    s1, c1, s2, c2, d1, d2, F1, F2, tau1, tau2, m1, m2, l1, r1, r2, I1, I2, g
):  # pragma: no cover - compiled
    """:func:`_acceleration` from the parameters as scalars (loops over many states at one parameter set keep them
    in registers and vectorize: :mod:`controllers.trajectory`'s lanes)."""
    m11, m12, m22 = _mass_entries(c2, m1, m2, l1, r1, r2, I1, I2)
    h1, h2 = _coriolis_entries(s2, d1, d2, m2, l1, r2)
    g1, g2 = _gravity_entries(c1, c1 * c2 - s1 * s2, m1, m2, l1, r1, r2, g)
    rhs1 = tau1 - (h1 + g1 + F1)
    rhs2 = tau2 - (h2 + g2 + F2)
    det = m11 * m22 - m12 * m12
    return (m22 * rhs1 - m12 * rhs2) / det, (m11 * rhs2 - m12 * rhs1) / det


@njit
def _acceleration(s1, c1, s2, c2, d1, d2, F1, F2, tau1, tau2, theta, b):  # pragma: no cover - compiled
    """Forward dynamics ``a = M^-1 (tau - C v - G - F)`` of member ``b`` from the sines and
    cosines of its joint angles and its friction torques ``F``; the 2 x 2 system by
    Cramer's rule (``det M >= (I1 + m1 r1^2)(I2 + m2 r2^2) > 0``). Returns ``(a1, a2)`` [rad/s^2]."""
    return _acceleration_of(s1, c1, s2, c2, d1, d2, F1, F2, tau1, tau2, theta[0, b], theta[1, b], theta[2, b], theta[4, b],
                            theta[5, b], theta[6, b], theta[7, b], theta[8, b])  # fmt: skip


@njit
def _trig(q):  # pragma: no cover - compiled
    """``(s1, c1, s2, c2)`` of the joint angles ``q`` (2, B) as a (4, B) array."""
    return sincos_rows(q, 0, 2)


@njit
def acceleration_kernel(q, v, tau, theta, a):  # pragma: no cover - compiled
    """Forward dynamics of a batch in columns (the kernel convention of :mod:`mbs_envs.dynamics.compiled`).

    Parameters
    ----------
    q, v : ndarray, shape (2, B)
        Joint angles [rad] and rates [rad/s].
    tau : ndarray, shape (2, B)
        Joint torques [N m].
    theta : ndarray, shape (14, B)
        The parameters in :class:`Planar2RParams` field order (:meth:`Planar2R.kernel_params`).
    a : ndarray, shape (2, B)
        Written: accelerations [rad/s^2].
    """
    if q.shape[1] == 1:  # one member (a single env): straight-line scalar code, faster than the batch loop
        s1, c1 = sincos_checked(q[0, 0])
        s2, c2 = sincos_checked(q[1, 0])
        F1 = _friction(v[0, 0], theta[9, 0], theta[11, 0], theta[13, 0], theta[14, 0], theta[16, 0])
        F2 = _friction(v[1, 0], theta[10, 0], theta[12, 0], theta[13, 0], theta[15, 0], theta[16, 0])
        a[0, 0], a[1, 0] = _acceleration(s1, c1, s2, c2, v[0, 0], v[1, 0], F1, F2, tau[0, 0], tau[1, 0], theta, 0)
        return
    T = _trig(q)
    F = np.empty((2, q.shape[1]))  # a pass of its own: the tanh call would keep the main loop scalar
    for b in range(q.shape[1]):
        F[0, b] = _friction(v[0, b], theta[9, b], theta[11, b], theta[13, b], theta[14, b], theta[16, b])
        F[1, b] = _friction(v[1, b], theta[10, b], theta[12, b], theta[13, b], theta[15, b], theta[16, b])
    for b in range(q.shape[1]):
        a[0, b], a[1, b] = _acceleration(
            T[0, b], T[1, b], T[2, b], T[3, b], v[0, b], v[1, b], F[0, b], F[1, b], tau[0, b], tau[1, b], theta, b
        )


@njit(inline="always")
def _energy_of(s1, c1, s2, c2, d1, d2, m1, m2, l1, r1, r2, I1, I2, g):  # pragma: no cover - compiled
    """:func:`_energy` from the parameters as scalars (as :func:`_acceleration_of`)."""
    m11, m12, m22 = _mass_entries(c2, m1, m2, l1, r1, r2, I1, I2)
    T = 0.5 * (m11 * d1 * d1 + 2.0 * m12 * d1 * d2 + m22 * d2 * d2)
    return T + _potential_entry(s1, s1 * c2 + c1 * s2, m1, m2, l1, r1, r2, g)


@njit
def _energy(s1, c1, s2, c2, d1, d2, theta, b):  # pragma: no cover - compiled
    """Mechanical energy ``v^T M v / 2 + V`` [J] of member ``b`` from the sines and cosines of its angles."""
    return _energy_of(s1, c1, s2, c2, d1, d2, theta[0, b], theta[1, b], theta[2, b], theta[4, b], theta[5, b], theta[6, b],
                      theta[7, b], theta[8, b])  # fmt: skip


@njit
def energy_kernel(q, v, theta, E):  # pragma: no cover - compiled
    """Mechanical energy [J] of a batch in columns: ``q, v`` (2, B), ``theta`` (14, B); writes ``E`` (B,)."""
    T = _trig(q)
    for b in range(q.shape[1]):
        E[b] = _energy(T[0, b], T[1, b], T[2, b], T[3, b], v[0, b], v[1, b], theta, b)


#: this module: a kernel passed on as a module attribute is a compile-time constant (a bare
#: global would be embedded as a Python object pointer, which numba cannot cache)
_this = sys.modules[__name__]


@njit
def advance_kernel(theta, stepper, q, v, tau):  # pragma: no cover - compiled
    """:func:`mbs_envs.dynamics.compiled.rk_run` with this model's :func:`acceleration_kernel` (cached on disk)."""
    rk_run(_this.acceleration_kernel, _compiled.no_projection, theta, stepper, q, v, tau)


def driven_joints(driven, n: int) -> tuple[int, ...]:
    """The driven joints as a sorted tuple of distinct indices in ``[0, n)``.

    Raises
    ------
    ValueError
        Naming ``driven`` if it is empty, repeats a joint or names one that does not exist.
    """
    try:
        joints = tuple(int(j) for j in np.atleast_1d(np.asarray(driven)) if float(j) == int(j))
    except (TypeError, ValueError):
        joints = ()
    if (
        not joints
        or len(joints) != np.size(driven)
        or len(set(joints)) != len(joints)
        or not all(0 <= j < n for j in joints)
    ):
        raise ValueError(f"driven must be distinct joint indices in [0, {n}), at least one, got {driven!r}")
    return tuple(sorted(joints))


class Planar2R(Model):
    """Planar two-link manipulator; equations as docs/physics.md §3.

    With ``M11 = I1 + I2 + m1 r1^2 + m2 (l1^2 + r2^2 + 2 l1 r2 c2)``,
    ``M12 = I2 + m2 (r2^2 + l1 r2 c2)``, ``M22 = I2 + m2 r2^2``,
    ``C v = (-m2 l1 r2 s2 (2 dth1 dth2 + dth2^2), m2 l1 r2 s2 dth1^2)``,
    ``G = ((m1 r1 + m2 l1) g c1 + m2 r2 g c12, m2 r2 g c12)``.
    """

    Params = Planar2RParams
    batched_params = True
    nq = 2
    nv = 2
    nu = 2  # per instance: len(driven)

    def __init__(self, params=None, driven=(0, 1), **overrides):
        super().__init__(params, **overrides)
        self.driven = driven_joints(driven, self.nq)
        self.nu = len(self.driven)

    @property
    def actuation(self) -> np.ndarray:
        """``B`` (2 x nu): the columns of the identity of the driven joints (``B = I`` when both are)."""
        return np.eye(2)[:, list(self.driven)]

    def __eq__(self, other: object) -> bool:
        return super().__eq__(other) and self.driven == other.driven

    def __hash__(self) -> int:
        return hash((super().__hash__(), self.driven))

    def __repr__(self) -> str:
        text = super().__repr__()
        return (
            text if self.driven == (0, 1) else text[:-1] + (", " if text[-2] != "(" else "") + f"driven={self.driven})"
        )

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``M(q)``, shape ``(..., 2, 2)`` [kg m^2]."""
        p = self.params
        q = as_vector(q, 2, "q")
        m11, m12, m22 = mass_entries(np.cos(q[..., 1]), p.m1, p.m2, p.l1, p.r1, p.r2, p.I1, p.I2)
        M = np.empty(q.shape[:-1] + (2, 2))
        M[..., 0, 0] = m11
        M[..., 0, 1] = m12
        M[..., 1, 0] = m12
        M[..., 1, 1] = m22
        return M

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C(q, v) v``, shape ``(..., 2)`` [N m]."""
        p = self.params
        q = as_vector(q, 2, "q")
        v = as_vector(v, 2, "v")
        c = coriolis_entries(np.sin(q[..., 1]), v[..., 0], v[..., 1], p.m2, p.l1, p.r2)
        return np.stack(np.broadcast_arrays(*c), axis=-1)

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """``G(q)``, shape ``(..., 2)`` [N m]."""
        p = self.params
        q = as_vector(q, 2, "q")
        G = gravity_entries(np.cos(q[..., 0]), np.cos(q[..., 0] + q[..., 1]), p.m1, p.m2, p.l1, p.r1, p.r2, p.g)
        return np.stack(np.broadcast_arrays(*G), axis=-1)

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        """``V = m1 g r1 s1 + m2 g (l1 s1 + r2 s12)`` [J], shape ``(...)``."""
        p = self.params
        q = as_vector(q, 2, "q")
        return potential_entry(np.sin(q[..., 0]), np.sin(q[..., 0] + q[..., 1]), p.m1, p.m2, p.l1, p.r1, p.r2, p.g)

    def friction(self, v: np.ndarray) -> np.ndarray:
        """``F_i = b_i v_i + f_i tanh(v_i / v_s)`` (+ the Stribeck peak where ``df_i > 0``), shape ``(..., 2)`` [N m]."""
        p = self.params
        v = as_vector(v, 2, "v")
        if all(isinstance(x, float) for x in (p.b1, p.b2, p.f1, p.f2, p.df1, p.df2)):
            b, f, df = np.array([p.b1, p.b2]), np.array([p.f1, p.f2]), np.array([p.df1, p.df2])
        else:  # per-member parameters (domain randomization): shape (B, 2)
            b = np.stack(np.broadcast_arrays(p.b1, p.b2), axis=-1)
            f = np.stack(np.broadcast_arrays(p.f1, p.f2), axis=-1)
            df = np.stack(np.broadcast_arrays(p.df1, p.df2), axis=-1)
        return smoothed_friction(v, b, f, np.asarray(p.v_s)[..., None], df, np.asarray(p.v_st)[..., None])

    # -- compiled path (see :mod:`mbs_envs.dynamics.compiled`) -----------------------------

    kernels = (acceleration_kernel, energy_kernel)
    advance_kernel = staticmethod(advance_kernel)

    def joint_positions(self, q: np.ndarray) -> np.ndarray:
        """Positions of the base, the elbow and the tip in the plane [m].

        Returns
        -------
        ndarray, shape (..., 3, 2)
        """
        p = self.params
        q = as_vector(q, 2, "q")
        th1 = q[..., 0]
        th12 = th1 + q[..., 1]
        elbow = np.stack([p.l1 * np.cos(th1), p.l1 * np.sin(th1)], axis=-1)
        tip = elbow + np.stack([p.l2 * np.cos(th12), p.l2 * np.sin(th12)], axis=-1)
        return np.stack([np.zeros_like(elbow), elbow, tip], axis=-2)
