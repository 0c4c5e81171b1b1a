"""``mbs_envs/Acrobot-v2``, ``mbs_envs/Pendubot-v2`` (and the protocol plant's ``AcrobotDFKI-v2``,
``PendubotDFKI-v2``): the swing-up task paid for what success needs, reaching the region an upright LQR catches.

The v0/v1 reward pays for the tip's height; a policy can collect most of it with the arm swinging through upright
or, without friction, with the straight arm rotating about the shoulder (energy conserved, the tip above the line
once a turn). The v2 reward is a *rate* [1/s] integrated over the step (``r = dt * rate``, so the return of an
episode does not depend on the control step or on how long an agent holds its actions):

    rate = - w_e |e|^2 - w_v1 v1^2 - w_v2 v2^2 - w_u a^2 + w_line 1[h >= h_line] + w_region 1[x^T S x < c]
           + w_hold 1[|e_1| <= tol and |e_2| <= tol] - w_p |u v_d|

- ``e = wrap(q - q_up)`` the distance to upright [rad], ``v`` the rates [rad/s], ``a`` the normalized input;
- ``h = (l1 sin th1 + l2 sin(th1 + th2)) / (l1 + l2)`` the tip's height over the arm's reach (each arm's own
  lengths), ``h_line = 0.8``: a step toward upright that shaping alone pays for;
- ``x = (e, v)``; ``S`` the Riccati solution of the LQR about upright (:func:`~mbs_envs.envs.upright.upright_lqr`,
  ``Q = diag(10, 10, 1, 1)``, ``R = 1`` (N m)^-2) on the env's plant, ``c`` the level below which that LQR,
  saturated at the torque limit, catches every state (``region_level``; measured for each registered plant with
  :func:`mbs_envs.controllers.region.estimate_region`, checked by the tests). The region's bonus is what makes
  holding upright worth ten times passing through it, and it only pays where balancing is possible.
- ``tol`` the success tolerance (``upright_tolerance``, 0.1 rad): the region holds states at rest with the elbow
  bent a quarter radian (balanced with a steady torque), which the success rule does not count; the hold bonus
  pays for the centre the rule asks for.
- default weights ``(w_e, w_v1, w_v2, w_u, w_line, w_region, w_hold) = (5, 0.02, 0.015, 10, 50, 500, 500)`` per
  second: the velocity weights a few thousandths of the error's (a swing-up needs speed), the effort a fiftieth of
  the bonuses.
- ``w_p`` (an optional eighth weight [1/(W s)], 0 by default: the registered task leaves it out) charges the motor's
  mechanical power ``|u v_d|`` [W] (``u = a u_max`` the torque, ``v_d`` the driven joint's rate): over an episode
  the term is ``w_p`` times the energy the motor moves in or out of the arm, what the DFKI protocol's energy
  criterion sums (:func:`mbs_envs.studies.dfki.criteria`). Work done and then taken back (an arm pumped past what
  the swing-up needs and braked) is paid twice. Reward shaping for fine-tuning toward that criterion; its cost is
  folded into ``reward_effort``.

The observation, action, start, episode end and success rule are v1's (:mod:`mbs_envs.envs.swingup`); ``info``
holds the terms (``reward_upright``, ``reward_rates``, ``reward_effort``, ``reward_line``, ``reward_region``,
``reward_hold``, each ``dt`` times its rate), ``tracking_error``, ``upright`` and ``power``.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from .. import validation as check
from ..dynamics import compiled as _compiled
from ..dynamics.jit import njit
from ..dynamics.trig import sincos_columns, wrap
from ..models import planar2r as _model
from .engine import engine_step
from .swingup import AcrobotEnv, PendubotEnv, StartBank, SwingUpEnv, observe_columns, start
from .tracking import _as_columns
from .upright import upright_lqr

#: the LQR weights of the region's cost-to-go: ``Q`` on ``(e1, e2, v1, v2)`` and ``R`` [(N m)^-2]
REGION_Q = np.diag([10.0, 10.0, 1.0, 1.0])
REGION_R = np.eye(1)
#: ``(w_e, w_v1, w_v2, w_u, w_line, w_region, w_hold)`` [1/s] (module docstring); an eighth, ``w_p``, is optional
DEFAULT_WEIGHTS = (5.0, 0.02, 0.015, 10.0, 50.0, 500.0, 500.0)
#: the rows of the task kernel's ``info``
ROWS = 11


@njit
def region_columns(
    q, v, action, weights, line, S, level, reach, u_max, driven, tolerance, dt, info
):  # pragma: no cover - compiled
    """The v2 task's reward and ``info`` (module docstring) of a batch in columns.

    Parameters
    ----------
    q, v : ndarray, shape (2, B)
        Joint angles [rad] and rates [rad/s].
    action : ndarray, shape (1, B)
        Normalized input.
    weights : ndarray, shape (8,)
        ``(w_e, w_v1, w_v2, w_u, w_line, w_region, w_hold)`` [1/s] and ``w_p`` [1/(W s)].
    line : float
        ``h_line``, the tip's height over the reach that earns ``w_line``.
    S : ndarray, shape (4, 4)
        The upright LQR's cost-to-go matrix.
    level : float
        The region's level ``c``.
    reach : ndarray, shape (2,)
        ``(l1, l2) / (l1 + l2)``.
    u_max : ndarray, shape (1,)
        Torque limit [N m].
    driven : ndarray of int, shape (1,)
    tolerance : float
        Upright tolerance per joint [rad].
    dt : float
        Control step [s].
    info : ndarray, shape (>= 11, B)
        Written: ``(r, r_upright, r_rates, r_effort, e1, e2, upright, power, r_line, r_region, r_hold)`` in rows
        0-10.
    """
    B = q.shape[1]
    s, c = np.empty((2, B)), np.empty((2, B))
    for i in range(2):
        sincos_columns(q[i], s[i], c[i])
    for b in range(B):
        e1 = wrap(q[0, b] - np.pi / 2)
        e2 = wrap(q[1, b])
        v1, v2 = v[0, b], v[1, b]
        h = reach[0] * s[0, b] + reach[1] * (s[0, b] * c[1, b] + c[0, b] * s[1, b])
        a = action[0, b]
        x = (e1, e2, v1, v2)
        cost = 0.0
        for i in range(4):
            for j in range(4):
                cost += x[i] * S[i, j] * x[j]
        r_e = -dt * weights[0] * (e1 * e1 + e2 * e2)
        r_v = -dt * (weights[1] * v1 * v1 + weights[2] * v2 * v2)
        power = a * u_max[0] * v[driven[0], b]
        r_u = -dt * (weights[3] * a * a + weights[7] * abs(power))
        r_l = dt * weights[4] * (h >= line)
        r_c = dt * weights[5] * (cost < level)
        up = abs(e1) <= tolerance and abs(e2) <= tolerance
        r_b = dt * weights[6] * up
        info[0, b] = r_e + r_v + r_u + r_l + r_c + r_b
        info[1, b], info[2, b], info[3, b] = r_e, r_v, r_u
        info[4, b], info[5, b] = e1, e2
        info[6, b] = up
        info[7, b] = power
        info[8, b], info[9, b], info[10, b] = r_l, r_c, r_b


@njit
def region_task(q, v, t, action, task, obs, info, terminated):  # pragma: no cover - compiled
    """The task kernel (:mod:`mbs_envs.envs.engine`) of :class:`RegionTaskParams.kernel_arguments`; no termination."""
    weights, line, S, level, reach, u_max, driven, tolerance, dt = task
    region_columns(q, v, action, weights, line, S, level, reach, u_max, driven, tolerance, dt, info)
    observe_columns(q, v, obs)
    for b in range(q.shape[1]):
        terminated[b] = False


@njit
def step_kernel(theta, stepper, control, task, state, out):  # pragma: no cover - compiled
    """The compiled step of the v2 scenes: :func:`~mbs_envs.envs.engine.engine_step` with Planar2R's kernels."""
    engine_step(
        _model.advance_kernel,
        _model.energy_kernel,
        _compiled.no_constraint_info,
        _compiled.never_singular,
        _this.region_task,
        theta,
        stepper,
        control,
        task,
        state,
        out,
    )


