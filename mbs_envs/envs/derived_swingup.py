"""Swing-up on a derived underactuated model: a user's mechanism, its upright and hanging configurations.

A mechanism derived by :func:`mbs_envs.models.symbolic.derive` with fewer inputs than coordinates (an
``actuation`` matrix that selects the driven ones) becomes a swing-up task in a few lines::

    model = symbolic.derive("CartPole", [x, th], T, V, params, actuation=[[1], [0]], damping={x: "b_x", th: "b_th"})
    derived.register("my/CartPoleSwingUp-v0", model, task="swing-up", torque_limit=10.0, upright=[0, 0],
                     hanging=[0, pi], angles=[th], bounds={x: (-2.4, 2.4)}, coordinates=[x, th], points=[...])

The task, written once for every such mechanism (``n`` coordinates, of which ``angles`` are revolute and the rest
linear, ``nu`` inputs):

- the error ``e_i = q_i - q_up,i``, wrapped to ``[-pi, pi)`` for the angles;
- the height ``h = 2 (V(q) - V_down) / (V_up - V_down) - 1``: the potential energy between the hanging
  (``-1``) and the upright (``+1``) configuration's, at the env's parameters (the model's own ``V``, so no
  height function to write; ``V_up > V_down`` is required);
- reward ``r = w_h h - w_e |e|^2 - w_u |action|^2 + w_b 1[upright] + r_x`` with ``(w_h, w_e, w_u) = (1, 0.05, 0.01)``
  and the hold bonus ``w_b = 1`` by default; ``upright`` is every angle within ``upright_tolerance`` of its
  upright value (linear coordinates, e.g. a cart's position, do not count);
- ``bounds`` on linear coordinates (a rail's ends): leaving them *terminates* the episode with
  ``r_x = -P k_left``, ``k_left`` the control steps left to ``horizon`` and ``P`` the largest loss one step
  inside the bounds can cost (``w_h + w_e sum_i max e_i^2 + w_u nu``): an episode that runs off the rail scores
  no more than one that stays on it, whatever it does there (a failed episode never improves a return);
- observation ``[cos q_angles, sin q_angles, q_linear, v]``;
- ``info``: the reward terms (``reward_height``, ``reward_upright``, ``reward_effort``, ``reward_hold``,
  ``reward_bound``), ``tracking_error`` (the angles' errors: the distance to upright the evaluation scores),
  ``upright``, ``power = sum_k u_k v_k`` [W] of the driven coordinates and ``out_of_bounds``.

Starts: ``q0 = hanging + U(-s, s)``, ``v0 = U(-s, s)`` with ``s = start_noise``. Stepped by the compiled engine
with the model's generated kernels (its ``swingup_step_kernel``: the generated potential energy, then
:func:`swingup_columns`), single and batched; the drawing is the named points' line, the upright configuration
as the ghost (at the current linear coordinates).
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from .. import validation as check
from ..dynamics.jit import njit
from ..dynamics.trig import sincos_columns, wrap
from ..models.symbolic import DerivedModel
from .base import MBSEnv
from .derived import NamedPoints, coordinate_index
from .draws import uniform_of
from .rendering import Shape, arm_shapes
from .swingup import SwingUpObservation
from .tracking import _as_columns

#: the task's ``info`` rows before ``tracking_error`` (reward and its terms)
TERMS = ("reward", "reward_height", "reward_upright", "reward_effort", "reward_hold", "reward_bound")


@njit
def swingup_columns(q, v, t, action, V, task, obs, info, terminated):  # pragma: no cover - compiled
    """The task kernel's body (module docstring) for a batch in columns, given the potential energy ``V``.

    Parameters
    ----------
    q, v : ndarray, shape (n, B)
        Coordinates [rad or m] and rates.
    t : ndarray, shape (B,)
        Time after the step [s].
    action : ndarray, shape (nu, B)
        Normalized inputs.
    V : ndarray, shape (B,)
        Potential energy [J] at ``q``.
    task : tuple
        :meth:`SwingUpTask.kernel_arguments` (its first entry, the parameters, is the caller's).
    obs : ndarray, float32, shape (2 n_a + n_l + n, B)
        Written: ``[cos q_a, sin q_a, q_l, v]``.
    info : ndarray, shape (>= 9 + n_a, B)
        Written: the rows of :data:`TERMS`, ``tracking_error`` (n_a), ``upright``, ``power``, ``out_of_bounds``.
    terminated : ndarray of bool, shape (B,)
        Written: out of bounds.
    """
    _, weights, q_up, angle, low, high, V_range, tol, u_max, actuated, horizon, dt, loss = task
    n, B = q.shape
    na = 0
    for i in range(n):
        na += angle[i]
    nl = n - na
    sn, cs = np.empty(B), np.empty(B)
    ka = 0
    for i in range(n):  # the angles' cosines and sines: one SIMD pass per angle (mbs_envs.dynamics.trig)
        if angle[i]:
            sincos_columns(q[i], sn, cs)
            for b in range(B):
                obs[ka, b] = cs[b]
                obs[na + ka, b] = sn[b]
            ka += 1
    for b in range(B):
        e2, up, out = 0.0, True, False
        ka, kl = 0, 0
        for i in range(n):
            x = q[i, b]
            if angle[i]:
                e = wrap(x - q_up[i])
                up &= abs(e) <= tol
                info[6 + ka, b] = e
                ka += 1
            else:
                e = x - q_up[i]
                obs[2 * na + kl, b] = x
                kl += 1
            out |= (x < low[i]) | (x > high[i])
            e2 += e * e
            obs[2 * na + nl + i, b] = v[i, b]
        a2, power = 0.0, 0.0
        for k in range(action.shape[0]):
            a = action[k, b]
            a2 += a * a
            power += a * u_max[k] * v[actuated[k], b]
        h = 2.0 * (V[b] - V_range[0]) / (V_range[1] - V_range[0]) - 1.0
        r_h, r_e, r_u, r_b = weights[0] * h, -weights[1] * e2, -weights[2] * a2, weights[3] * up
        left = max(horizon - np.rint(t[b] / dt), 0.0)
        r_x = -loss * left if out else 0.0
        info[0, b] = r_h + r_e + r_u + r_b + r_x
        info[1, b], info[2, b], info[3, b], info[4, b], info[5, b] = r_h, r_e, r_u, r_b, r_x
        info[6 + na, b] = up
        info[7 + na, b] = power
        info[8 + na, b] = out
        terminated[b] = out


@dataclasses.dataclass(frozen=True)
class SwingUpTask:
    """The derived swing-up task's parameters (module docstring), explicit and immutable.

    Attributes
    ----------
    weights : ndarray, shape (4,)
        ``(w_h, w_e, w_u, w_b)``.
    upright, hanging : ndarray, shape (n,)
        The goal and the starts' centre [rad or m].
    angle : ndarray of bool, shape (n,)
        Which coordinates are angles (wrapped, observed by cos and sin).
    low, high : ndarray, shape (n,)
        Bounds (infinite where none).
    V_range : ndarray, shape (2,)
        ``(V_down, V_up)`` [J].
    tolerance : float
        Upright tolerance per angle [rad].
    u_max : ndarray, shape (nu,)
    actuated : ndarray of int, shape (nu,)
        The coordinate each input drives.
    horizon : int
        The episode's length in control steps (the bound's penalty counts the steps left to it).
    dt : float
        Control step [s].
    start_noise : float
    """

    weights: np.ndarray
    upright: np.ndarray
    hanging: np.ndarray
    angle: np.ndarray
    low: np.ndarray
    high: np.ndarray
    V_range: np.ndarray
    tolerance: float
    u_max: np.ndarray
    actuated: np.ndarray
    horizon: int
    dt: float
    start_noise: float

    @property
    def step_loss(self) -> float:
        """The largest loss of one step inside the bounds, ``w_h + w_e sum_i max e_i^2 + w_u nu`` (the angles' ``max e^2``
        is ``pi^2``, a bounded coordinate's the square of its bound's farthest end from upright)."""
        span = np.where(
            self.angle, np.pi, np.maximum(np.abs(self.low - self.upright), np.abs(self.high - self.upright))
        )
        w_h, w_e, w_u, _ = self.weights
        return float(w_h + w_e * np.sum(span**2) + w_u * len(self.u_max))

    def kernel_arguments(self, theta: np.ndarray) -> tuple:
        """The task kernel's tuple, ``theta (P, 1)`` the parameters its potential energy is evaluated at."""
        return (np.ascontiguousarray(theta, float).reshape(-1, 1), np.array(self.weights, float), np.array(self.upright, float),
                np.array(self.angle, np.int64), np.array(self.low, float), np.array(self.high, float),
                np.array(self.V_range, float), float(self.tolerance), np.array(self.u_max, float),
                np.array(self.actuated, np.int64), float(self.horizon), float(self.dt), self.step_loss)  # fmt: skip


