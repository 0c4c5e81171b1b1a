"""A swing-up designed offline for a protocol's score: a smooth feedforward torque, stabilized by time-varying LQR
along its nominal trajectory, then the upright LQR (Acrobot, Pendubot; the DFKI protocol ids).

The design (:mod:`mbs_envs.studies.dfki_swingup` searches it) is the driven joint's torque at knots ``knot_dt``
apart from the start at rest hanging, interpolated by a cubic spline at the control steps (a smooth input: the
protocol scores the torque's smoothness) and held within the torque limit. On the nominal model this input gives
the planned trajectory ``X``; the controller applies

    u_k = U_k + K_k wrap(x_k - X_k)      for k < N (the plan's steps),
    u_k = -K_up wrap(x_k - x_up)          after,

with ``K_k`` the time-varying LQR along ``(X, U)`` (:func:`controllers.trajectory.tvlqr`, weights ``Q``, ``track_r``,
terminal the upright LQR's ``S``) and ``K_up`` the upright LQR. On the nominal plant the feedback terms are zero
along the plan (the same trajectory), so the protocol's score is the design's; off nominal they hold the arm to it.
The controller's memory (the step since the episode's start) is kept in SB3's ``state``.
"""

from __future__ import annotations

import json
import pathlib
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from mbs_envs import validation as check
from mbs_envs.dynamics.jit import njit
from mbs_envs.envs.swingup import Q_DOWN, Q_UP, SwingUpEnv

from . import trajectory as traj
from .base import Controller
from .swingup import upright_lqr, wrap_angle

#: the designs shipped with the package (``scripts/dfki.py --design``), by env id
DESIGNS = pathlib.Path(__file__).with_name("scored_swingup.json")


def feedforward(knots: np.ndarray, knot_dt: float, dt: float, u_max: float) -> np.ndarray:
    """The torque at the control steps ``k dt``, ``k < N = round((len(knots) - 1) knot_dt / dt)``: the cubic spline
    through ``(i knot_dt, knots[i])`` (natural ends), clipped to ``[-u_max, u_max]``; shape ``(N,)``."""
    knots = np.asarray(knots, float)
    n = int(round((len(knots) - 1) * knot_dt / dt))
    t = np.arange(n) * dt
    spline = CubicSpline(np.arange(len(knots)) * knot_dt, knots, bc_type="natural")
    return np.clip(spline(t), -u_max, u_max)


@njit
def closed_loop(U, K, goal, u_max, driven, theta, dt, substeps, steps, X, u):  # pragma: no cover - compiled
    """The nominal episode of a design: ``U`` (N,) from hanging at rest, then the upright LQR ``u = -K wrap(x -
    goal)`` clipped to ``u_max``, for ``steps`` control steps in all; writes the states ``X`` (steps, 4) at each
    step's start and the inputs ``u`` (steps,)."""
    x0, x1, x2, x3 = X[0, 0], X[0, 1], X[0, 2], X[0, 3]
    for k in range(steps):
        X[k, 0], X[k, 1], X[k, 2], X[k, 3] = x0, x1, x2, x3
        if k < U.shape[0]:
            uk = U[k]
        else:
            e0, e1, e2, e3 = traj.error4(x0, x1, x2, x3, goal[0], goal[1], goal[2], goal[3])
            uk = -(K[0] * e0 + K[1] * e1 + K[2] * e2 + K[3] * e3)
            uk = min(max(uk, -u_max), u_max)
        u[k] = uk
        x0, x1, x2, x3 = traj.step4(x0, x1, x2, x3, uk, driven, theta, dt, substeps)


def nominal_plan(U: np.ndarray, x0: np.ndarray, driven: int, theta: np.ndarray, dt: float, substeps: int) -> np.ndarray:
    """The states ``X`` (N+1, 4) of the inputs ``U`` (N,) from ``x0`` on the model ``theta`` (RK4, as the env steps):
    :func:`closed_loop` over the plan's steps and the state after it."""
    X = np.empty((len(U) + 1, 4))
    X[0] = x0
    closed_loop(U, np.zeros(4), np.zeros(4), 0.0, driven, theta, dt, substeps, len(U) + 1, X, np.empty(len(U) + 1))
    return X


