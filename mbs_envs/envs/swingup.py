"""``mbs_envs/Acrobot-v0`` and ``mbs_envs/Pendubot-v0``: swing the 2R arm up with one motor and balance it.

The Planar2R model (docs/physics.md §3) with one driven joint
(:class:`~mbs_envs.models.planar2r.Planar2R` ``driven``): the elbow for the
acrobot, the shoulder for the pendubot. The task, written once for both:

- upright is ``q_up = (pi/2, 0)``; the error ``e = wrap(q - q_up)`` in ``[-pi, pi)``;
- reward ``r = w_h h - w_e |e|^2 - w_u |action|^2 + w_b 1[upright]`` with the height term
  ``h = (sin th1 + sin(th1 + th2)) / 2`` in ``[-1, 1]`` (the tip's height over the
  arm's reach for equal links; 1 upright, -1 hanging) and default weights
  ``(w_h, w_e, w_u) = (1, 0.05, 0.01)``; the hold bonus ``w_b`` is 0 in v0 and 1 in v1
  (``Acrobot-v1``, ``Pendubot-v1``: a changed reward is a new version, v0 stays registered);
- observation ``[cos q (2), sin q (2), v (2)]``;
- ``info``: the reward terms (``reward_hold`` the bonus), ``tracking_error = e`` (the distance to upright, which
  the evaluation scores), ``upright`` (``|e_i| <= upright_tolerance`` on both joints)
  and ``power = u v_driven`` [W], the motor's mechanical power.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from .. import validation as check
from ..dynamics import compiled as _compiled
from ..dynamics.jit import njit
from ..dynamics.trig import sincos_columns, wrap
from ..models import planar2r as _model
from ..models.planar2r import Planar2R
from .base import MBSEnv
from .draws import uniform_of
from .engine import engine_step
from .presets import with_preset
from .rendering import Shape, arm_shapes
from .tracking import _as_columns


#: the upright configuration ``(th1, th2)`` [rad]
Q_UP = np.array([np.pi / 2, 0.0])
#: the hanging configuration [rad]
Q_DOWN = np.array([-np.pi / 2, 0.0])


@njit
def observe_columns(q, v, obs):  # pragma: no cover - compiled
    """``obs = [cos q, sin q, v]`` of a batch: ``q, v`` in columns (2, B), ``obs`` (6, B) written (a column per member)."""
    B = q.shape[1]
    s, c = np.empty(B), np.empty(B)
    for i in range(2):
        sincos_columns(q[i], s, c)
        for b in range(B):
            obs[i, b] = c[b]
            obs[2 + i, b] = s[b]
            obs[4 + i, b] = v[i, b]


@njit
def swingup_columns(q, v, action, weights, u_max, driven, tolerance, info):  # pragma: no cover - compiled
    """The swing-up task's reward and ``info`` (module docstring) of a batch in columns.

    Parameters
    ----------
    q, v : ndarray, shape (2, B)
        Joint angles [rad] and rates [rad/s].
    action : ndarray, shape (1, B)
        Normalized input.
    weights : ndarray, shape (4,)
        ``(w_h, w_e, w_u, w_b)``.
    u_max : ndarray, shape (1,)
        Torque limit [N m].
    driven : ndarray of int, shape (1,)
        The driven joint.
    tolerance : float
        Upright tolerance per joint [rad].
    info : ndarray, shape (>= 9, B)
        Written: ``(r, r_height, r_upright, r_effort, e1, e2, upright, power, r_hold)`` in rows 0-8.
    """
    B = q.shape[1]
    s, c = np.empty((2, B)), np.empty((2, B))
    for i in range(2):
        sincos_columns(q[i], s[i], c[i])
    for b in range(B):
        e1 = wrap(q[0, b] - np.pi / 2)
        e2 = wrap(q[1, b])
        h = 0.5 * (s[0, b] + s[0, b] * c[1, b] + c[0, b] * s[1, b])  # sin th1 + sin(th1 + th2), halved
        a = action[0, b]
        r_h, r_e, r_u = weights[0] * h, -weights[1] * (e1 * e1 + e2 * e2), -weights[2] * a * a
        up = abs(e1) <= tolerance and abs(e2) <= tolerance
        r_b = weights[3] * up
        info[0, b] = r_h + r_e + r_u + r_b  # v0: w_b = 0, and x + 0.0 == x (the same bits as before)
        info[1, b], info[2, b], info[3, b] = r_h, r_e, r_u
        info[4, b], info[5, b] = e1, e2
        info[6, b] = up
        info[7, b] = a * u_max[0] * v[driven[0], b]
        info[8, b] = r_b


@njit
def swingup_task(q, v, t, action, task, obs, info, terminated):  # pragma: no cover - compiled
    """The task kernel (:mod:`mbs_envs.envs.engine`): ``task = (weights, u_max, driven, tolerance)``; no termination."""
    weights, u_max, driven, tolerance = task
    swingup_columns(q, v, action, weights, u_max, driven, tolerance, info)
    observe_columns(q, v, obs)
    for b in range(q.shape[1]):
        terminated[b] = False


@njit
def step_kernel(theta, stepper, control, task, state, out):  # pragma: no cover - compiled
    """The compiled step of both scenes: :func:`~mbs_envs.envs.engine.engine_step` with Planar2R's kernels."""
    engine_step(
        _model.advance_kernel,
        _model.energy_kernel,
        _compiled.no_constraint_info,
        _compiled.never_singular,
        _this.swingup_task,
        theta,
        stepper,
        control,
        task,
        state,
        out,
    )