_this = sys.modules[__name__]


@dataclasses.dataclass(frozen=True)
class RegionTaskParams:
    """The v2 task's parameters (module docstring), explicit and immutable.

    Attributes
    ----------
    weights : ndarray, shape (7,) or (8,)
        ``(w_e, w_v1, w_v2, w_u, w_line, w_region, w_hold)`` [1/s] and optionally ``w_p`` [1/(W s)] (0 when left
        out).
    line : float
        ``h_line``.
    S : ndarray, shape (4, 4)
        The upright LQR's cost-to-go matrix on the env's plant.
    level : float
        The region's level ``c``.
    reach : ndarray, shape (2,)
        ``(l1, l2) / (l1 + l2)``.
    u_max : ndarray, shape (1,)
        [N m].
    driven : int
    tolerance : float
        Upright tolerance per joint [rad] (``info["upright"]``, the success rule).
    dt : float
        Control step [s].
    start_noise, start_upright : float
        As :class:`~mbs_envs.envs.swingup.SwingUpTaskParams`'s (the same starts).
    start_bank : StartBank or None
        As :class:`~mbs_envs.envs.swingup.SwingUpTaskParams`'s.
    """

    weights: np.ndarray
    line: float
    S: np.ndarray
    level: float
    reach: np.ndarray
    u_max: np.ndarray
    driven: int
    tolerance: float
    dt: float
    start_noise: float
    start_upright: float = 0.0
    start_bank: StartBank | None = None

    def kernel_arguments(self) -> tuple:
        """The task kernel's arguments, as :func:`region_columns` takes them after ``action`` (the weights padded
        to eight with ``w_p = 0``)."""
        w = np.zeros(8)
        w[: len(self.weights)] = self.weights
        return (
            w,
            float(self.line),
            np.ascontiguousarray(self.S, float),
            float(self.level),
            np.array(self.reach, float),
            np.array(self.u_max, float),
            np.array([self.driven], np.int64),
            float(self.tolerance),
            float(self.dt),
        )


