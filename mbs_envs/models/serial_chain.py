"""Scene 4: the planar N-link serial chain, with O(N) recursive algorithms (docs/physics.md §6).

``q_i`` is the angle of link i relative to link i-1 (``q_1`` from +x); every
joint is a driven revolute about z (``B = I``). Link i: mass ``m_i``, length
``l_i``, centre of mass at ``r_i`` along the link, inertia ``I_i`` about it;
optional joint ``armature_i`` (a drive's rotor inertia reflected through its
gear, as in Pinocchio and MuJoCo: ``M -> M + diag(armature)``, default 0).
With N = 2 this is :class:`~mbs_envs.models.planar2r.Planar2R`.

Algorithms (all in world coordinates; ``th_i = q_1 + ... + q_i`` absolute angles):

- inverse dynamics by the recursive Newton-Euler algorithm (:meth:`SerialChain.rnea`).
  In the plane its forward pass (velocities, accelerations) and backward pass
  (forces, moments) are prefix and suffix sums, so it is vectorized over the
  links as well as the batch: O(N) work, no Python loop;
- forward dynamics by the articulated-body algorithm (:meth:`SerialChain.aba`),
  a sequential recursion, compiled with numba (:func:`_aba_kernel`);
- the mass matrix by the composite-rigid-body algorithm (:meth:`SerialChain.mass_matrix`),
  ``M_ij = sum_{k >= max(i,j)} [I_k + m_k (c_k - p_i) . (c_k - p_j)]`` from suffix sums,
  the cross-check (``forward_dynamics_crba``: Cholesky of ``M``).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..dynamics.compiled import batch_theta, columns_of
from .base import Model, Params, as_vector, param, smoothed_friction
from .serial_recursions import _aba_kernel, _energy_rows, acceleration_kernel, energy_kernel, advance_kernel


#: the longest chain the model takes (its O(N) algorithms; ``mass_matrix`` is N x N)
MAX_LINKS = 100_000


def link_count(n: Any, upper: int, name: str = "n_links") -> int:
    """``n`` as an int in ``[1, upper]`` (integer-valued floats accepted); ``ValueError`` naming ``name`` otherwise."""
    integral = isinstance(n, (int, np.integer)) or (isinstance(n, (float, np.floating)) and float(n).is_integer())
    if isinstance(n, (bool, np.bool_)) or not integral or not 1 <= n <= upper:
        raise ValueError(f"{name} must be an integer in [1, {upper}], got {n!r}")
    return int(n)


@dataclasses.dataclass(frozen=True)
class SerialChainParams(Params):
    """Parameters of :class:`SerialChain`: per-link arrays of length ``n_links``
    (scalars are broadcast). Defaults: every link a uniform rod of
    ``m = 1 / n_links`` kg and ``l = 1 / n_links`` m (``r = l / 2``,
    ``I = m l^2 / 12``), so the whole chain is a 1 kg, 1 m rope whatever N.
    """

    n_links: int = param(2, "positive", "", "number of links")
    m: Any = param(None, "positive", "kg", "link masses")
    l: Any = param(None, "positive", "m", "link lengths")  # noqa: E741
    r: Any = param(None, "nonnegative", "m", "joint to centre of mass, along the link")
    I: Any = param(None, "nonnegative", "kg m^2", "link inertias about the centre of mass")  # noqa: E741
    g: float = param(9.81, "finite", "m/s^2", "gravity along -y")
    armature: Any = param(0.0, "nonnegative", "kg m^2", "reflected rotor inertia at each joint (adds to diag M)")
    b: Any = param(0.0, "nonnegative", "N m s/rad", "viscous joint friction")
    f: Any = param(0.0, "nonnegative", "N m", "smoothed Coulomb joint friction")
    v_s: float = param(0.01, "positive", "rad/s", "Coulomb smoothing speed")

    def __post_init__(self) -> None:
        n = link_count(self.n_links, MAX_LINKS, "parameter 'n_links'")
        object.__setattr__(self, "n_links", n)
        defaults = {"m": 1.0 / n, "l": 1.0 / n}
        for name in ("m", "l", "r", "I", "armature", "b", "f"):
            value = getattr(self, name)
            if value is None:
                value = defaults.get(name)
            if value is None and name == "r":
                value = 0.5 * np.asarray(self.l if self.l is not None else defaults["l"], float)
            if value is None and name == "I":
                mm = np.asarray(self.m if self.m is not None else defaults["m"], float)
                ll = np.asarray(self.l if self.l is not None else defaults["l"], float)
                value = mm * ll**2 / 12
            try:
                arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
            except (TypeError, ValueError):
                raise ValueError(
                    f"parameter {name!r} must be a scalar or have length n_links = {n}, got {value!r}"
                ) from None
            object.__setattr__(self, name, arr)
        super().__post_init__()
        object.__setattr__(self, "n_links", n)  # keep it an int

    def _check(self) -> None:
        bad = np.flatnonzero(~(self.I + self.m * self.r**2 > 0))
        if bad.size:
            raise ValueError(f"parameters I, r: link {bad[0] + 1} has no inertia about its joint")

    def replace(self, **overrides: Any) -> "SerialChainParams":
        if "n_links" in overrides:  # per-link defaults follow the new length
            unknown = sorted(set(overrides) - set(self.names()))
            if unknown:
                raise ValueError(f"unknown parameter(s) {unknown} for {type(self).__name__}")
            kept = {k: getattr(self, k) for k in ("g", "v_s")}
            return type(self)(**{**kept, **overrides})
        return super().replace(**overrides)


def _suffix_sum(x: np.ndarray, axis: int = -1) -> np.ndarray:
    """``y_i = sum_{k >= i} x_k`` along ``axis``."""
    return np.flip(np.cumsum(np.flip(x, axis), axis), axis)


class RecursiveChain(Model):
    """What every chain with O(N) recursions shares, written once: ``N`` driven revolute joints (``B = I``),
    and ``C v``, ``G``, ``h``, inverse and forward dynamics and the energies from the subclass's
    :meth:`rnea`, :meth:`aba`, :meth:`friction` and :meth:`_energies` (the planar :class:`SerialChain`
    and :class:`~mbs_envs.models.spatial_chain.SpatialChain`)."""

    nu = nv = nq = 2  # replaced per instance in __init__

    def __init__(self, params=None, **overrides):
        super().__init__(params, **overrides)
        n = self.params.n_links
        self.nq = self.nv = self.nu = n

    @property
    def n_links(self) -> int:
        return self.params.n_links

    @property
    def actuation(self) -> np.ndarray:
        return np.eye(self.n_links)

    def rnea(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, gravity: bool = True) -> np.ndarray:
        """``M a + C v (+ G)`` by the recursive Newton-Euler algorithm (the subclass's)."""
        raise NotImplementedError

    def aba(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Accelerations for joint torques ``tau`` (friction not included) by the articulated-body algorithm."""
        raise NotImplementedError

    def _energies(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(T, V)`` [J], shape ``(...)``, from the links' velocities and positions (the subclass's)."""
        raise NotImplementedError

    def coriolis(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C(q, v) v`` from RNEA with zero acceleration and no gravity."""
        v = as_vector(v, self.n_links, "v")
        return self.rnea(q, v, np.zeros_like(v), gravity=False)

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """``G(q)`` from RNEA at rest."""
        q = as_vector(q, self.n_links, "q")
        z = np.zeros(q.shape)
        return self.rnea(q, z, z)

    def bias(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``C v + G + F`` in one RNEA pass."""
        v = as_vector(v, self.n_links, "v")
        return self.rnea(q, v, np.zeros_like(v)) + self.friction(v)

    def inverse_dynamics(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Joint torques for accelerations ``a``: RNEA plus friction, O(N)."""
        v = as_vector(v, self.n_links, "v")
        return self.rnea(q, v, a) + self.friction(v)

    def forward_dynamics(self, q: np.ndarray, v: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """Accelerations by the articulated-body algorithm, O(N); friction included."""
        v = as_vector(v, self.n_links, "v")
        tau = -self.friction(v) if u is None else as_vector(u, self.n_links, "u") - self.friction(v)
        return self.aba(q, v, tau)

    def forward_dynamics_crba(self, q: np.ndarray, v: np.ndarray, u: np.ndarray | None = None) -> np.ndarray:
        """The cross-check path: ``M^-1 (u - h)`` with ``M`` by CRBA and a Cholesky solve, O(N^3)."""
        return Model.forward_dynamics(self, q, v, u)

    def energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``T + V`` [J], one pass: the subclass's compiled ``energy_kernel`` (``kernels[1]``), the compiled step's
        own (the same bits as its ``info["energy"]``; one kernel less to compile on a first reset)."""
        n = self.n_links
        q, v = np.broadcast_arrays(as_vector(q, n, "q"), as_vector(v, n, "v"))
        qc, vc = columns_of(q), columns_of(v)
        E = np.empty(qc.shape[1])
        self.kernels[1](qc, vc, batch_theta(self, qc.shape[1]), E)
        return E.reshape(q.shape[:-1])

    def kinetic_energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Kinetic energy of the links and the drives' armature [J] from the link velocities (O(N), not via ``M``)."""
        return self._energies(q, v)[0]

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        """Potential energy of gravity [J]."""
        q = as_vector(q, self.n_links, "q")
        return self._energies(q, np.zeros(q.shape[-1:]))[1]


class SerialChain(RecursiveChain):
    """Planar N-link chain, every joint driven; see the module docstring.

    Construct with ``SerialChain(n_links=N, m=..., l=..., r=..., I=..., g=...,
    b=..., f=..., v_s=...)``, per-link arrays or scalars.
    """

    Params = SerialChainParams

    # -- kinematics ---------------------------------------------------------

    def kinematics(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Absolute angles, joint positions and centres of mass (world frame).

        :func:`_member_kinematics`'s formulas in numpy over the batch, its running sums in the same
        order (``np.cumsum``), with numpy's ``sin``/``cos`` (within 1 ulp of the kernels' sincos).
        numpy, not a kernel: the env's construction sizes its drives with ``gravity`` and
        ``mass_matrix``, and a kernel here was compiled in every fresh process (its cost in
        docs/performance.md).

        Returns
        -------
        dict with ``th`` (..., N), ``p`` (..., N, 2) joint i positions (``p_1 = 0``),
        ``c`` (..., N, 2) centres of mass, ``e`` (..., N, 2) link unit vectors.
        """
        p_ = self.params
        q = as_vector(q, self.n_links, "q")
        th = np.cumsum(q, axis=-1)
        e = np.stack([np.cos(th), np.sin(th)], axis=-1)
        p = np.zeros(e.shape)
        np.cumsum(p_.l[:-1, None] * e[..., :-1, :], axis=-2, out=p[..., 1:, :])
        return {"th": th, "p": p, "c": p + p_.r[:, None] * e, "e": e}

    def joint_positions(self, q: np.ndarray) -> np.ndarray:
        """Base, joints and tip [m], shape ``(..., N + 1, 2)``."""
        k = self.kinematics(q)
        tip = k["p"][..., -1:, :] + self.params.l[-1] * k["e"][..., -1:, :]
        return np.concatenate([k["p"], tip], axis=-2)

    # -- inverse dynamics: RNEA with prefix/suffix sums ------------------------

    def rnea(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, gravity: bool = True) -> np.ndarray:
        """Joint torques ``M a + C v (+ G)`` by the recursive Newton-Euler algorithm.

        Forward pass: link rates ``w = cumsum(v)``, ``dw = cumsum(a)``; centre
        of mass accelerations from the link vectors (prefix sums over the
        joints). Backward pass: the force carried by joint i is the suffix sum
        ``F_i = sum_{k>=i} m_k (a_Ck + g e_y)``, its moment about joint i
        ``sum_{k>=i} [I_k dw_k + (c_k - p_i) x m_k (a_Ck + g e_y)]``, written
        as suffix sums too. O(N), vectorized over links and batch. Friction
        is not included (see :meth:`inverse_dynamics`).

        Returns
        -------
        tau : ndarray, shape (..., N)
        """
        p_ = self.params
        q = as_vector(q, self.n_links, "q")
        v = as_vector(v, self.n_links, "v")
        a = as_vector(a, self.n_links, "a")
        k = self.kinematics(q)
        e, p, c = k["e"], k["p"], k["c"]
        w = np.cumsum(v, axis=-1)
        dw = np.cumsum(a, axis=-1)
        n_perp = np.stack([-e[..., 1], e[..., 0]], axis=-1)
        # acceleration of a point at distance d along link j: d (dw_j n_j - w_j^2 e_j)
        link_acc = dw[..., None] * n_perp - (w**2)[..., None] * e  # per unit length
        tip_acc = np.cumsum(p_.l[:, None] * link_acc, axis=-2)  # acceleration of the tip of link i
        joint_acc = np.concatenate([np.zeros(tip_acc.shape[:-2] + (1, 2)), tip_acc[..., :-1, :]], axis=-2)
        a_c = joint_acc + p_.r[:, None] * link_acc
        if gravity:
            a_c = a_c + np.array([0.0, p_.g])
        F = p_.m[:, None] * a_c  # net force needed on each link (incl. weight support)
        F_sum = _suffix_sum(F, axis=-2)
        cross_cF = c[..., 0] * F[..., 1] - c[..., 1] * F[..., 0]
        moment = _suffix_sum(p_.I * dw + cross_cF, axis=-1)
        tau = moment - (p[..., 0] * F_sum[..., 1] - p[..., 1] * F_sum[..., 0])
        return tau + p_.armature * a

    # -- the Model interface --------------------------------------------------

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Composite-rigid-body ``M(q)``, shape ``(..., N, N)``, from suffix sums."""
        p_ = self.params
        k = self.kinematics(q)
        p, c = k["p"], k["c"]
        S0 = _suffix_sum(p_.I + p_.m * np.sum(c**2, axis=-1), axis=-1)  # (..., N)
        S1 = _suffix_sum(p_.m[:, None] * c, axis=-2)  # (..., N, 2)
        S2 = _suffix_sum(p_.m, axis=-1)  # (N,)
        n = self.n_links
        J = np.maximum.outer(np.arange(n), np.arange(n))
        pp = np.einsum("...id,...jd->...ij", p, p)
        S1J = S1[..., J, :]  # (..., N, N, 2)
        cross = np.einsum("...ijd,...id->...ij", S1J, p) + np.einsum("...ijd,...jd->...ij", S1J, p)
        return S0[..., J] - cross + S2[J] * pp + np.diag(p_.armature)

    def friction(self, v: np.ndarray) -> np.ndarray:
        p_ = self.params
        v = as_vector(v, self.n_links, "v")
        return smoothed_friction(v, p_.b, p_.f, p_.v_s)

    def aba(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Accelerations for joint torques ``tau`` (friction not included), O(N).

        The articulated-body recursion runs in the compiled :func:`_aba_kernel`,
        over the flattened batch (:meth:`shifted_forward_dynamics` with ``d = 0``).
        """
        return self.shifted_forward_dynamics(q, v, tau, np.zeros(self.n_links))

    def shifted_forward_dynamics(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, d: np.ndarray) -> np.ndarray:
        """``(M + diag(d))^-1 (tau - C v - G)`` in O(N): the articulated-body recursion with
        ``d`` added to the joint armature (which enters ``M`` the same way). See
        :meth:`mbs_envs.models.base.Model.shifted_forward_dynamics`."""
        p_ = self.params
        n = self.n_links
        q = as_vector(q, n, "q")
        v = as_vector(v, n, "v")
        tau = as_vector(tau, n, "tau")
        d = as_vector(d, n, "d")
        shape = np.broadcast_shapes(q.shape, v.shape, tau.shape, d.shape)
        flat = lambda x: np.ascontiguousarray(np.broadcast_to(x, shape).reshape(-1, n), dtype=float)  # noqa: E731
        out = _aba_kernel(
            flat(q), flat(v), p_.l, p_.r, flat(p_.m), flat(p_.I), flat(p_.armature + d), flat(tau), float(p_.g)
        )
        return out.reshape(shape)

    def _energies(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(T, V)`` [J], shape ``(...)``, by the compiled :func:`_energy_member` over the flattened batch."""
        p_ = self.params
        n = self.n_links
        q = as_vector(q, n, "q")
        v = as_vector(v, n, "v")
        shape = np.broadcast_shapes(q.shape, v.shape)
        flat = lambda x: np.ascontiguousarray(np.broadcast_to(x, shape).reshape(-1, n), dtype=float)  # noqa: E731
        T, V = _energy_rows(flat(q), flat(v), p_.l, p_.r, p_.m, p_.I, p_.armature, float(p_.g))
        return T.reshape(shape[:-1]), V.reshape(shape[:-1])

    # -- compiled path (see :mod:`mbs_envs.dynamics.compiled`) -----------------------------

    kernels = (acceleration_kernel, energy_kernel)
    advance_kernel = staticmethod(advance_kernel)
    #: the kernels take one parameter column for every member (:func:`mbs_envs.dynamics.compiled.batch_theta`)
    shared_theta = True

    def kernel_params(self) -> np.ndarray:
        """``(l, r, m, I, armature, b, f)`` per link, then ``g, v_s``: shape ``(7 N + 2,)``."""
        p_ = self.params
        return np.concatenate([p_.l, p_.r, p_.m, p_.I, p_.armature, p_.b, p_.f, [p_.g, p_.v_s]])