_this = sys.modules[__name__]


@dataclasses.dataclass(frozen=True)
class SwingUpObservation:
    """A decoded swing-up observation: ``q, v`` of shape ``(..., n)`` (``n = 2`` for the arm; angles in ``[-pi, pi]``)."""

    q: np.ndarray
    v: np.ndarray


def encode_swingup(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``[cos q, sin q, v]``, float32, shape ``(..., 6)`` (:func:`observe_columns`, batched)."""
    lead, (q2, v2) = _as_columns(q, v)
    obs = np.empty((6, q2.shape[1]), np.float32)
    observe_columns(q2, v2, obs)
    return obs.T.reshape(lead + (6,))


def decode_swingup(obs: np.ndarray) -> SwingUpObservation:
    """Invert :func:`encode_swingup` (batched); ``q = atan2(sin, cos)``."""
    obs = np.asarray(obs, float)
    if obs.shape[-1] != 6:
        raise ValueError(f"observation must have shape (..., 6), got {obs.shape}")
    return SwingUpObservation(q=np.arctan2(obs[..., 2:4], obs[..., 0:2]), v=obs[..., 4:6])


@dataclasses.dataclass(frozen=True, eq=False)
class StartBank:
    """Training starts from given states: a curriculum (the evaluated task starts hanging).

    Attributes
    ----------
    share : float
        The share, in [0, 1], of the episodes that would start hanging which start from a row instead.
    rows : ndarray, shape (K, 4)
        States ``(th1, th2, dth1, dth2)`` [rad, rad/s]; such a start is a row drawn uniformly, plus the task's start
        noise ``U(-s, s)`` on each entry (as about hanging).

    Equal only to itself (``eq=False``): a bank is immutable (its rows read-only) and each assignment of the setting
    makes a new one, so a task cache keyed on the bank object is rebuilt exactly when the setting changes, without
    comparing the rows at every step.
    """

    share: float
    rows: np.ndarray


def start_bank(value: Any, name: str) -> StartBank | None:
    """The ``start_states`` setting: ``None`` (no bank), a :class:`StartBank`, or a mapping ``{"share": p, "rows":
    (K, 4) states}`` (JSON's form, e.g. ``--train-env-kwargs``); a ``ValueError`` naming the culprit otherwise."""
    if value is None:
        return None
    if isinstance(value, StartBank):
        value = {"share": value.share, "rows": value.rows}
    m = check.mapping(value, name)
    if set(m) != {"share", "rows"}:
        raise ValueError(f"{name} must have exactly the keys 'share' and 'rows', got {sorted(m)}")
    share = check.real(m["share"], f"{name}['share']", 0.0, 1.0)
    rows = check.reals(m["rows"], f"{name}['rows']")
    if rows.ndim != 2 or rows.shape[1] != 4 or len(rows) == 0:
        raise ValueError(f"{name}['rows'] must have shape (K, 4) with K >= 1 (th1, th2, dth1, dth2), got {rows.shape}")
    if not np.all(np.isfinite(rows)):
        raise ValueError(f"{name}['rows'] must be finite")
    return StartBank(share, check.frozen(rows))


@dataclasses.dataclass(frozen=True)
class SwingUpTaskParams:
    """The swing-up task's parameters, explicit and immutable (Gymnasium's phys2d style); an env
    holds its own as :attr:`SwingUpEnv.task_params`.

    Attributes
    ----------
    weights : ndarray, shape (4,)
        ``(w_h, w_e, w_u, w_b)`` of the reward (``w_b``: the hold bonus; 0 in the v0 task).
    u_max : ndarray, shape (1,)
        Torque limit [N m] (the power in ``info``).
    driven : int
        The driven joint.
    tolerance : float
        Upright tolerance per joint [rad].
    start_noise : float
        ``q0 = q_c + U(-s, s)``, ``v0 = U(-s, s)`` about the start's centre ``q_c``.
    start_upright : float
        The share of episodes whose centre ``q_c`` is upright instead of hanging (0: every
        episode hangs, the task as evaluated; a training curriculum may raise it).
    start_bank : StartBank or None
        Of the episodes that would hang, a share that starts from given states instead (a training curriculum).
    """

    weights: np.ndarray
    u_max: np.ndarray
    driven: int
    tolerance: float
    start_noise: float
    start_upright: float = 0.0
    start_bank: StartBank | None = None

    def kernel_arguments(self) -> tuple:
        """``(weights, u_max, driven, tolerance)`` as :func:`swingup_columns` takes them."""
        return (
            np.array(self.weights, float),
            np.array(self.u_max, float),
            np.array([self.driven], np.int64),
            float(self.tolerance),
        )


def start(p: SwingUpTaskParams, rngs: list[np.random.Generator]) -> tuple[np.ndarray, np.ndarray]:
    """Starts ``(q0, v0)``, shape ``(L, 2)`` each, member ``i`` from ``rngs[i]`` (the task has no other
    episode state): a centre ``(q_c, v_c)`` plus ``U(-s, s)`` on each entry. The centre is upright at rest with
    probability ``p.start_upright``; else a row of ``p.start_bank`` with probability ``p.start_bank.share``; else
    hanging at rest. The choice is drawn first (one double), then the row (one double), each only when its option is
    on, so the hanging task's starts are the same draws as without the options."""
    s, bank = p.start_noise, p.start_bank
    b = int(bank is not None and bank.share > 0.0)
    k = int(p.start_upright > 0.0 or b > 0)
    d = np.array([rng.random(k + b + 4) for rng in rngs])  # (the choice), (the row), q noise, v noise (:mod:`.draws`)
    r = d[:, 0] if k else np.ones(len(rngs))
    upright = r < p.start_upright
    noise = uniform_of(d[:, k + b :], -s, s)
    q_c = np.where(upright[:, None], Q_UP, Q_DOWN)
    v_c = np.zeros_like(q_c)
    if b:
        banked = ~upright & (r < p.start_upright + bank.share * (1.0 - p.start_upright))
        rows = bank.rows[np.minimum((d[:, 1] * len(bank.rows)).astype(np.int64), len(bank.rows) - 1)]
        q_c = np.where(banked[:, None], rows[:, :2], q_c)
        v_c = np.where(banked[:, None], rows[:, 2:], v_c)
    return q_c + noise[:, :2], v_c + noise[:, 2:]


def reward_formula(weights: Any, tolerance: float, q: np.ndarray, action: np.ndarray) -> np.ndarray:
    """:func:`swingup_columns`'s reward as its formula in plain numpy (the kernel is its SIMD loop; tested equal).

    ``r = w_h h - w_e |e|^2 - w_u a^2 + w_b 1[|e_1| <= tol and |e_2| <= tol]`` with ``h = (sin th1 + sin(th1 + th2))
    / 2`` and ``e = wrap(q - (pi/2, 0))``; ``q`` of shape ``(..., 2)``, ``action`` ``(..., 1)``.
    """
    w_h, w_e, w_u, w_b = weights
    e = np.mod(q - np.array([np.pi / 2, 0.0]) + np.pi, 2 * np.pi) - np.pi
    h = (np.sin(q[..., 0]) + np.sin(q[..., 0] + q[..., 1])) / 2
    up = np.all(np.abs(e) <= tolerance, axis=-1)
    return w_h * h - w_e * np.sum(e * e, -1) - w_u * action[..., 0] ** 2 + w_b * up


def task_rows(p: SwingUpTaskParams, q: np.ndarray, v: np.ndarray, action: np.ndarray) -> np.ndarray:
    """:func:`swingup_columns` batched over leading dimensions: shape ``(..., 9)``."""
    lead, (q2, v2, a2) = _as_columns(q, v, action)
    info = np.empty((9, q2.shape[1]))
    swingup_columns(q2, v2, a2, *p.kernel_arguments(), info)
    return info.T.reshape(lead + (9,))


def reward(
    p: SwingUpTaskParams, q: np.ndarray, v: np.ndarray, action: np.ndarray
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The reward ``(...)`` (module docstring) and its terms."""
    rows = task_rows(p, q, v, action)
    terms = {
        "reward_height": rows[..., 1],
        "reward_upright": rows[..., 2],
        "reward_effort": rows[..., 3],
        "reward_hold": rows[..., 8],
    }
    return rows[..., 0], terms


def info(p: SwingUpTaskParams, q: np.ndarray, v: np.ndarray, action: np.ndarray) -> dict[str, np.ndarray]:
    """The task's ``info``: the distance to upright ``tracking_error`` (..., 2), ``upright`` and the driven joint's ``power``."""
    rows = task_rows(p, q, v, action)
    return {"tracking_error": rows[..., 4:6], "upright": rows[..., 6].astype(bool), "power": rows[..., 7]}


class SwingUpEnv(MBSEnv):
    """Swing a 2R arm with one motor up from hanging and balance it upright (module docstring).

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: the driven joint's torque over ``torque_limit``.

    ## Observation Space

    ``Box((6,), float32)``: ``[cos th1, cos th2, sin th1, sin th2, dth1, dth2]``;
    :func:`decode_swingup`.

    ## Rewards

    ``r = w_h h - w_e |wrap(q - q_up)|^2 - w_u |action|^2 + w_b 1[upright]``,
    ``h = (sin th1 + sin(th1 + th2)) / 2``; default ``(1, 0.05, 0.01)`` and ``w_b`` 0 (v0) or 1 (v1);
    terms in ``info`` (``reward_height``, ``reward_upright``, ``reward_effort``, ``reward_hold``).

    ## Starting State

    Hanging: ``q0 = (-pi/2, 0) + U(-s, s)``, ``v0 = U(-s, s)`` with ``s = start_noise``
    (default 0.1, at most pi: then ``q0`` is uniform on the torus), or exactly
    ``reset(options={"q": ..., "v": ...})``. ``start_upright = p`` (default 0) starts a share ``p``
    of the episodes about upright instead, ``q0 = (pi/2, 0) + U(-s, s)``, and ``start_states = {"share": p,
    "rows": (K, 4) states}`` a share ``p`` of those that would hang from a row drawn uniformly (plus the same noise):
    training curricula (``scripts/train.py --train-env-kwargs``, ``--starts-from-plan``), not the task the
    evaluation scores.

    ## Episode End

    Truncation after ``max_episode_steps`` (1500: 15 s); termination only on
    divergence (``info["diverged"]``). An episode *succeeds* when both joints stay
    within ``upright_tolerance`` (default 0.1 rad) of upright for its last 2 s. The torque limits
    make a swing-up take several pumps of the arm.

    ## Arguments

    ``gym.make(id, params=None, torque_limit=..., dt=0.01, integrator="rk4", substeps=2,
    reward_weights=(1, 0.05, 0.01), hold_bonus=None, start_noise=0.1, start_upright=0.0, start_states=None, upright_tolerance=0.1, compiled=True, ...)``;
    ``params`` overrides :class:`~mbs_envs.models.planar2r.Planar2RParams` (Planar2R-v0's defaults:
    uniform 1 kg, 1 m rods, no friction).
    """

    step_kernel = staticmethod(step_kernel)
    #: the driven joint (0: shoulder, 1: elbow)
    driven: ClassVar[int]
    #: the scene's default torque limit [N m]
    default_torque_limit: ClassVar[float]

    reward_weights = check.Checked(lambda x, name: check.vector(x, name, 3, 0.0, broadcast=False))
    start_noise = check.Checked(lambda x, name: check.nonnegative(x, name, np.pi))
    start_upright = check.Checked(lambda x, name: check.real(x, name, 0.0, 1.0))
    upright_tolerance = check.Checked(lambda x, name: check.positive(x, name, np.pi))
    hold_bonus = check.Checked(lambda x, name: check.nonnegative(x, name, 1e6))
    #: the task's default hold bonus ``w_b`` (0 for v0: its reward is unchanged)
    default_hold_bonus: ClassVar[float] = 0.0

    def __init__(
        self,
        params: Mapping[str, Any] | None = None,
        torque_limit: Any = None,
        substeps: int | None = None,
        reward_weights: Any = (1.0, 0.05, 0.01),
        start_noise: float | None = None,
        start_upright: float = 0.0,
        upright_tolerance: float = 0.1,
        hold_bonus: Any = None,
        preset: str | None = None,
        start_states: Any = None,
        **kwargs: Any,
    ):
        given = {
            "params": params,
            "torque_limit": torque_limit,
            "substeps": substeps,
            "start_noise": start_noise,
            **kwargs,
        }
        kwargs = with_preset(preset, {k: v for k, v in given.items() if v is not None})
        params, torque_limit = kwargs.pop("params", None), kwargs.pop("torque_limit", self.default_torque_limit)
        substeps, start_noise = kwargs.pop("substeps", 2), kwargs.pop("start_noise", 0.1)
        #: the preset this env was built from (:mod:`mbs_envs.envs.presets`), or None
        self.preset = preset
        super().__init__(Planar2R(params, driven=(self.driven,)), torque_limit, substeps=substeps, **kwargs)
        self.reward_weights = reward_weights
        self.start_noise = start_noise
        self.start_upright = start_upright
        self.upright_tolerance = upright_tolerance
        self.hold_bonus = self.default_hold_bonus if hold_bonus is None else hold_bonus
        high = np.concatenate([np.ones(4), np.full(2, self.divergence_limit)]).astype(np.float32)
        self.observation_space = gym.spaces.Box(-high, high, dtype=np.float32)
        self._check_start_bound(np.pi / 2 + self.start_noise)
        self.start_states = start_states

    @property
    def start_states(self) -> StartBank | None:
        """Training starts from given states (:class:`StartBank`), or None (class docstring, Starting State)."""
        return self.__dict__.get("_start_states")

    @start_states.setter
    def start_states(self, value: Any) -> None:
        bank = start_bank(value, "start_states")  # refused before anything is stored
        if bank is not None:
            self._check_start_bound(float(np.abs(bank.rows).max()) + self.start_noise)
        self.__dict__["_start_states"] = bank
        check.touch(self)

    def _start_key(self) -> tuple:
        """The start settings, as a task cache's key holds them (the bank by identity: :class:`StartBank`)."""
        return (self.start_noise, self.start_upright, self.start_states)

    # -- the task: the module's functions with this env's parameters -----------------

    def _task_cache(self) -> tuple:
        """``(key, task_params, kernel arguments)``, built again only when a setting they hold changes."""
        key = (
            self.reward_weights.tobytes(),
            self.hold_bonus,
            self.u_max.tobytes(),
            self.upright_tolerance,
            self._start_key(),
        )
        cached = self.__dict__.get("_task_params")
        if cached is None or cached[0] != key:
            weights = np.append(self.reward_weights, self.hold_bonus)
            params = SwingUpTaskParams(
                weights, self.u_max, self.driven, self.upright_tolerance, self.start_noise, self.start_upright,
                self.start_states,
            )  # fmt: skip
            cached = self._task_params = (key, params, params.kernel_arguments())
        return cached

    @property
    def task_params(self) -> SwingUpTaskParams:
        """This env's task parameters, from its current settings."""
        return self._task_cache()[1]

    def _draw_states(self, task: Any, rngs: list, model: Planar2R) -> tuple[np.ndarray, np.ndarray]:
        return start(self.task_params, rngs)

    def observe(self, q, v, now, task) -> np.ndarray:
        return encode_swingup(q, v)

    @staticmethod
    def decode_observation(obs: np.ndarray) -> SwingUpObservation:
        """The state in an observation (batched); see :func:`decode_swingup`."""
        return decode_swingup(obs)

    def reward(self, q, v, now, task, u, action) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        return reward(self.task_params, q, v, action)

    def task_info(self, q, v, now, task, u) -> dict[str, Any]:
        return info(self.task_params, q, v, np.asarray(u, float) / self.u_max)

    # -- the compiled step (see mbs_envs.envs.engine) ----------------------------

    def task_arguments(self) -> tuple:
        return self._task_cache()[2]

    def task_layout(self) -> tuple[tuple[str, int | None, bool], ...]:
        names = ("reward", "reward_height", "reward_upright", "reward_effort")
        return tuple((k, None, False) for k in names) + (
            ("tracking_error", 2, False),
            ("upright", None, True),
            ("power", None, False),
            ("reward_hold", None, False),
        )

    # -- drawing ------------------------------------------------------------------

    def _render_extent(self) -> float:
        p = self.model.params
        return 1.1 * (p.l1 + p.l2)

    error_label = "distance to upright"

    def _drawing(self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: Any = None) -> list[Shape]:
        return arm_shapes(self.model.joint_positions(q), self.model.joint_positions(Q_UP), self._torque_arcs(u))


class AcrobotEnv(SwingUpEnv):
    """Acrobot (2R arm, only the elbow driven, 10 N m): swing up from hanging and balance upright.

    ## Description

    The Planar2R arm (uniform 1 kg, 1 m rods, no friction; ``docs/physics.md``) with a motor at the elbow only:
    the shoulder is passive. The arm starts hanging and must be swung up with a torque too small to lift it
    directly, then balanced upright. ``Acrobot-v1`` adds a bonus for holding within the success tolerance.

    ## Version History

    - v1: a hold bonus of 1 per step while both joints are within the success tolerance (``Acrobot-v1``).
    - v0: initial version (this id), kept registered.
    """

    step_kernel = staticmethod(step_kernel)  # declared per class: the same task (see MBSEnv.compiled)
    driven = 1
    default_torque_limit = 10.0


class PendubotEnv(SwingUpEnv):
    """Pendubot (2R arm, only the shoulder driven, 5 N m): swing up from hanging and balance upright.

    ## Description

    The Planar2R arm (uniform 1 kg, 1 m rods, no friction; ``docs/physics.md``) with a motor at the shoulder
    only: the elbow is passive. The arm starts hanging and must be swung up, then balanced upright.
    ``Pendubot-v1`` adds a bonus for holding within the success tolerance.

    ## Version History

    - v1: a hold bonus of 1 per step while both joints are within the success tolerance (``Pendubot-v1``).
    - v0: initial version (this id), kept registered.
    """

    step_kernel = staticmethod(step_kernel)
    driven = 0
    default_torque_limit = 5.0


class AcrobotV1Env(AcrobotEnv):
    """Acrobot (2R arm, only the elbow driven, 10 N m): swing up from hanging and balance, paid for holding upright.

    ## Rewards

    ``r = h - 0.05 |e|^2 - 0.01 a^2 + 1[|e_1| <= tol and |e_2| <= tol]`` with the tip's height
    ``h = (sin th1 + sin(th1 + th2)) / 2``, the error from upright ``e`` and the success tolerance ``tol``
    (0.1 rad): holding within the tolerance earns about twice what hovering just outside it does, so the return
    ranks a policy that stays up above one that swings through. The terms are in ``info``
    (``reward_height``, ``reward_upright``, ``reward_effort``, ``reward_hold``).

    ## Version History

    - v1: a hold bonus of 1 per step while both joints are within the success tolerance (this id).
    - v0: initial version (``Acrobot-v0``), kept registered.
    """

    step_kernel = staticmethod(step_kernel)
    default_hold_bonus = 1.0


class PendubotV1Env(PendubotEnv):
    """Pendubot (2R arm, only the shoulder driven, 5 N m): swing up from hanging and balance, paid for holding upright.

    ## Rewards

    As ``Acrobot-v1``'s: ``r = h - 0.05 |e|^2 - 0.01 a^2 + 1[|e_1| <= tol and |e_2| <= tol]``.

    ## Version History

    - v1: a hold bonus of 1 per step while both joints are within the success tolerance (this id).
    - v0: initial version (``Pendubot-v0``), kept registered.
    """

    step_kernel = staticmethod(step_kernel)
    default_hold_bonus = 1.0