def weights_7_or_8(x: Any, name: str) -> np.ndarray:
    """The v2 reward's weights: seven, or eight with ``w_p`` last (module docstring), each finite and >= 0."""
    w = check.reals(x, name)
    if w.shape not in ((7,), (8,)):
        raise ValueError(f"{name} must have shape (7,) or (8,) (w_p last), got shape {w.shape}")
    return check.vector(w, name, w.shape[0], 0.0, broadcast=False)


def task_rows(p: RegionTaskParams, q: np.ndarray, v: np.ndarray, action: np.ndarray) -> np.ndarray:
    """:func:`region_columns` batched over leading dimensions: shape ``(..., 11)``."""
    lead, (q2, v2, a2) = _as_columns(q, v, action)
    info = np.empty((ROWS, q2.shape[1]))
    region_columns(q2, v2, a2, *p.kernel_arguments(), info)
    return info.T.reshape(lead + (ROWS,))


#: the reward's terms: name -> row of :func:`region_columns`' ``info``
TERMS = {
    "reward_upright": 1,
    "reward_rates": 2,
    "reward_effort": 3,
    "reward_line": 8,
    "reward_region": 9,
    "reward_hold": 10,
}


class SwingUpV2Env(SwingUpEnv):
    """Swing a 2R arm with one motor up from hanging and balance it, paid for reaching what an LQR catches
    (:mod:`mbs_envs.envs.swingup_v2`).

    ## Rewards

    ``r = dt * (-w_e |e|^2 - w_v1 v1^2 - w_v2 v2^2 - w_u a^2 + w_line 1[h >= 0.8] + w_region 1[x^T S x < c]
    + w_hold 1[upright])`` (module docstring): default ``(5, 0.02, 0.015, 10, 50, 500, 500)`` per second; ``S`` the
    upright LQR's cost-to-go on the env's plant, ``c`` the ``region_level``, ``upright`` both joints within
    ``upright_tolerance``; terms in ``info``.

    ## Arguments

    As v1's, with ``reward_weights`` the seven rates above (or eight: ``w_p`` last, the optional power term
    ``- w_p |u v_d|``, folded into ``reward_effort``), ``line_height=0.8`` and ``region_level=None`` (the registered
    plant's measured level; for another plant or torque limit, measure it with
    :func:`mbs_envs.controllers.region.estimate_region` and pass it). ``hold_bonus`` is ``reward_weights[6]`` here.
    """

    step_kernel = staticmethod(step_kernel)
    reward_weights = check.Checked(weights_7_or_8)
    line_height = check.Checked(lambda x, name: check.real(x, name, -1.0, 1.0))
    region_level = check.Checked(lambda x, name: check.nonnegative(x, name, 1e12))
    #: the measured region level of the scene's plant by preset (None: the scene's own plant)
    default_region_levels: ClassVar[Mapping[str | None, float]]

    def __init__(
        self,
        params: Mapping[str, Any] | None = None,
        torque_limit: Any = None,
        substeps: int | None = None,
        reward_weights: Any = DEFAULT_WEIGHTS,
        start_noise: float | None = None,
        start_upright: float = 0.0,
        upright_tolerance: float = 0.1,
        line_height: float = 0.8,
        region_level: float | None = None,
        preset: str | None = None,
        **kwargs: Any,
    ):
        if "hold_bonus" in kwargs:
            raise ValueError("hold_bonus: the v2 reward has its hold bonus in reward_weights[6] (a rate, per second)")
        levels = self.default_region_levels
        if region_level is None and preset not in levels:
            raise ValueError(f"region_level: no measured level for preset {preset!r}; pass region_level")
        self.line_height = line_height
        self.region_level = levels[preset] if region_level is None else region_level
        super().__init__(params, torque_limit, substeps, reward_weights, start_noise, start_upright, upright_tolerance,
                         preset=preset, **kwargs)  # fmt: skip

    def _task_cache(self) -> tuple:
        """``(key, task_params, kernel arguments)``, built again only when a setting they hold changes."""
        key = (
            self.reward_weights.tobytes(),
            self.line_height,
            self.region_level,
            self.u_max.tobytes(),
            self.upright_tolerance,
            self._start_key(),
            self.dt,
        )
        cached = self.__dict__.get("_task_params")
        if cached is None or cached[0] != key:
            if "_region_S" not in self.__dict__:  # the plant is fixed at construction (MBSEnv.model)
                self._region_S = upright_lqr(self.model, REGION_Q, REGION_R)[1]
            p = self.model.params
            params = RegionTaskParams(
                self.reward_weights, self.line_height, self._region_S, self.region_level,
                np.array([p.l1, p.l2]) / (p.l1 + p.l2), self.u_max, self.driven, self.upright_tolerance, self.dt,
                self.start_noise, self.start_upright, self.start_states,
            )  # fmt: skip
            cached = self._task_params = (key, params, params.kernel_arguments())
        return cached

    @property
    def task_params(self) -> RegionTaskParams:  # type: ignore[override]
        """This env's task parameters, from its current settings."""
        return self._task_cache()[1]

    def _draw_states(self, task: Any, rngs: list, model: Any) -> tuple[np.ndarray, np.ndarray]:
        return start(self.task_params, rngs)

    def reward(self, q, v, now, task, u, action) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        rows = task_rows(self.task_params, q, v, action)
        return rows[..., 0], {name: rows[..., i] for name, i in TERMS.items()}

    def task_info(self, q, v, now, task, u) -> dict[str, Any]:
        rows = task_rows(self.task_params, q, v, np.asarray(u, float) / self.u_max)
        return {"tracking_error": rows[..., 4:6], "upright": rows[..., 6].astype(bool), "power": rows[..., 7]}

    def task_layout(self) -> tuple[tuple[str, int | None, bool], ...]:
        return (
            ("reward", None, False),
            ("reward_upright", None, False),
            ("reward_rates", None, False),
            ("reward_effort", None, False),
            ("tracking_error", 2, False),
            ("upright", None, True),
            ("power", None, False),
            ("reward_line", None, False),
            ("reward_region", None, False),
            ("reward_hold", None, False),
        )