def stored_design(env_id: str, path: pathlib.Path = DESIGNS) -> dict[str, Any]:
    """The design shipped for ``env_id`` (``{"knot_dt": ..., "knots": [...]}``), or a ``ValueError`` naming the ids
    that have one."""
    designs = json.loads(path.read_text()) if path.exists() else {}
    if env_id not in designs:
        raise ValueError(f"no scored swing-up design for {env_id!r}; designs exist for {sorted(designs)}")
    return designs[env_id]


class ScoredSwingUp(Controller):
    """Follow a swing-up designed for a protocol's score, then balance (module docstring).

    Parameters
    ----------
    env : gymnasium.Env
        An Acrobot or Pendubot env (the protocol ids); its ``dt``, ``substeps`` and torque limit are the design's.
    design : mapping, optional
        ``{"knot_dt": float [s], "knots": list of float [N m]}``; default the design shipped for the env's id.
    lqr_r, track_r : float
        The input weights [(N m)^-2] of the upright LQR and of the time-varying LQR (state weights ``Q``).
    """

    fits = (SwingUpEnv,)
    Q = np.diag([10.0, 10.0, 1.0, 1.0])
    #: where its settings come from (the DFKI report says so)
    settings_note = "designed on the protocol's score (`scripts/dfki_design.py`, `controllers/scored_swingup.json`)"

    def __init__(self, env: Any, design: Mapping[str, Any] | None = None, lqr_r: float = 1.0, track_r: float = 1.0):
        super().__init__(env)
        base = env.unwrapped
        design = stored_design(base.spec.id if base.spec is not None else "") if design is None else design
        knot_dt = check.positive(design["knot_dt"], "knot_dt")
        knots = check.reals(design["knots"], "knots")
        if knots.ndim != 1 or len(knots) < 4 or not np.all(np.isfinite(knots)):
            raise ValueError(f"knots must be at least 4 finite torques, got shape {knots.shape}")
        self.dt, self.substeps = float(base.dt), int(base.substeps)
        self.driven = int(self.model.driven[0])
        self.theta = np.asarray(self.model.kernel_params(), float).reshape(-1, 1)
        self.R = np.full((1, 1), check.positive(lqr_r, "lqr_r"))
        self.K, self.S = upright_lqr(self.model, self.Q, self.R)
        self.U = feedforward(knots, knot_dt, self.dt, float(self.u_max[0]))
        x0 = np.concatenate([Q_DOWN, np.zeros(2)])
        self.X = nominal_plan(self.U, x0, self.driven, self.theta, self.dt, self.substeps)
        R_track = check.positive(track_r, "track_r")
        self.K_track = traj.tvlqr(self.X, self.U, self.Q, R_track, np.asarray(self.S, float).reshape(4, 4), self.driven,
                                  self.theta, self.dt, self.substeps)  # fmt: skip
        self.goal = np.concatenate([Q_UP, np.zeros(2)])

    def input(self, obs: Any) -> np.ndarray:
        """Without memory: the upright LQR (the plan needs the step since the episode's start, :meth:`control`)."""
        x = np.concatenate([obs.q, obs.v], axis=-1)
        return self._lqr(x)

    def _lqr(self, x: np.ndarray) -> np.ndarray:
        e = np.concatenate([wrap_angle(x[..., :2] - Q_UP), x[..., 2:]], axis=-1)
        return -(e @ np.asarray(self.K, float).reshape(4))[..., None]

    def control(self, obs: Any, state: Any, episode_start: Any) -> tuple[np.ndarray, Any]:
        """The plan's input with its feedback while the plan lasts, the upright LQR after; ``state`` the step."""
        x = np.concatenate([obs.q, obs.v], axis=-1)
        single = x.ndim == 1
        x = x.reshape(-1, 4)
        n = len(x)
        k = np.zeros(n, np.int64) if state is None else np.asarray(state, np.int64).reshape(n).copy()
        if episode_start is not None:
            k[np.asarray(episode_start, bool).reshape(n)] = 0
        u = self._lqr(x)[:, 0]
        on = k < len(self.U)
        if on.any():
            j = k[on]
            e = x[on] - self.X[j]
            e[:, :2] = wrap_angle(e[:, :2])
            u[on] = self.U[j] + np.einsum("ij,ij->i", self.K_track[j], e)
        u = u[:, None]
        return (u[0] if single else u), k + 1
