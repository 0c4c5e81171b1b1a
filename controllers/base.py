"""The controller protocol: SB3's ``PolicyPredictor``."""

from __future__ import annotations

import abc
from typing import Any

import gymnasium as gym
import numpy as np

from mbs_envs import validation as check
from mbs_envs.dynamics.linearize import linearize  # noqa: F401  (re-exported: the controllers' linearizations)


def gain(value: Any, n: int, name: str) -> np.ndarray:
    """A non-negative finite gain, scalar or per coordinate, as shape ``(n,)``.

    Raises
    ------
    ValueError
        Naming the gain, if it is negative, non-finite or of the wrong length.
    """
    return check.vector(value, name, n, 0.0)


def solve_rows(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.solve`` over a batch, NaN (instead of an exception for the whole batch) for the members
    whose matrix is singular. Shapes as ``np.linalg.solve``'s: ``(..., n, n)``, ``(..., n, k)``."""
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        lead = np.broadcast_shapes(A.shape[:-2], b.shape[:-2])
        A, b = np.broadcast_to(A, lead + A.shape[-2:]), np.broadcast_to(b, lead + b.shape[-2:])
        out = np.full(lead + b.shape[-2:], np.nan, dtype=np.result_type(A, b))
        for idx in np.ndindex(out.shape[:-2]):
            try:
                out[idx] = np.linalg.solve(A[idx], b[idx])
            except np.linalg.LinAlgError:
                pass
        return out


def care(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, newton: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """The LQR gain ``K = R^-1 B^T S`` and the stabilizing solution ``S`` of the continuous
    algebraic Riccati equation ``A^T S + S A - S B R^-1 B^T S + Q = 0``, batched.

    ``S`` from the stable invariant subspace of the Hamiltonian ``[[A, -B R^-1 B^T], [-Q, -A^T]]``
    (eigenvectors ``[X1; X2]`` of its ``n`` eigenvalues with negative real part, ``S = X2 X1^-1``),
    refined by ``newton`` Newton--Kleinman steps (each a Lyapunov equation
    ``Acl^T S + S Acl = -(Q + K^T R K)``, ``Acl = A - B K``, solved through its Kronecker form): the
    same answer as ``control.lqr`` (``scipy.linalg.solve_continuous_are``) for one system, for a
    batch in one call. Where ``(A, B)`` is not stabilizable (or so close to it that a step's linear
    system is singular, or the result does not stabilize it) that member's ``K`` and ``S`` are NaN; the
    others are unaffected.

    Parameters
    ----------
    A : ndarray, shape (..., n, n)
    B : ndarray, shape (..., n, m)
    Q : ndarray, shape (n, n), symmetric positive semidefinite
    R : ndarray, shape (m, m), symmetric positive definite

    Returns
    -------
    K : ndarray, shape (..., m, n)
    S : ndarray, shape (..., n, n)
    """
    A, B = np.asarray(A, float), np.asarray(B, float)
    n = A.shape[-1]
    Rinv = np.linalg.inv(R)
    lead = np.broadcast_shapes(A.shape[:-2], B.shape[:-2])
    A, B = np.broadcast_to(A, lead + A.shape[-2:]), np.broadcast_to(B, lead + B.shape[-2:])
    BT = np.swapaxes(B, -1, -2)
    H = np.concatenate([np.concatenate([A, -B @ Rinv @ BT], -1),
                        np.concatenate([np.broadcast_to(-Q, lead + (n, n)), -np.swapaxes(A, -1, -2)], -1)], -2)  # fmt: skip
    w, V = np.linalg.eig(H)
    stable = np.argsort(w.real, axis=-1)[..., :n]
    V = np.take_along_axis(V, stable[..., None, :], axis=-1)
    S = np.real(solve_rows(np.swapaxes(V[..., :n, :], -1, -2), np.swapaxes(V[..., n:, :], -1, -2)))
    S = 0.5 * (S + np.swapaxes(S, -1, -2))  # X2 X1^-1 = (X1^-T X2^T)^T, symmetric up to round-off
    eye = np.eye(n)
    for _ in range(newton):
        K = Rinv @ BT @ S
        Acl = A - B @ K
        AclT = np.swapaxes(Acl, -1, -2)
        L = np.einsum("...ij,kl->...ikjl", AclT, eye) + np.einsum(
            "ij,...kl->...ikjl", eye, AclT
        )  # vec(Acl^T S + S Acl)
        rhs = -(Q + np.swapaxes(K, -1, -2) @ R @ K)
        S = solve_rows(L.reshape(lead + (n * n, n * n)), rhs.reshape(lead + (n * n,))[..., None]).reshape(lead + (n, n))
        S = 0.5 * (S + np.swapaxes(S, -1, -2))
    K = Rinv @ BT @ S
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(S).all(axis=(-1, -2)) | (
            np.linalg.eigvals(A - B @ np.nan_to_num(K)).real.max(axis=-1) >= 0
        )  # or not stabilizing
    return np.where(bad[..., None, None], np.nan, K), np.where(bad[..., None, None], np.nan, S)


#: the env settings a controller (or a policy wrapper) is built for: what it derives its gains, scales and step
#: counts from at construction
BUILT_FOR = ("u_max", "dt", "substeps")


class BuiltFor:
    """The settings :data:`BUILT_FOR` of an env as a dependant saw them at construction, checked when it acts.

    The rule for every controller and setting: a controller acts for the settings it was built with. A documented
    change of one (``env.u_max = ...``, ``env.dt = ...``, ``set_attr``) after the controller was built makes its next
    ``predict`` raise ``ValueError`` naming the setting and both values (build the controller again), never act on
    the old one. The check costs one integer comparison while the env's settings are unchanged
    (:func:`mbs_envs.validation.settings_version`).
    """

    def __init__(self, base: Any):
        self.base = base
        self.values = {name: np.array(getattr(base, name), float) for name in BUILT_FOR if hasattr(base, name)}
        self.version = check.settings_version(base)

    def check(self, who: str) -> None:
        """Raise ``ValueError`` if a setting of :data:`BUILT_FOR` changed since construction."""
        version = check.settings_version(self.base)
        if version == self.version:
            return
        for name, value in self.values.items():
            now = np.array(getattr(self.base, name), float)
            if now.shape != value.shape or not np.array_equal(now, value):
                raise ValueError(f"{who} was built for the env's {name} = {value.tolist()}, which is now {now.tolist()}: "
                                 f"build the controller again after changing {name}")  # fmt: skip
        self.version = version  # changed and changed back: nothing this controller depends on moved


class Controller(abc.ABC):
    """A model-based policy: observation -> normalized action.

    Implements ``predict(observation, state=None, episode_start=None,
    deterministic=True) -> (action, state)`` (SB3's ``PolicyPredictor``),
    batched: an observation of shape ``(n_envs, obs_dim)`` gives actions of
    shape ``(n_envs, nu)``. Subclasses compute actuator inputs ``u`` [N m] in
    :meth:`input`; the conversion to the env's ``[-1, 1]`` scale (with
    saturation) happens here once.

    Parameters
    ----------
    env : gymnasium.Env
        The environment (wrapped or not) the controller will act on; its
        ``unwrapped`` must expose ``model``, ``u_max`` and ``decode_observation``.
    """

    #: the environment classes this controller can act on (its observation decoding and model use)
    fits: tuple[type, ...] = ()

    def __init__(self, env: Any):
        base = env.unwrapped if isinstance(env, (gym.Env, gym.vector.VectorEnv)) else None
        base = getattr(base, "env", base) if isinstance(base, gym.vector.VectorEnv) else base
        if base is None or not isinstance(base, self.fits):
            kinds = ", ".join(c.__name__ for c in self.fits)
            raise ValueError(
                f"{type(self).__name__} acts on {kinds} environments, got {type(getattr(env, 'unwrapped', env)).__name__}"
            )
        self.model = base.model
        self.u_max = np.asarray(base.u_max, float)
        self.built_for = BuiltFor(base)
        self.decode_observation = base.decode_observation
        space = base.observation_space
        self._obs_low, self._obs_high = np.asarray(space.low, float), np.asarray(space.high, float)

    @abc.abstractmethod
    def input(self, obs: Any) -> np.ndarray:
        """Actuator inputs ``u`` [N m], shape ``(..., nu)``, from a decoded observation."""

    def control(self, obs: Any, state: Any, episode_start: Any) -> tuple[np.ndarray, Any]:
        """Inputs ``u`` and the controller's next internal state.

        Stateless controllers (the default) pass ``state`` through; controllers
        with memory (integral action) override this and keep it in SB3's
        ``state``, reset where ``episode_start`` is true, so ``evaluate_policy``
        and batched rollouts carry it as they carry a recurrent policy's.
        """
        return self.input(obs), state

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action for an observation (or a batch), and the controller's state (see :meth:`control`).

        The observation must be real numbers and finite (``ValueError`` naming the members that are
        not: a NaN observation has no action). Where a finite observation far beyond the env's observation
        space overflows the computation (the disk LQR's feedforward at 1e30), the input is computed again from
        the observation clipped into the space (the env never observes beyond it): every finite observation
        gives a finite action, and every other one the same action as before."""
        self.built_for.check(type(self).__name__)
        obs = check.reals(observation, "observation")
        width = self._obs_low.shape[-1]
        if obs.ndim == 0 or obs.shape[-1] != width:
            raise ValueError(
                f"observation must have {width} entries per member (shape ({width},) or (n, {width})), "
                f"got shape {obs.shape}"
            )
        finite = np.isfinite(obs)
        if not finite.all():
            where = (
                ""
                if obs.ndim < 2
                else f" (members {np.flatnonzero(~finite.reshape(-1, obs.shape[-1]).all(axis=-1)).tolist()})"
            )
            raise ValueError(f"observation must be finite{where}")
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is caught below, from the result
            u, new_state = self.control(self.decode_observation(obs), state, episode_start)
        if not np.all(np.isfinite(u)) and obs.shape[-1:] == self._obs_low.shape:  # overflow from a finite observation
            u, new_state = self.control(
                self.decode_observation(np.clip(obs, self._obs_low, self._obs_high)), state, episode_start
            )
        state = new_state
        action = np.clip(u / self.u_max, -1.0, 1.0).astype(np.float32)
        return action, state

    def __repr__(self) -> str:
        return f"{type(self).__name__}(model={self.model!r})"