class AcrobotV2Env(SwingUpV2Env, AcrobotEnv):
    """Acrobot (2R arm, only the elbow driven, 10 N m): swing up from hanging and balance, paid for reaching what an
    LQR catches.

    ## Description

    The Planar2R arm (uniform 1 kg, 1 m rods, no friction; ``docs/physics.md``) with a motor at the elbow only: the
    shoulder is passive. The arm starts hanging and must be swung up with a torque too small to lift it directly,
    then balanced upright. The task and its success rule are ``Acrobot-v1``'s; the reward pays for reaching and
    staying in the region an upright LQR catches, the bonus an agent can only keep by balancing.

    ## Rewards

    ``r = dt * (-5 |e|^2 - 0.02 v1^2 - 0.015 v2^2 - 10 a^2 + 50 * 1[h >= 0.8] + 500 * 1[x^T S x < c]
    + 500 * 1[upright])`` (:mod:`mbs_envs.envs.swingup_v2`): the tip above 0.8 of the reach, and above all the
    region the upright LQR catches and the success tolerance, pay; distance, speed and effort cost. Terms in
    ``info`` (``reward_upright``, ``reward_rates``, ``reward_effort``, ``reward_line``, ``reward_region``,
    ``reward_hold``).

    ## Version History

    - v2: the reward above (this id): the height reward of v0/v1 pays for an arm swinging through upright or
      rotating about the shoulder; this one for what the success rule asks, holding upright.
    - v1: a hold bonus of 1 per step while both joints are within the success tolerance (``Acrobot-v1``), kept.
    - v0: initial version (``Acrobot-v0``), kept registered.
    """

    step_kernel = staticmethod(step_kernel)
    default_region_levels = {None: 0.85, "dfki_c1": 1.6}


class PendubotV2Env(SwingUpV2Env, PendubotEnv):
    """Pendubot (2R arm, only the shoulder driven, 5 N m): swing up from hanging and balance, paid for reaching what
    an LQR catches.

    ## Description

    The Planar2R arm (uniform 1 kg, 1 m rods, no friction; ``docs/physics.md``) with a motor at the shoulder only:
    the elbow is passive. The task and its success rule are ``Pendubot-v1``'s; the reward is ``Acrobot-v2``'s.

    ## Rewards

    As ``Acrobot-v2``'s (:mod:`mbs_envs.envs.swingup_v2`), with the pendubot's own LQR region.

    ## Version History

    - v2: the reward of ``Acrobot-v2`` (this id).
    - v1: a hold bonus of 1 per step while both joints are within the success tolerance (``Pendubot-v1``), kept.
    - v0: initial version (``Pendubot-v0``), kept registered.
    """

    step_kernel = staticmethod(step_kernel)
    default_region_levels = {None: 1.6, "dfki_c1": 1.9}