def task_rows(p: SwingUpTask, model: DerivedModel, q, v, t, action) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`swingup_columns` batched over leading dimensions (the numpy path; ``V`` from ``model``'s numpy terms):
    ``(info (..., 9 + n_a), obs (..., obs_dim), terminated (...))``."""
    lead, (q2, v2, a2, t2) = _as_columns(q, v, action, np.asarray(t, float)[..., None])
    n, B = q2.shape
    na = int(np.sum(p.angle))
    info, obs, term = np.empty((9 + na, B)), np.empty((2 * na + (n - na) + n, B), np.float32), np.empty(B, bool)
    V = np.ascontiguousarray(model.potential_energy(q2.T), float).reshape(B)
    swingup_columns(q2, v2, t2[0], a2, V, p.kernel_arguments(model.kernel_params()), obs, info, term)
    return info.T.reshape(lead + (9 + na,)), obs.T.reshape(lead + (obs.shape[0],)), term.reshape(lead)


class DerivedSwingUpEnv(NamedPoints, MBSEnv):
    """Swing a derived underactuated mechanism up from hanging and balance it (module docstring).

    ## Action Space

    ``Box(-1, 1, (nu,), float32)``: the inputs over ``torque_limit``.

    ## Observation Space

    ``Box((2 n_a + n_l + n,), float32)``: ``[cos q_angles, sin q_angles, q_linear, v]``.

    ## Rewards

    ``r = w_h h - w_e |e|^2 - w_u |action|^2 + w_b 1[upright] + r_x`` (module docstring).

    ## Episode End

    Truncation after ``max_episode_steps``; termination on leaving ``bounds`` or on divergence.

    Parameters
    ----------
    model : DerivedModel
        Unconstrained, its actuation selecting ``nu < n`` driven coordinates.
    torque_limit : float or array_like
        Per input [N m or N].
    upright, hanging : array_like, shape (n,)
        The goal and the starts' centre; ``V(upright) > V(hanging)``.
    angles : sequence, optional
        The revolute coordinates (entries of ``coordinates`` or indices; default every coordinate).
    bounds : mapping, optional
        A linear coordinate -> ``(low, high)`` [m]: leaving it ends the episode.
    reward_weights : (w_h, w_e, w_u)
    hold_bonus : float
        ``w_b``.
    upright_tolerance : float
        [rad].
    start_noise : float
        ``s`` [rad, m, or per second].
    horizon : int
        Control steps of an episode (``register`` sets it to ``max_episode_steps``; ``gym.make(id,
        max_episode_steps=k)`` leaves it, so pass ``horizon=k`` too: a longer horizon only makes leaving the bounds
        cost more, never less).
    coordinates, points, params, **kwargs
        As :class:`~mbs_envs.envs.derived.DerivedTrackingEnv`'s.
    """

    @property
    def step_kernel(self) -> Any:
        """The compiled step: the derived model's generated binding of the engine to its kernels and this task's."""
        return type(self.model).generated.swingup_step_kernel

    reward_weights = check.Checked(lambda x, name: check.vector(x, name, 3, 0.0, broadcast=False))
    hold_bonus = check.Checked(lambda x, name: check.nonnegative(x, name, 1e6))
    upright_tolerance = check.Checked(lambda x, name: check.positive(x, name, np.pi))
    start_noise = check.Checked(lambda x, name: check.nonnegative(x, name, np.pi))
    horizon = check.Checked(lambda x, name: check.integer(x, name, 1, 10**9))
    error_label = "distance to upright"

    def __init__(self, model: DerivedModel, torque_limit: Any, upright: Any, hanging: Any, angles: Sequence[Any] | None = None,
                 bounds: Mapping[Any, Any] | None = None, reward_weights: Any = (1.0, 0.05, 0.01), hold_bonus: float = 1.0,
                 upright_tolerance: float = 0.1, start_noise: float = 0.1, horizon: int = 1000, coordinates: Sequence[Any] = (),
                 points: Sequence[Any] = (), params: Any = None, **kwargs: Any):  # fmt: skip
        if not isinstance(model, DerivedModel):
            raise ValueError(f"model must be a model from mbs_envs.models.symbolic.derive, got {type(model).__name__}")
        if model.nc:
            raise ValueError(
                "the swing-up task takes an unconstrained model (this one has constraints): use the tracking task"
            )
        if params is not None:
            model = type(model)(check.mapping(params, "params"))
        n = model.nq
        if model.nu >= n:
            raise ValueError(
                f"the swing-up task is for underactuated models: this one drives {model.nu} of its {n} coordinates (pass actuation= to derive)"
            )
        self.set_points(n, coordinates, points)
        self.upright = check.vector(upright, "upright", n, broadcast=False)
        self.hanging = check.vector(hanging, "hanging", n, broadcast=False)
        angle = np.ones(n, bool) if angles is None else np.zeros(n, bool)
        for c in angles or ():
            angle[coordinate_index(c, self._coordinates, n, "angles")] = True
        self.angle = angle
        self.low, self.high = np.full(n, -np.inf), np.full(n, np.inf)
        if bounds is not None and not isinstance(bounds, Mapping):
            raise ValueError(f"bounds must be a mapping of coordinates to (low, high), got {type(bounds).__name__}")
        for c, lim in (bounds or {}).items():
            i = coordinate_index(c, self._coordinates, n, "bounds")
            if angle[i]:
                raise ValueError(f"bounds: coordinate {c} is an angle (bounds apply to linear coordinates)")
            low, high = check.vector(lim, f"bounds[{c}]", 2, broadcast=False)
            if not low < self.upright[i] < high or not low < self.hanging[i] < high:
                raise ValueError(f"bounds[{c}] = {lim!r} must hold the upright and hanging values strictly inside")
            self.low[i], self.high[i] = low, high
        super().__init__(model, torque_limit, **kwargs)
        self.reward_weights = reward_weights
        self.hold_bonus = hold_bonus
        self.upright_tolerance = upright_tolerance
        self.start_noise = start_noise
        self.horizon = horizon
        V_down, V_up = (float(model.potential_energy(q)) for q in (self.hanging, self.upright))
        if not V_up > V_down:
            raise ValueError(
                f"upright must have more potential energy than hanging: V(upright) = {V_up:.6g} J, V(hanging) = {V_down:.6g} J"
            )
        self.V_range = np.array([V_down, V_up])
        B = model.actuation
        self.actuated = np.argmax(B, axis=0).astype(np.int64)
        # a linear coordinate's observation may leave its bounds (the step that ends the episode there)
        high = np.concatenate(
            [np.ones(2 * int(angle.sum())), np.full(2 * n - int(angle.sum()), self.divergence_limit)]
        ).astype(np.float32)
        self.observation_space = gym.spaces.Box(-high, high, dtype=np.float32)
        self._check_start_bound(float(np.max(np.abs(self.hanging))) + self.start_noise)
        reach = (self.hanging - self.start_noise < self.low) | (self.hanging + self.start_noise > self.high)
        if np.any(reach):
            i = int(np.argmax(reach))
            raise ValueError(
                f"start_noise = {self.start_noise:g} reaches beyond bounds of coordinate {i} ({self.low[i]:g}, {self.high[i]:g}) "
                f"from hanging = {self.hanging[i]:g}: sampled starts would be refused"
            )

    # -- the task ------------------------------------------------------------------------------

    def _task_cache(self) -> tuple:
        """``(key, task_params, kernel arguments)``, built again only when a setting they hold changes (a step reads
        them; building them is most of a single step's Python time)."""
        key = (self.reward_weights.tobytes(), self.hold_bonus, self.u_max.tobytes(), self.upright_tolerance, self.start_noise,
               self.horizon, self.dt, self.model.kernel_params().tobytes())  # fmt: skip
        cached = self.__dict__.get("_task_params")
        if cached is None or cached[0] != key:
            p = SwingUpTask(np.append(self.reward_weights, self.hold_bonus), self.upright, self.hanging, self.angle, self.low,
                            self.high, self.V_range, self.upright_tolerance, self.u_max, self.actuated, self.horizon, self.dt,
                            self.start_noise)  # fmt: skip
            cached = self._task_params = (key, p, p.kernel_arguments(self.model.kernel_params()))
        return cached

    @property
    def task_params(self) -> SwingUpTask:
        """This env's task parameters, from its current settings."""
        return self._task_cache()[1]

    def _draw_states(self, task: Any, rngs: list, model: Any) -> tuple[np.ndarray, np.ndarray]:
        s, n = self.start_noise, model.nq
        noise = uniform_of(np.array([rng.random(2 * n) for rng in rngs]), -s, s)  # :mod:`mbs_envs.envs.draws`
        return self.hanging + noise[:, :n], noise[:, n:]

    def _check_start(self, q0: np.ndarray, v0: np.ndarray, task: Any, given: bool) -> np.ndarray:
        """The base rule (finite, within ``divergence_limit``, observable), and inside ``bounds``."""
        obs = super()._check_start(q0, v0, task, given)
        out = np.any((np.asarray(q0) < self.low) | (np.asarray(q0) > self.high), axis=-1)
        if np.any(out):
            i = np.unravel_index(np.argmax(out), out.shape) if out.ndim else ()
            source = "the start state given in options" if given else "a sampled start state"
            raise ValueError(
                f"{source} (q = {np.asarray(q0)[i].tolist()}) is outside bounds (low {self.low.tolist()}, high {self.high.tolist()})"
            )
        return obs

    def task_now(self, t: np.ndarray, task: Any) -> np.ndarray:
        return np.asarray(t, float)

    def _rows(self, q, v, now, action) -> tuple:
        return task_rows(self.task_params, self.model, q, v, np.broadcast_to(now, np.shape(q)[:-1]), action)

    def observe(self, q, v, now, task) -> np.ndarray:
        return self._rows(q, v, now, np.zeros(np.shape(q)[:-1] + (self.model.nu,)))[1]

    def reward(self, q, v, now, task, u, action) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        info = self._rows(q, v, now, action)[0]
        return info[..., 0], {k: info[..., i] for i, k in enumerate(TERMS) if i}

    def terminated(self, q, v, now, task) -> np.ndarray:
        return self._rows(q, v, now, np.zeros(np.shape(q)[:-1] + (self.model.nu,)))[2]

    def decode_observation(self, obs: np.ndarray) -> SwingUpObservation:
        """The state in an observation (batched): angles by ``atan2(sin, cos)`` in ``[-pi, pi]``, linear coordinates as
        observed."""
        obs = np.asarray(obs, float)
        n, na = self.model.nq, int(self.angle.sum())
        if obs.shape[-1:] != self.observation_space.shape:
            raise ValueError(f"observation must have shape (..., {self.observation_space.shape[0]}), got {obs.shape}")
        q = np.empty(obs.shape[:-1] + (n,))
        q[..., self.angle] = np.arctan2(obs[..., na : 2 * na], obs[..., :na])
        q[..., ~self.angle] = obs[..., 2 * na : n + na]
        return SwingUpObservation(q=q, v=obs[..., n + na :])

    def task_info(self, q, v, now, task, u) -> dict[str, Any]:
        info = self._rows(q, v, now, np.asarray(u, float) / self.u_max)[0]
        na = int(self.angle.sum())
        return {"tracking_error": info[..., 6:6 + na], "upright": info[..., 6 + na].astype(bool), "power": info[..., 7 + na],
                "out_of_bounds": info[..., 8 + na].astype(bool)}  # fmt: skip

    # -- the compiled step (see mbs_envs.envs.engine) ------------------------------------------

    def task_arguments(self) -> tuple:
        return self._task_cache()[2]

    def task_layout(self) -> tuple[tuple[str, int | None, bool], ...]:
        return tuple((k, None, False) for k in TERMS) + (
            ("tracking_error", int(self.angle.sum()), False),
            ("upright", None, True),
            ("power", None, False),
            ("out_of_bounds", None, True),
        )

    # -- drawing -------------------------------------------------------------------------------

    def _frame_configurations(self) -> np.ndarray:
        """Upright and hanging, with every bounded coordinate at each of its ends."""
        ends = [
            (self.low[i], self.high[i]) if np.isfinite(self.low[i]) else (self.upright[i],)
            for i in range(self.model.nq)
        ]
        out = []
        for q in (self.upright, self.hanging):
            for corner in itertools.product(*ends):
                out.append(np.where(np.isfinite(self.low), corner, q))
        return np.array(out)

    def _drawing(self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: Any = None) -> list[Shape]:
        ghost = np.where(self.angle, self.upright, q)  # upright where the mechanism stands now
        return arm_shapes(self.draw_points(q), self.draw_points(ghost), ())
