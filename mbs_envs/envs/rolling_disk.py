"""``mbs_envs/RollingDisk-v0``: keep a rolling disk upright on a commanded heading and speed."""

from __future__ import annotations

import collections
import dataclasses
import sys
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from .. import validation as check
from ..dynamics.jit import njit
from ..dynamics.trig import wrap
from ..models import rolling_disk as _model
from ..models.rolling_disk import RollingDisk
from .draws import uniform_of
from .references import SumOfSines, sample_sums_of_sines, sum_of_sines_columns
from .base import MBSEnv
from .engine import engine_step
from .rendering import GHOST, GROUND, LINK, Arrow, Dot, Inset, Line, Polygon, Shape, Text, oblique
from .tracking import _as_columns


@dataclasses.dataclass(frozen=True)
class DiskObservation:
    """A decoded RollingDisk-v0 observation; each array has shape ``(...)``."""

    lean: np.ndarray
    dlean: np.ndarray
    dheading: np.ndarray
    dspin: np.ndarray
    heading_error: np.ndarray  # wrap(heading_ref - heading)
    dheading_ref: np.ndarray
    ddheading_ref: np.ndarray
    spin_ref: np.ndarray


OBS_FIELDS = tuple(f.name for f in dataclasses.fields(DiskObservation))


@dataclasses.dataclass(frozen=True)
class DiskTask:
    """An episode's commands: the heading reference and the spin rate ``spin_ref`` [rad/s]."""

    heading: SumOfSines
    spin_ref: np.ndarray


@njit
def disk_columns(
    q, v, h, dh, ddh, spin_ref, action, weights, Wc, lean_limit, obs, info, terminated
):  # pragma: no cover - compiled
    """The task's formulas (:class:`RollingDiskEnv`'s docstring) for a batch in columns.

    Parameters
    ----------
    q, v : ndarray, shape (6, B)
    h, dh, ddh : ndarray, shape (B,)
        The heading reference and its rates [rad, rad/s, rad/s^2].
    spin_ref : ndarray, shape (B,)
        Commanded spin rates [rad/s].
    action : ndarray, shape (2, B)
    weights : ndarray, shape (4,)
        ``(w_h, w_l, w_s, w_u)``.
    Wc, lean_limit : float
        The critical spin [rad/s] and the fall limit [rad].
    obs : ndarray, shape (8, B)
        Written (:data:`OBS_FIELDS`).
    info : ndarray, shape (>= 9, B)
        Written: ``(r, r_heading, r_lean, r_speed, r_effort, lean, fell, heading error, spin error)``.
    terminated : ndarray of bool, shape (B,)
        Written: fell.
    """
    for b in range(q.shape[1]):
        e_h = wrap(h[b] - q[3, b])
        e_s = (v[5, b] - spin_ref[b]) / Wc
        effort = 0.0
        for k in range(action.shape[0]):
            effort += action[k, b] * action[k, b]
        r_h, r_l, r_s, r_u = (
            -weights[0] * e_h**2,
            -weights[1] * q[4, b] ** 2,
            -weights[2] * e_s**2,
            -weights[3] * effort,
        )
        fell = abs(q[4, b]) > lean_limit
        info[0, b] = 1.0 + r_h + r_l + r_s + r_u
        info[1, b], info[2, b], info[3, b], info[4, b] = r_h, r_l, r_s, r_u
        info[5, b], info[6, b], info[7, b], info[8, b] = q[4, b], fell, e_h, v[5, b] - spin_ref[b]
        terminated[b] = fell
        fields = (q[4, b], v[4, b], v[3, b], v[5, b], e_h, dh[b], ddh[b], spin_ref[b])
        for i in range(8):
            obs[i, b] = fields[i]


@njit
def disk_task(q, v, t, action, task, obs, info, terminated):  # pragma: no cover - compiled
    """The task kernel of RollingDisk-v0 (:mod:`mbs_envs.envs.engine`): the heading reference at
    ``t``, then :func:`disk_columns`.

    ``task = (weights, W_c, lean_limit, center, rate, amplitude, omega, phase, spin_ref)``:
    :meth:`DiskTaskParams.kernel_arguments`, the heading references in columns
    (:meth:`SumOfSines.columns`) and the commanded spins ``(B,)``.
    """
    weights, Wc, lean_limit, center, rate, amplitude, omega, phase, spin_ref = task
    B = q.shape[1]
    refs = np.empty((3, 1, B))
    sum_of_sines_columns(t, center, rate, amplitude, omega, phase, refs[0], refs[1], refs[2])
    disk_columns(
        q, v, refs[0, 0], refs[1, 0], refs[2, 0], spin_ref, action, weights, Wc, lean_limit, obs, info, terminated
    )


