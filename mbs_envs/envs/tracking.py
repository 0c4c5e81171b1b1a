"""The joint-space tracking task shared by the fully actuated scenes.

The observation carries the state and the reference at the current time, so a
model-based controller acts from the observation alone:

    obs = [cos q, sin q, v, e, v_ref, a_ref],   e = wrap(q_ref - q[tracked]) in [-pi, pi)

(``q, v`` of length ``n = nq``, the reference blocks of length ``m`` = the
number of tracked coordinates: all of them for serial scenes, the crank for the
four-bar; ``q`` is recovered as ``atan2(sin, cos)`` and ``q_ref = q[tracked] + e``,
exact modulo 2 pi, which is all a revolute model needs). The reward is

    r = -(w_e |e|^2 + w_de |v_ref - v[tracked]|^2 + w_u |action|^2)

with each term reported in ``info``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import gymnasium as gym
from ..dynamics.jit import njit
import numpy as np

from .draws import uniform_of
from .references import SumOfSines, sample_sums_of_sines, sum_of_sines_columns
from ..dynamics.trig import sincos_columns, wrap, wrap_fast
from .. import validation as check
from .base import MBSEnv


def wrap_angle(x: np.ndarray) -> np.ndarray:
    """Wrap angles to ``[-pi, pi)`` (floats or arrays)."""
    return (x + np.pi) % (2 * np.pi) - np.pi


# ---------------------------------------------------------------------------
# The task's formulas for one member (compiled), and their batched callers
# ---------------------------------------------------------------------------


@njit
def error_columns(q, q_ref, tracked, e):  # pragma: no cover - compiled
    """The tracking error ``e = wrap(q_ref - q[tracked])`` of a batch (computed once per step:
    the observation and the reward both read it).

    Parameters
    ----------
    q : ndarray, shape (n, B)
        Columns (:mod:`mbs_envs.dynamics.compiled`).
    q_ref : ndarray, shape (m, B)
    tracked : ndarray of int, shape (m,)
    e : ndarray, shape (m, B)
        Written [rad], in ``[-pi, pi)``: :func:`wrap_angle`'s bits (:func:`mbs_envs.dynamics.trig.wrap_fast`).
    """
    ok = True
    for j in range(tracked.shape[0]):  # one SIMD pass (exact where ok), then the rest by fmod
        qj, rj, ej = q[tracked[j]], q_ref[j], e[j]  # 1-d rows: LLVM did not vectorize the 2-d q[tracked[j], b]
        for b in range(q.shape[1]):
            ej[b], ok_b = wrap_fast(rj[b] - qj[b])
            ok &= ok_b
    if not ok:
        for j in range(tracked.shape[0]):
            for b in range(q.shape[1]):
                e[j, b] = wrap(q_ref[j, b] - q[tracked[j], b])


@njit
def encode_columns(q, v, e, v_ref, a_ref, obs):  # pragma: no cover - compiled
    """``obs = [cos q, sin q, v, e, v_ref, a_ref]`` of a batch.

    Parameters
    ----------
    q, v : ndarray, shape (n, B)
        Columns (:mod:`mbs_envs.dynamics.compiled`).
    e, v_ref, a_ref : ndarray, shape (m, B)
        The tracking error (:func:`error_columns`) and the reference's rates.
    obs : ndarray, shape (3 n + 3 m, B)
        Written, one column per member (the env returns its transpose, as Gymnasium's
        ``CartPoleVectorEnv`` does: stores along the members are SIMD code).
    """
    n, B = q.shape
    m = e.shape[0]
    s, c = np.empty(B), np.empty(B)
    for i in range(n):
        sincos_columns(q[i], s, c)
        for b in range(B):
            obs[i, b] = c[b]
            obs[n + i, b] = s[b]
            obs[2 * n + i, b] = v[i, b]
    for j in range(m):
        for b in range(B):
            obs[3 * n + j, b] = e[j, b]
            obs[3 * n + m + j, b] = v_ref[j, b]
            obs[3 * n + 2 * m + j, b] = a_ref[j, b]


@njit
def reward_columns(v, e, v_ref, action, tracked, weights, terms):  # pragma: no cover - compiled
    """The reward terms (module docstring) of a batch.

    Parameters
    ----------
    v : ndarray, shape (n, B)
    e, v_ref : ndarray, shape (m, B)
        The tracking error (:func:`error_columns`) and the reference rate.
    action : ndarray, shape (nu, B)
    tracked : ndarray of int, shape (m,)
    weights : ndarray, shape (3,)
        ``(w_e, w_de, w_u)``.
    terms : ndarray, shape (>= 4, B)
        Written: rows ``(r, r_e, r_de, r_u)``, one column per member.
    """
    B = v.shape[1]
    s_e, s_de, s_u = np.zeros(B), np.zeros(B), np.zeros(B)
    for j in range(tracked.shape[0]):
        ej, rj, vj = e[j], v_ref[j], v[tracked[j]]  # rows (SIMD; see error_columns)
        for b in range(B):
            de = rj[b] - vj[b]
            s_e[b] += ej[b] * ej[b]
            s_de[b] += de * de
    for k in range(action.shape[0]):
        ak = action[k]
        for b in range(B):
            s_u[b] += ak[b] * ak[b]
    for b in range(B):
        r_e = -weights[0] * s_e[b]
        r_de = -weights[1] * s_de[b]
        r_u = -weights[2] * s_u[b]
        terms[0, b] = r_e + r_de + r_u
        terms[1, b] = r_e
        terms[2, b] = r_de
        terms[3, b] = r_u


def reward_formula(weights: Any, e: np.ndarray, de: np.ndarray, action: np.ndarray) -> tuple[np.ndarray, tuple]:
    """:func:`reward_columns` as its formula in plain numpy (the kernel is its SIMD loop; the tests hold them equal).

    ``r = -(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |a|^2)``; ``e, de`` of shape ``(..., m)`` (error and rate error of
    the tracked coordinates), ``action`` ``(..., nu)``. Returns ``r`` and its terms ``(r_e, r_de, r_u)``.
    """
    w_e, w_de, w_u = weights
    r_e, r_de, r_u = -w_e * np.sum(e * e, -1), -w_de * np.sum(de * de, -1), -w_u * np.sum(action * action, -1)
    return r_e + r_de + r_u, (r_e, r_de, r_u)


def _as_columns(*arrays: np.ndarray) -> tuple[tuple, list[np.ndarray]]:
    """Broadcast the leading dimensions of ``(..., k_i)`` arrays, flatten them to ``L``
    members and lay each out in contiguous columns ``(k_i, L)``."""
    arrays = [np.asarray(x, float) for x in arrays]
    lead = np.broadcast_shapes(*(x.shape[:-1] for x in arrays))
    # new arrays, writable as well as contiguous: the kernels' calls from compiled code pass writable arrays,
    # and a read-only argument (a no-op broadcast's view) would compile every kernel a second time
    return lead, [np.array((x if x.shape[:-1] == lead else np.broadcast_to(x, lead + x.shape[-1:])).reshape(-1, x.shape[-1]).T, order="C")
                  for x in arrays]  # fmt: skip


@njit
def tracking_task(q, v, t, action, task, obs, info, terminated):  # pragma: no cover - compiled
    """The task kernel of the tracking scenes (:mod:`mbs_envs.envs.engine`): at the new time
    ``t``, the reference, the reward and its terms, the observation and the info columns
    ``(r, r_e, r_de, r_u, e (m), q_ref (m))``; no termination.

    ``task = (tracked, weights, center, rate, amplitude, omega, phase)``: the tracked
    coordinates, the reward weights and the references in columns (:meth:`SumOfSines.columns`).
    """
    tracked, weights, center, rate, amplitude, omega, phase = task
    B = q.shape[1]
    m = tracked.shape[0]
    refs = np.empty((3, m, B))
    sum_of_sines_columns(t, center, rate, amplitude, omega, phase, refs[0], refs[1], refs[2])
    e = np.empty((m, B))
    error_columns(q, refs[0], tracked, e)
    reward_columns(v, e, refs[1], action, tracked, weights, info)
    encode_columns(q, v, e, refs[1], refs[2], obs)
    for j in range(m):  # rows: SIMD stores along the members
        ej, rj, ie, ir = e[j], refs[0, j], info[4 + j], info[4 + m + j]
        for b in range(B):
            ie[b] = ej[b]
            ir[b] = rj[b]
    for b in range(B):
        terminated[b] = False


@dataclasses.dataclass(frozen=True)
class TrackingObservation:
    """A decoded tracking observation.

    ``q, v`` have shape ``(..., n)`` (the whole state); ``q_ref, v_ref, a_ref``
    shape ``(..., m)``, the reference of the coordinates ``tracked``.
    """

    q: np.ndarray
    v: np.ndarray
    q_ref: np.ndarray
    v_ref: np.ndarray
    a_ref: np.ndarray
    tracked: tuple[int, ...]


def encode_tracking(q, v, q_ref, v_ref, a_ref, tracked: tuple[int, ...]) -> np.ndarray:
    """Observation ``[cos q, sin q, v, wrap(q_ref - q[tracked]), v_ref, a_ref]`` (float32), batched.

    Parameters
    ----------
    q, v : array_like, shape (..., n)
    q_ref, v_ref, a_ref : array_like, shape (..., m)
    tracked : tuple of int, length m

    Returns
    -------
    ndarray, float32, shape (..., 3 n + 3 m)
    """
    lead, (q2, v2, q_ref2, v_ref2, a_ref2) = _as_columns(q, v, q_ref, v_ref, a_ref)
    (n, L), m = q2.shape, len(tracked)
    obs = np.empty((3 * (n + m), L), np.float32)
    e = np.empty(q_ref2.shape)
    error_columns(q2, q_ref2, np.asarray(tracked, np.int64), e)
    encode_columns(q2, v2, e, v_ref2, a_ref2, obs)
    return obs.T.reshape(lead + (3 * (n + m),))


def decode_tracking(obs: np.ndarray, n: int, tracked: tuple[int, ...] | None = None) -> TrackingObservation:
    """Invert :func:`encode_tracking` (batched over leading dimensions).

    Parameters
    ----------
    obs : ndarray, shape (..., 3 n + 3 m)
    n : int
        Number of coordinates.
    tracked : tuple of int, optional
        Tracked coordinates (default all ``n``).

    Returns
    -------
    TrackingObservation
    """
    tracked = tuple(range(n)) if tracked is None else tuple(tracked)
    m = len(tracked)
    obs = np.asarray(obs, dtype=float)
    if obs.shape[-1] != 3 * (n + m):
        raise ValueError(f"observation must have shape (..., {3 * (n + m)}), got {obs.shape}")
    c, s, v = (obs[..., k * n : (k + 1) * n] for k in range(3))
    e, v_ref, a_ref = (obs[..., 3 * n + k * m : 3 * n + (k + 1) * m] for k in range(3))
    q = np.arctan2(s, c)
    return TrackingObservation(q=q, v=v, q_ref=q[..., list(tracked)] + e, v_ref=v_ref, a_ref=a_ref, tracked=tracked)


#: names in ``info`` of the reward terms (columns 1-3 of :func:`reward_columns`'s output)
REWARD_TERMS = ("reward_tracking", "reward_velocity", "reward_effort")


@dataclasses.dataclass(frozen=True)
class TrackingTaskParams:
    """The tracking task's parameters, explicit and immutable (Gymnasium's phys2d style): the
    task is the functions below of ``(q, v, t, task state, params)``; an env holds its
    parameters as :attr:`JointTrackingEnv.task_params`.

    Attributes
    ----------
    tracked : tuple of int
        The tracked coordinates (``m`` of them).
    weights : ndarray, shape (3,)
        ``(w_e, w_de, w_u)`` of the reward.
    center_low, center_high : ndarray, shape (m,)
        Range of the reference's centre [rad].
    max_amplitude : ndarray, shape (m,)
        Largest total amplitude [rad].
    omega_range : (float, float)
        Frequencies [rad/s].
    rate_range : (float, float) or None
        Mean rate [rad/s] (None: no drift).
    n_components : int
    start_noise : float
        ``q0 = q_ref(0) + U(-s, s)``, ``v0 = v_ref(0) + U(-s, s)`` on the tracked coordinates.
    """

    tracked: tuple[int, ...]
    weights: np.ndarray
    center_low: np.ndarray
    center_high: np.ndarray
    max_amplitude: np.ndarray
    omega_range: tuple[float, float]
    rate_range: tuple[float, float] | None
    n_components: int
    start_noise: float


def sample(p: TrackingTaskParams, rngs: list[np.random.Generator]) -> SumOfSines:
    """The episode's task state of ``L = len(rngs)`` members, stacked: their references
    (:func:`sample_sums_of_sines`)."""
    return sample_sums_of_sines(
        rngs, p.center_low, p.center_high, p.max_amplitude, p.omega_range, p.n_components, p.rate_range
    )


def start_tracked(
    p: TrackingTaskParams, reference: SumOfSines, rngs: list[np.random.Generator]
) -> tuple[np.ndarray, np.ndarray]:
    """The tracked coordinates' start ``(q_t, v_t)``, shape ``(L, m)`` each: the stacked references at 0
    plus noise, member ``i``'s from ``rngs[i]`` (a scene completes the rest of the state)."""
    q_ref, v_ref, _ = reference(0.0)
    s, m = p.start_noise, len(p.tracked)
    noise = uniform_of(np.array([rng.random(2 * m) for rng in rngs]), -s, s)  # :mod:`mbs_envs.envs.draws`
    return q_ref + noise[:, :m], v_ref + noise[:, m:]


def observe(p: TrackingTaskParams, q: np.ndarray, v: np.ndarray, now: tuple) -> np.ndarray:
    """The observation (module docstring) at ``now = (q_ref, v_ref, a_ref)``, float32 ``(..., 3 n + 3 m)``."""
    return encode_tracking(q, v, *now, p.tracked)


def errors(p: TrackingTaskParams, q: np.ndarray, v: np.ndarray, now: tuple) -> tuple[np.ndarray, np.ndarray]:
    """``(wrap(q_ref - q), v_ref - v)`` on the tracked coordinates, shape ``(..., m)``."""
    q_ref, v_ref, _ = now
    idx = list(p.tracked)
    return wrap_angle(q_ref - q[..., idx]), v_ref - v[..., idx]


def reward(
    p: TrackingTaskParams, q: np.ndarray, v: np.ndarray, now: tuple, action: np.ndarray
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The reward ``(...)`` (module docstring) and its terms (:data:`REWARD_TERMS`), by :func:`reward_columns`."""
    lead, (q2, v2, q_ref, v_ref, a2) = _as_columns(q, v, now[0], now[1], action)
    tracked = np.asarray(p.tracked, np.int64)
    terms, e = np.empty((4, q2.shape[1])), np.empty(q_ref.shape)
    error_columns(q2, q_ref, tracked, e)
    reward_columns(v2, e, v_ref, a2, tracked, np.asarray(p.weights, float), terms)
    terms = terms.T.reshape(lead + (4,))
    return terms[..., 0], {k: terms[..., i + 1] for i, k in enumerate(REWARD_TERMS)}


def info(p: TrackingTaskParams, q: np.ndarray, v: np.ndarray, now: tuple) -> dict[str, np.ndarray]:
    """The task's ``info``: ``tracking_error`` and ``q_ref``, shape ``(..., m)`` each (no termination)."""
    return {"tracking_error": errors(p, q, v, now)[0], "q_ref": now[0]}


class JointTrackingEnv(MBSEnv):
    """Track a random smooth reference (:class:`SumOfSines`) of the ``tracked`` coordinates.

    Subclasses set the reference distribution (class attributes below) and
    the drawing. Serial scenes track every joint (``tracked`` = all, fully
    actuated); a constrained scene tracks its independent coordinates and
    overrides :meth:`_state_from_tracked` to complete a consistent state.

    Parameters
    ----------
    model, u_max, **kwargs
        See :class:`MBSEnv`.
    reward_weights : (float, float, float)
        ``(w_e, w_de, w_u)`` of the reward.
    start_noise : float
        Start state ``q0 = q_ref(0) + U(-s, s)``, ``v0 = v_ref(0) + U(-s, s)`` [rad, rad/s].
    """

    #: reference centre range per tracked coordinate [rad], amplitude [rad],
    #: frequencies [rad/s], mean rate range [rad/s] (None: no drift)
    center_low: ClassVar[np.ndarray]
    center_high: ClassVar[np.ndarray]
    max_amplitude: ClassVar[np.ndarray]
    omega_range: ClassVar[tuple[float, float]] = (0.5, 3.0)
    rate_range: ClassVar[tuple[float, float] | None] = None
    n_components: ClassVar[int] = 3
    #: the pre-tuning (kp, kd) of a PD controller on this task [N m/rad, N m s/rad]
    pd_gains: tuple[float, float] = (100.0, 20.0)
    #: inertia [kg m^2] (scalar or per tracked joint) that turns a bandwidth into PD gains:
    #: ``kp = J omega^2``, ``kd = 2 J zeta omega`` (controllers/tuned.py)
    joint_inertia: Any = 1.0

    reward_weights = check.Checked(lambda x, name: check.vector(x, name, 3, 0.0, broadcast=False))
    start_noise = check.Checked(lambda x, name: check.nonnegative(x, name, 10.0))

    def __init__(self, model, u_max, *, reward_weights=(1.0, 0.1, 1e-3), start_noise=0.1, **kwargs):
        super().__init__(model, u_max, **kwargs)
        self.tracked = tuple(getattr(model, "independent", range(model.nq)))
        if len(self.tracked) != model.nu:
            raise ValueError("JointTrackingEnv needs one input per tracked coordinate")
        self.reward_weights = reward_weights
        self._tracked = np.asarray(self.tracked, np.int64)
        self.start_noise = start_noise
        n, m = model.nq, len(self.tracked)
        # |v| <= divergence_limit is guaranteed (a diverged step keeps the last
        # finite state); the reference's rates are bounded by |s| + sum A w and sum A w^2.
        w_max = self.omega_range[1]
        s_max = 0.0 if self.rate_range is None else np.max(np.abs(self.rate_range))
        high = np.concatenate(
            [
                np.ones(2 * n),
                np.full(n, self.divergence_limit),
                np.full(m, np.pi),
                np.broadcast_to(s_max + self.max_amplitude * w_max, (m,)),
                np.broadcast_to(self.max_amplitude * w_max**2, (m,)),
            ]
        ).astype(np.float32)
        self.observation_space = gym.spaces.Box(-high, high, dtype=np.float32)
        span = np.maximum(np.abs(self.center_low), np.abs(self.center_high)) + self.max_amplitude
        self._check_start_bound(
            float(np.max(np.concatenate([span, s_max + self.max_amplitude * w_max]))) + self.start_noise
        )

    # -- the compiled step (see mbs_envs.envs.engine) ----------------------------

    def task_arguments(self) -> tuple:
        c = self.__dict__.get(
            "_task_arguments_cache"
        )  # a writable copy of the (read-only) weights, per settings version
        if c is None or c[0] != check.settings_version(self):
            c = self._task_arguments_cache = (
                check.settings_version(self),
                (self._tracked, np.array(self.reward_weights)),
            )
        return c[1]

    def task_columns(self, task: SumOfSines) -> tuple:
        return task.columns()

    def task_layout(self) -> tuple[tuple[str, int | None, bool], ...]:
        m = len(self.tracked)
        terms = tuple((name, None, False) for name in self.reward_terms)
        return (("reward", None, False),) + terms + (("tracking_error", m, False), ("q_ref", m, False))

    @property
    def reference(self) -> SumOfSines | None:
        """The episode's reference (None before the first reset)."""
        return self._task

    def reference_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q_ref, v_ref, a_ref)`` at the current time."""
        return self.now()

    # -- the task: the module's functions with this env's parameters -----------------

    @property
    def task_params(self) -> TrackingTaskParams:
        """This env's task parameters, from its current settings (a new value each call)."""
        return TrackingTaskParams(
            self.tracked, self.reward_weights, np.asarray(self.center_low, float), np.asarray(self.center_high, float),
            np.asarray(self.max_amplitude, float), self.omega_range, self.rate_range, self.n_components, self.start_noise,
        )  # fmt: skip

    def _draw_tasks(self, options: dict, rngs: list) -> SumOfSines:
        return sample(self.task_params, rngs)

    def _draw_states(self, task: SumOfSines, rngs: list, model) -> tuple[np.ndarray, np.ndarray]:
        return self._state_from_tracked(*start_tracked(self.task_params, task, rngs), model)

    def _state_from_tracked(self, q_t: np.ndarray, v_t: np.ndarray, model) -> tuple[np.ndarray, np.ndarray]:
        """Whole states ``(L, nq)``, ``(L, nv)`` from the tracked coordinates ``(L, m)`` (identity when all are tracked)."""
        return q_t, v_t

    def task_now(self, t: np.ndarray, task: SumOfSines) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q_ref, v_ref, a_ref)`` at ``t``, each shape ``(..., m)``."""
        return task(t)

    def observe(self, q, v, now, task) -> np.ndarray:
        return observe(self.task_params, q, v, now)

    def decode_observation(self, obs: np.ndarray) -> TrackingObservation:
        """The state and reference in an observation (batched); see :func:`decode_tracking`."""
        return decode_tracking(obs, self.model.nq, self.tracked)

    def errors(self, q: np.ndarray, v: np.ndarray, now) -> tuple[np.ndarray, np.ndarray]:
        """``(wrap(q_ref - q), v_ref - v)`` on the tracked coordinates, shape ``(..., m)``."""
        return errors(self.task_params, q, v, now)

    reward_terms: ClassVar[tuple[str, ...]] = REWARD_TERMS

    def reward(self, q, v, now, task, u, action) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        return reward(self.task_params, q, v, now, action)

    def task_info(self, q, v, now, task, u) -> dict[str, Any]:
        return info(self.task_params, q, v, now)


class ChainTrackingEnv(JointTrackingEnv):
    """An N-link chain, every joint driven, tracking a random smooth joint reference about a rest posture.

    What the planar and the spatial chain share (``mbs_envs/SerialChain-v0``, ``mbs_envs/SpatialChain-v0``):
    the drives, the reference distribution and the PD pre-tuning; the subclass names its model class
    (:attr:`Model`) and gives :meth:`holding_torque` and :meth:`posture`.

    - Drives: a torque limit per joint of :meth:`holding_torque` (the gravity torque of the chain beyond
      the joint held out straight), and a rotor inertia reflected through its gear (``armature``, on
      ``M``'s diagonal) of ``torque_limit / rotor_acceleration``: a drive at full torque accelerates its
      own rotor at 30 rad/s^2. ``params={"armature": 0}`` gives the bare chain.
    - Reference: centres ``posture + U(-s, s)`` with ``s = 0.5`` rad on the first :attr:`wide_joints`
      joints and ``1 / N`` on the others, amplitude ``U(0.5, 1) 0.8 / N`` rad per joint, frequencies
      ``U(0.5, 3)`` rad/s; start at the reference plus ``U(-0.1, 0.1) / N``. The ``1 / N`` keeps the
      whole chain's posture the same for any N.
    - Reward ``-(w_e |e|^2 + w_de |v_ref - v|^2 + w_u |action|^2) / N``, default weights ``(1, 0.1, 0.001)``.
    - ``pd_gains``: ``(100, 20) J_i`` per joint, ``J_i = 1 / (M^-1)_ii`` the apparent inertia of joint i at
      the posture (computed torque's bandwidth joint by joint).
    """

    Model: ClassVar[type]
    omega_range = (0.5, 3.0)
    #: the longest chain of the task (its construction forms the N x N mass matrix once)
    max_links: ClassVar[int] = 500
    #: a drive at full torque accelerates its own rotor alone at this rate [rad/s^2]
    rotor_acceleration: ClassVar[float] = 30.0
    #: how many joints (from the base) have reference centres spread by +-0.5 rad (the others +-1/N)
    wide_joints: ClassVar[int] = 1

    def __init__(self, n_links: int = 10, params: Any = None, torque_limit: Any = None,
                 reward_weights: Any = (1.0, 0.1, 1e-3), **kwargs: Any):  # fmt: skip
        from ..models.serial_chain import link_count

        n_links = link_count(n_links, self.max_links)
        if isinstance(params, self.Model.Params):  # a ready parameter set: the model exactly as given
            if params.n_links != n_links:
                raise ValueError(
                    f"params has n_links = {params.n_links}, but n_links = {n_links}; pass the same number"
                )
            model = self.Model(params)
            holding = self.holding_torque(model)
        else:
            params = check.mapping(params, "params")
            if "n_links" in params:
                raise ValueError("params: pass n_links as the make kwarg n_links, not inside params")
            nominal = self.Model(n_links=n_links, **{k: v for k, v in params.items() if k != "armature"})
            holding = self.holding_torque(nominal)
            model = self.Model({"armature": holding / self.rotor_acceleration, **params, "n_links": n_links})
        if torque_limit is None:
            torque_limit = holding
        n = model.n_links
        posture = self.posture(model)
        spread = np.full(n, 1.0 / n)
        spread[: self.wide_joints] = 0.5
        self.center_low, self.center_high = posture - spread, posture + spread
        self.max_amplitude = np.full(n, 0.8 / n)
        weights = check.vector(reward_weights, "reward_weights", 3, 0.0, broadcast=False) / n
        kwargs.setdefault("start_noise", 0.1 / n)
        super().__init__(model, torque_limit, reward_weights=weights, **kwargs)
        # PD gains with computed torque's bandwidth at the posture, joint by joint, on the apparent
        # inertia 1 / (M^-1)_ii (the others free to move)
        J = 1.0 / np.diag(np.linalg.inv(model.mass_matrix(posture)))
        self.joint_inertia = J
        self.pd_gains = (100.0 * J, 20.0 * J)

    @staticmethod
    def holding_torque(model: Any) -> np.ndarray:
        """The torque limit of each joint's drive [N m], shape (N,) (the subclass's)."""
        raise NotImplementedError

    @staticmethod
    def posture(model: Any) -> np.ndarray:
        """The rest posture the references are drawn about [rad], shape (N,) (the subclass's)."""
        raise NotImplementedError