@njit
def step_kernel(theta, stepper, control, task, state, out):  # pragma: no cover - compiled
    """The compiled step of this scene: :func:`~mbs_envs.envs.engine.engine_step` with the model's
    kernels (projection, contact force, the flat-disk singularity) and :func:`disk_task`."""
    engine_step(
        _model.advance_kernel,
        _model.energy_kernel,
        _model.constraint_info_kernel,
        _model.singular_kernel,
        _this.disk_task,
        theta,
        stepper,
        control,
        task,
        state,
        out,
    )


_this = sys.modules[__name__]


@dataclasses.dataclass(frozen=True)
class DiskTaskParams:
    """The disk task's parameters, explicit and immutable (Gymnasium's phys2d style); an env holds
    its own as :attr:`RollingDiskEnv.task_params`.

    Attributes
    ----------
    weights : ndarray, shape (4,)
        ``(w_h, w_l, w_s, w_u)`` of the reward.
    critical_spin : float
        The model's critical spin ``W_c`` [rad/s] (the unit of the speed error).
    lean_limit : float
        Termination beyond this lean [rad].
    spin_range : (float, float)
        Commanded spin in units of ``W_c``.
    heading_amplitude : float
        [rad]
    heading_omega : (float, float)
        Frequencies of the heading reference [rad/s].
    """

    weights: np.ndarray
    critical_spin: float
    lean_limit: float
    spin_range: tuple[float, float]
    heading_amplitude: float
    heading_omega: tuple[float, float]

    def kernel_arguments(self) -> tuple:
        """``(weights, W_c, lean_limit)`` as :func:`disk_columns` takes them."""
        return (np.asarray(self.weights, float), float(self.critical_spin), float(self.lean_limit))


def sample(p: DiskTaskParams, rngs: list[np.random.Generator], spin_ref: Any = None) -> DiskTask:
    """The episode's commands of ``L = len(rngs)`` members, stacked, member ``i``'s from ``rngs[i]``: a
    spin rate in ``spin_range`` (or ``spin_ref`` [rad/s], checked; the draw is made either way), then a
    heading reference."""
    spin = uniform_of(np.array([rng.random() for rng in rngs]), *p.spin_range) * p.critical_spin
    if spin_ref is not None:
        W_max = p.spin_range[1] * p.critical_spin
        spin[:] = check.real(spin_ref, "options['spin_ref']", -W_max, W_max)
    heading = sample_sums_of_sines(rngs, [-np.pi], [np.pi], [p.heading_amplitude], p.heading_omega, n_components=2)
    return DiskTask(heading=heading, spin_ref=spin)


def start(
    p: DiskTaskParams, task: DiskTask, rngs: list[np.random.Generator], model: RollingDisk
) -> tuple[np.ndarray, np.ndarray]:
    """Upright rolling at the commanded spin, heading near the reference's, small lean and lean rate:
    ``(q0, v0)``, shape ``(L, 6)`` each, member ``i``'s noise from ``rngs[i]``."""
    d = np.array([rng.random(3) for rng in rngs])  # heading, lean, lean rate (:mod:`mbs_envs.envs.draws`)
    noise = uniform_of(d, np.array([-0.1, -0.05, -0.1]), np.array([0.1, 0.05, 0.1]))
    heading0 = task.heading(0.0)[0][:, 0] + noise[:, 0]
    return model.rolling_state(heading=heading0, lean=noise[:, 1], dlean=noise[:, 2], dspin=task.spin_ref)


def reference(task: DiskTask, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(heading_ref, dheading_ref, ddheading_ref)`` at ``t``, each shape ``(...)``."""
    h, dh, ddh = task.heading(t)
    return h[..., 0], dh[..., 0], ddh[..., 0]


def task_rows(
    p: DiskTaskParams, q, v, now: tuple, task: DiskTask, action=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`disk_columns` batched over leading dimensions: ``obs (..., 8)`` float32,
    ``info (..., 9)`` and ``fell (...)`` (``action`` None: no effort)."""
    action = np.zeros(2) if action is None else action
    cols = (now[0], now[1], now[2], task.spin_ref)
    lead, (q2, v2, a2, *refs) = _as_columns(q, v, action, *(np.asarray(x, float)[..., None] for x in cols))
    B = q2.shape[1]
    obs, info, fell = np.empty((8, B), np.float32), np.empty((9, B)), np.empty(B, bool)
    disk_columns(q2, v2, refs[0][0], refs[1][0], refs[2][0], refs[3][0], a2, *p.kernel_arguments(), obs, info, fell)
    return obs.T.reshape(lead + (8,)), info.T.reshape(lead + (9,)), fell.reshape(lead)


def observe(p: DiskTaskParams, q, v, now: tuple, task: DiskTask) -> np.ndarray:
    """The observation (:data:`OBS_FIELDS`), float32 ``(..., 8)``."""
    return task_rows(p, q, v, now, task)[0]


def reward(p: DiskTaskParams, q, v, now: tuple, task: DiskTask, action) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``r = 1 - (w_h e_h^2 + w_l lean^2 + w_s ((dspin - W_ref) / W_c)^2 + w_u |action|^2)`` and its terms."""
    info = task_rows(p, q, v, now, task, action)[1]
    names = ("reward_heading", "reward_lean", "reward_speed", "reward_effort")
    return info[..., 0], {k: info[..., 1 + i] for i, k in enumerate(names)}


def terminated(p: DiskTaskParams, q, v, now: tuple, task: DiskTask) -> np.ndarray:
    """Fell: ``|lean| > lean_limit``, bool ``(...)``."""
    return task_rows(p, q, v, now, task)[2]


def info(p: DiskTaskParams, q, v, now: tuple, task: DiskTask) -> dict[str, np.ndarray]:
    """``lean``, ``fell``, ``tracking_error`` (the heading error, ``(..., 1)``) and ``spin_error`` [rad/s]."""
    rows = task_rows(p, q, v, now, task)[1]
    return {
        "lean": rows[..., 5],
        "fell": rows[..., 6].astype(bool),
        "tracking_error": rows[..., 7:8],
        "spin_error": rows[..., 8],
    }


#: the smallest critical spin [rad/s] the task takes: its speed error is in units of W_c, so a disk
#: without gravity (W_c = 0) has a reward of -inf and one with g = 1e-300 of -1e263
MIN_CRITICAL_SPIN = 1e-3


class RollingDiskEnv(MBSEnv):
    """Thin disk rolling without slipping (drive and steer): stay upright, follow a heading, hold a spin.

    ## Description

    The disk of docs/physics.md §5 (six coordinates, rolling constraints, no
    slip). Each episode commands a spin rate ``W_ref`` (forward speed
    ``r W_ref``), drawn uniformly between 0.3 and 2 times the critical spin
    of upright rolling (so about 40 % of episodes are not self-stable), and
    a smooth heading reference ``heading_ref(t)`` (two slow sinusoids, total
    amplitude up to 0.6 rad). The disk must follow both without falling.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``: ``(drive, steer)`` normalized by
    ``torque_limit``: the generalized forces on the spin angle and the heading,
    i.e. the components of an applied torque along the spin axis and the
    vertical (see :mod:`mbs_envs.models.rolling_disk`).

    ## Observation Space

    ``Box((8,), float32)``: ``[lean, dlean, dheading, dspin, wrap(heading_ref -
    heading), dheading_ref, ddheading_ref, spin_ref]``; see :class:`DiskObservation`.

    ## Rewards

    ``r = 1 - (e_h^2 + lean^2 + 0.1 ((dspin - W_ref) / W_c)^2 + 0.001 |action|^2)``
    per step (the 1 rewards staying up); terms in ``info``.

    ## Starting State

    Upright rolling at ``W_ref`` with lean ``U(-0.05, 0.05)`` rad, lean rate
    ``U(-0.1, 0.1)`` rad/s, heading ``heading_ref(0) + U(-0.1, 0.1)``, no heading
    rate; the centre's velocity from the rolling constraints. Or an exact state
    through ``reset(options={"q": ..., "v": ...})`` (projected onto the constraints).

    ## Episode End

    Termination when ``|lean| > lean_limit`` (default 0.6 rad; ``info["fell"]``)
    or on divergence, which includes the disk nearing flat (Euler-angle
    singularity at ``|lean| = pi/2``). Truncation after ``max_episode_steps``
    (default 1000, 10 s).

    ## Arguments

    ``gym.make("mbs_envs/RollingDisk-v0", params=None, torque_limit=(0.3, 0.3),
    lean_limit=0.6, dt=0.01, integrator="rk4", substeps=1,
    stabilization="projection", compiled=True, ...)``. With an explicit
    integrator and the projection, a step is one compiled kernel
    (:mod:`mbs_envs.envs.engine`); ``compiled=False`` forces the numpy path.

    ``info`` holds ``t``, ``energy``, ``diverged``, ``constraint_residual``
    (``|z - r cos lean|`` [m]), ``multipliers`` (the contact force of the ground
    on the disk [N], world frame), ``lean``, ``fell``, ``tracking_error`` (the
    heading error), ``spin_error``, the reward terms and ``u``.

    ## Version History

    - v0: initial version.
    """

    step_kernel = staticmethod(step_kernel)

    spin_range = (0.3, 2.0)  # W_ref / W_c
    task_options = ("spin_ref",)
    heading_amplitude = 0.6  # rad
    heading_omega = (0.2, 0.8)  # rad/s
    reward_weights = (1.0, 1.0, 0.1, 1e-3)

    def __init__(
        self,
        params: Mapping[str, Any] | None = None,
        torque_limit: Any = (0.3, 0.3),
        lean_limit: float = 0.6,
        stabilization: str = "projection",
        **kwargs: Any,
    ):
        model = RollingDisk(params)
        Wc = model.critical_spin
        if not (
            np.isfinite(Wc) and Wc >= MIN_CRITICAL_SPIN
        ):  # g <= 0 (or ~0): the task's speeds, in units of W_c, are undefined
            raise ValueError(
                f"params: g = {model.params.g:g} gives the critical spin W_c = {Wc:g} rad/s; this task's spin "
                f"references and speed error are in units of W_c, so it needs gravity g > 0 and W_c >= {MIN_CRITICAL_SPIN:g} rad/s"
            )
        super().__init__(model, torque_limit, stabilization=stabilization, **kwargs)
        self.lean_limit = lean_limit
        w_max = self.heading_omega[1]
        high = np.array(
            [np.pi / 2, self.divergence_limit, self.divergence_limit, self.divergence_limit, np.pi,
             self.heading_amplitude * w_max, self.heading_amplitude * w_max**2, self.spin_range[1] * Wc],
            dtype=np.float32,
        )  # fmt: skip
        self.observation_space = gym.spaces.Box(-high, high, dtype=np.float32)
        # starts: heading within pi + amplitude + 0.1, spin up to the top of spin_range, the
        # centre's speed r times it, lean and heading rates below 1 rad/s
        W_top = self.spin_range[1] * Wc
        self._check_start_bound(
            max(np.pi + self.heading_amplitude + 0.1, model.params.r, W_top * max(1.0, model.params.r) + 1.0)
        )

    @property
    def lean_limit(self) -> float:
        """The fall limit on ``|lean|`` [rad], in ``(0, flat_lean)``: validated on every assignment."""
        return self._lean_limit

    @lean_limit.setter
    def lean_limit(self, value: Any) -> None:
        self._lean_limit = check.real(value, "lean_limit", 0.0, self.model.flat_lean, low_open=True, high_open=True)
        check.touch(self)

    # -- the task: the module's functions with this env's parameters -----------------

    def _task_cache(self) -> tuple:
        """``(key, task_params, kernel arguments)``, built again only when a setting they hold changes."""
        key = (self.model, self.lean_limit, self.reward_weights)
        cached = self.__dict__.get("_task_arguments")
        if cached is None or cached[0] != key:
            params = DiskTaskParams(np.asarray(self.reward_weights, float), float(self.model.critical_spin), float(self.lean_limit),
                                    self.spin_range, self.heading_amplitude, self.heading_omega)  # fmt: skip
            cached = self._task_arguments = (key, params, params.kernel_arguments())
        return cached

    @property
    def task_params(self) -> DiskTaskParams:
        """This env's task parameters, from its current settings."""
        return self._task_cache()[1]

    def _draw_tasks(self, options: dict, rngs: list) -> DiskTask:
        return sample(self.task_params, rngs, options.get("spin_ref"))

    def _draw_states(self, task: DiskTask, rngs: list, model: RollingDisk) -> tuple[np.ndarray, np.ndarray]:
        return start(self.task_params, task, rngs, model)

    @property
    def spin_ref(self) -> float:
        """The episode's commanded spin rate [rad/s]."""
        return float(self._task.spin_ref) if self._task is not None else self.model.critical_spin

    @property
    def heading_reference(self) -> SumOfSines | None:
        return None if self._task is None else self._task.heading

    def task_now(self, t: np.ndarray, task: DiskTask) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(heading_ref, dheading_ref, ddheading_ref)``, each shape ``(...)``."""
        return reference(task, t)

    def observe(self, q, v, now, task) -> np.ndarray:
        return observe(self.task_params, q, v, now, task)

    @staticmethod
    def decode_observation(obs: np.ndarray) -> DiskObservation:
        """The fields of an observation (batched over leading dimensions)."""
        obs = np.asarray(obs, dtype=float)
        if obs.shape[-1] != len(OBS_FIELDS):
            raise ValueError(f"observation must have shape (..., {len(OBS_FIELDS)}), got {obs.shape}")
        return DiskObservation(*(obs[..., i] for i in range(len(OBS_FIELDS))))

    def fell(self, q: np.ndarray) -> np.ndarray:
        """``|lean| > lean_limit``, bool ``(...)``."""
        return np.abs(q[..., 4]) > self.lean_limit

    def terminated(self, q, v, now, task) -> np.ndarray:
        return terminated(self.task_params, q, v, now, task)

    def reward(self, q, v, now, task, u, action) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        return reward(self.task_params, q, v, now, task, action)

    def task_info(self, q, v, now, task, u) -> dict[str, Any]:
        return {**self.constraint_info(q, v, u), **info(self.task_params, q, v, now, task)}

    # -- the compiled step (see mbs_envs.envs.engine) ----------------------------

    def task_arguments(self) -> tuple:
        return self._task_cache()[2]

    def task_columns(self, task: DiskTask) -> tuple:
        return task.heading.columns() + (np.array(np.reshape(task.spin_ref, -1), float),)

    def task_layout(self) -> tuple[tuple[str, int | None, bool], ...]:
        names = ("reward", "reward_heading", "reward_lean", "reward_speed", "reward_effort", "lean")
        return tuple((k, None, False) for k in names) + (
            ("fell", None, True),
            ("tracking_error", 1, False),
            ("spin_error", None, False),
        )

    # -- drawing: an oblique camera beside the disk, and a map seen from above ------------------

    #: seconds of contact path drawn behind the disk
    trail_seconds = 4.0
    #: the camera looks at the disk from this angle behind its side [rad] (90 deg: square to its face)
    camera_angle = np.deg2rad(70.0)
    draws_ground = False  # the ground is drawn as a grid in the camera's projection
    error_label = "heading error"

    def _camera(self, q: np.ndarray) -> float:
        """The camera's azimuth [rad]: it turns with the heading, ``camera_angle`` from the rolling direction."""
        return float(q[3]) - self.camera_angle

    def _render_extent(self) -> float:
        return 4.0 * self.model.params.r

    def _render_center(self, q: np.ndarray) -> tuple[float, float]:
        c = oblique(np.asarray(q[:3], float), self._camera(q))
        return (float(c[0]), float(c[1]))

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        # points kept: trail_seconds of steps, at most 100,000 (a tiny valid dt would ask for more than memory)
        self._trail = collections.deque(maxlen=int(max(min(self.trail_seconds / self.dt, 1e5), 2)))
        out = super().reset(seed=seed, options=options)
        self._trail.append(self._contact_point(self._q))
        return out

    def step(self, action: Any):
        out = super().step(action)
        if self.render_mode is not None:  # the path is only kept for drawing
            self._trail.append(self._contact_point(self._q))
        return out

    def trail(self) -> np.ndarray | None:
        """The contact points of the last ``trail_seconds`` (k, 3) [m] (kept while rendering)."""
        points = getattr(self, "_trail", None)
        return np.array(points) if points else None

    def _contact_point(self, q: np.ndarray) -> np.ndarray:
        return np.asarray(q[:3], float) + self.model.contact_offset(q)

    def _drawing(
        self, q: np.ndarray, t: float, task: DiskTask, u: np.ndarray, trail: np.ndarray | None = None
    ) -> list[Shape]:
        """The disk seen by a camera beside it (:meth:`_camera`, 30 deg above the ground): the rim
        (the projected circle of the tilted disk, an ellipse) with a spoke turning with the spin, the
        ground as a 0.5 m grid, the contact path of the last ``trail_seconds``, the direction of
        rolling (blue) and the commanded heading (green) as arrows from the contact point. A map
        seen from above (north up, fixed) shows the path, the disk's footprint and both arrows;
        "FALLEN" once past the lean limit.
        """
        r = self.model.params.r
        q = np.asarray(q, float)
        th1, th2, th3 = q[3], q[4], q[5]
        c1, s1 = np.cos(th1), np.sin(th1)
        R = self.model.orientation(q)
        az = self._camera(q)

        def view(points):
            return oblique(points, az)

        centre, contact = q[:3], self._contact_point(q)
        shapes: list[Shape] = []
        step = 0.5
        x0, y0 = np.round(centre[0] / step) * step, np.round(centre[1] / step) * step
        span = np.arange(-4, 5) * step
        for k in span:  # the ground grid around the disk
            shapes.append(
                Line(view(np.array([[x0 + k, y0 + span[0], 0.0], [x0 + k, y0 + span[-1], 0.0]])), (225, 225, 225), 1)
            )
            shapes.append(
                Line(view(np.array([[x0 + span[0], y0 + k, 0.0], [x0 + span[-1], y0 + k, 0.0]])), (225, 225, 225), 1)
            )
        if trail is not None and len(trail) > 1:
            shapes.append(Line(view(trail), (200, 60, 60), 2))
        h_ref = float(self.task_now(np.asarray(t), task)[0])
        rolling = np.array([c1, s1, 0.0])
        commanded = np.array([np.cos(h_ref), np.sin(h_ref), 0.0])
        shapes.append(Arrow(view(contact), view(contact + 2.5 * r * commanded), (40, 160, 60)))
        phi = np.linspace(0.0, 2 * np.pi, 49)[:-1]
        rim = centre + r * (np.cos(phi)[:, None] * R[:, 0] + np.sin(phi)[:, None] * R[:, 2])
        shapes.append(Polygon(view(rim), GHOST))
        shapes.append(Line(view(rim), LINK, 3, closed=True))
        spoke = np.stack([centre - r * R[:, 2], centre + r * R[:, 2]])
        shapes.append(Line(view(spoke), LINK, 3))
        shapes.append(Dot(view(spoke[1]), 5, (200, 60, 60)))
        shapes.append(Arrow(view(contact), view(contact + 2.5 * r * rolling), LINK))
        shapes.append(Dot(view(contact), 3, GROUND))
        footprint = np.stack([contact[:2] - r * rolling[:2], contact[:2] + r * rolling[:2]])
        top = [Line(trail[:, :2], (200, 60, 60), 2)] if trail is not None and len(trail) > 1 else []
        top += [Line(footprint, LINK, 4), Arrow(contact[:2], contact[:2] + 3 * r * commanded[:2], (40, 160, 60), 2),
                Arrow(contact[:2], contact[:2] + 3 * r * rolling[:2], LINK, 2)]  # fmt: skip
        shapes.append(Inset(tuple(top), contact[:2], 6.0 * r, title="from above, N up"))
        if self.fell(q):
            shapes.append(Text("FALLEN (|lean| > lean limit)", 3, (200, 0, 0)))
        shapes.append(Text(f"lean {np.degrees(th2):+5.1f} deg, spin {np.degrees(th3) % 360:5.1f} deg", 2))
        return shapes
