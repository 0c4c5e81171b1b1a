"""An environment from a derived model: joint tracking on a model of :mod:`mbs_envs.models.symbolic`.

A user's mechanism becomes a registered Gymnasium id in a few lines::

    model = symbolic.derive("Arm2R", [q1, q2], T, V, params, damping={q1: "b1", q2: "b2"})
    derived.register("my/Arm2R-v0", model, torque_limit=(40.0, 20.0), posture=(-1.57, 0.0),
                     coordinates=[q1, q2], points=[(0, 0), (x1, y1), (x2, y2)])
    env = gym.make("my/Arm2R-v0")                  # and gym.make_vec(..., vectorization_mode="vector_entry_point")

The task is :class:`~mbs_envs.envs.tracking.JointTrackingEnv`'s (a random smooth reference about ``posture``,
observation, reward and ``info`` as ``Planar2R-v0``'s), stepped by the compiled engine with the derived model's
generated kernels (its ``step_kernel``), single and batched; the drawing is a line through the points the user
names (planar ``(x, y)`` expressions in the coordinates).

Unconstrained, every coordinate is tracked and driven. With constraints (a derived
:class:`~mbs_envs.models.symbolic.ConstrainedDerivedModel`) the tracked coordinates are the model's
``independent`` ones, one input each (as ``FourBar-v0``'s crank): a start state is assembled on the constraints
from ``guess`` (:meth:`~mbs_envs.models.symbolic.ConstrainedDerivedModel.assemble`), steps project onto them, a
loop opened beyond ``residual_limit`` ends the episode as diverged, and ``info`` holds ``constraint_residual`` and
the ``multipliers``.

An underactuated model (fewer inputs than coordinates) takes the swing-up task instead: ``register(...,
task="swing-up", upright=..., hanging=..., angles=..., bounds=...)``
(:class:`~mbs_envs.envs.derived_swingup.DerivedSwingUpEnv`); both tasks draw the same way (:class:`NamedPoints`).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np

from .. import validation as check
from ..models.symbolic import DerivedModel
from .base import checked_residual_limit
from .rendering import Shape, arm_shapes
from .tracking import JointTrackingEnv

ENTRY_POINT = "mbs_envs.envs.derived:DerivedTrackingEnv"


def coordinate_index(c: Any, coordinates: Sequence[Any], n: int, name: str) -> int:
    """The index of coordinate ``c``: an int in ``[0, n)``, or an entry of ``coordinates`` (the user's symbols)."""
    if isinstance(c, (int, np.integer)) and not isinstance(c, bool):
        if 0 <= c < n:
            return int(c)
        raise ValueError(f"{name}: coordinate index {c} is not in [0, {n})")
    for i, x in enumerate(coordinates):
        if x == c:
            return i
    raise ValueError(
        f"{name}: {c!r} is not one of the coordinates {list(coordinates)} (pass coordinates=..., or indices)"
    )


class NamedPoints:
    """The drawing of a derived scene: a line through the points the user names, ``(x, y)`` expressions in the
    coordinates and the model's parameters (by name); framed by the points over :meth:`_frame_configurations`."""

    def set_points(self, n: int, coordinates: Sequence[Any], points: Sequence[Any]) -> None:
        """Keep the user's ``coordinates`` (``n`` of them where points are named) and ``points``."""
        self._coordinates, self._points = tuple(coordinates), tuple(points)
        if self._points and len(self._coordinates) != n:
            raise ValueError(f"points need the {n} coordinates they are written in (coordinates=...)")

    def _frame_configurations(self) -> np.ndarray:
        """Configurations ``(k, n)`` the picture must hold."""
        raise NotImplementedError

    @functools.cached_property
    def _point_function(self):
        import sympy as sp

        plain = sp.symbols(f"p0:{len(self._coordinates)}")
        exprs = sp.Matrix([[sp.sympify(x), sp.sympify(y)] for x, y in self._points]).xreplace(
            dict(zip(self._coordinates, plain))
        )
        values = self.model.params.as_dict()  # the model's parameters by name (the env's values, overrides included)
        exprs = exprs.xreplace({x: values[str(x)] for x in exprs.free_symbols if str(x) in values})
        unknown = sorted(str(x) for x in exprs.free_symbols - set(plain))
        if unknown:
            raise ValueError(f"points use symbols that are neither coordinates nor parameters: {unknown}")
        return sp.lambdify([plain], exprs, "numpy")

    def draw_points(self, q: np.ndarray) -> np.ndarray:
        """The named points at ``q`` [m], shape (k, 2)."""
        return np.asarray(self._point_function(np.asarray(q, float)), float).reshape(-1, 2)

    @functools.cached_property
    def _frame(self) -> tuple[np.ndarray, float]:
        """The drawing's centre and half-width [m]: the bounding box of the named points over
        :meth:`_frame_configurations`, with a margin."""
        if not self._points:
            raise ValueError("no points to draw: pass coordinates= and points= to the env")
        P = np.concatenate([self.draw_points(q) for q in self._frame_configurations()])
        lo, hi = P.min(axis=0), P.max(axis=0)
        return (lo + hi) / 2, 0.6 * float(max(np.max(hi - lo), 1e-3)) + 0.05 * float(max(np.max(np.abs(P)), 1e-3))

    def _render_extent(self) -> float:
        return self._frame[1]

    def _render_center(self, q: np.ndarray) -> tuple[float, float]:
        return tuple(self._frame[0])

    def __getstate__(self) -> dict:
        state = super().__getstate__()
        state.pop("_point_function", None)  # a lambdified function: made again on demand
        state.pop("_frame", None)
        return state


class DerivedTrackingEnv(NamedPoints, JointTrackingEnv):
    """Joint tracking on a derived model (module docstring).

    Parameters
    ----------
    model : DerivedModel
        From :func:`mbs_envs.models.symbolic.derive`; one input per tracked coordinate (``B`` selects one each).
    torque_limit : float or array_like
        Per input [N m or N].
    posture : array_like, shape (m,)
        The reference's centre [rad or m], one per tracked coordinate (all ``n``, or the ``independent`` ones).
    spread : float or array_like
        Centres drawn from ``posture +- spread``.
    amplitude : float or array_like
        The largest total amplitude of each coordinate's reference.
    rate : (float, float), optional
        A mean rate drawn from this range [rad/s] (a crank that turns); default none.
    guess : array_like, shape (n,), optional
        Constrained models: the configuration starts are assembled from (default zeros; its branch is kept).
    residual_limit : float
        Constrained models: the largest ``max |phi|`` [m] of a state that has not diverged.
    coordinates, points : optional
        The user's coordinates (sympy dynamicsymbols) and the points to draw, ``(x, y)`` expressions in them and
        the model's parameters (by name), or numbers; without them no drawing.
    params : mapping, optional
        Parameter overrides of the model.
    **kwargs
        :class:`~mbs_envs.envs.base.MBSEnv`'s (``dt``, ``integrator``, ``substeps``, ...).
    """

    @property
    def step_kernel(self) -> Any:
        """The compiled step: the derived model's generated binding of the engine to its kernels and this task's."""
        return type(self.model).generated.step_kernel

    residual_limit = checked_residual_limit()

    def __init__(self, model: DerivedModel, torque_limit: Any, posture: Any, spread: Any = 0.5, amplitude: Any = 0.3,
                 rate: Any = None, guess: Any = None, residual_limit: float = 0.01, coordinates: Sequence[Any] = (),
                 points: Sequence[Any] = (), params: Any = None, **kwargs: Any):  # fmt: skip
        if not isinstance(model, DerivedModel):
            raise ValueError(f"model must be a model from mbs_envs.models.symbolic.derive, got {type(model).__name__}")
        if params is not None:
            model = type(model)(check.mapping(params, "params"))
        n = model.nq
        m = len(getattr(model, "independent", range(n)))
        posture = check.vector(posture, "posture", m, broadcast=False)
        self.center_low = posture - check.vector(spread, "spread", m, 0.0)
        self.center_high = posture + check.vector(spread, "spread", m, 0.0)
        self.max_amplitude = check.vector(amplitude, "amplitude", m, 0.0)
        if rate is not None:
            low, high = check.vector(rate, "rate", 2, -100.0, 100.0, broadcast=False)
            if not low <= high:
                raise ValueError(f"rate must be a range (low <= high), got {rate!r}")
            self.rate_range = (float(low), float(high))
        if guess is not None and not model.nc:
            raise ValueError("guess: only a constrained model assembles its starts from a guess")
        self.guess = np.zeros(n) if guess is None else check.vector(guess, "guess", n, broadcast=False)
        self.residual_limit = residual_limit
        self.set_points(n, coordinates, points)
        if model.nc:
            kwargs.setdefault("stabilization", "projection")
        super().__init__(model, torque_limit, **kwargs)
        J = self._apparent_inertia(posture)
        self.joint_inertia = J
        self.pd_gains = (100.0 * J, 20.0 * J)

    def _apparent_inertia(self, posture: np.ndarray) -> np.ndarray:
        """``1 / (J^-1)_ii`` of the tracked coordinates, ``J = T^T M T`` with ``T = dq / dq_tracked`` (the identity
        without constraints): at ``posture``, or averaged over a turn of the first tracked coordinate when the
        reference turns (``rate``) [kg m^2 or kg]."""
        model, m = self.model, len(self.tracked)
        q_t = np.array(np.broadcast_to(posture, (72 if self.rate_range else 1, m)))
        if self.rate_range:
            q_t[:, 0] = np.linspace(-np.pi, np.pi, 72, endpoint=False)
        q = self._assembled(q_t)
        T = np.stack([model.complete_velocity(q, np.eye(m)[k]) for k in range(m)], axis=-1) if model.nc else np.eye(m)
        J = np.swapaxes(T, -1, -2) @ model.mass_matrix(q) @ T
        w = np.linalg.eigvalsh(J)
        singular = ~(w[..., 0] > 1e-12 * np.maximum(np.abs(w[..., -1]), 1e-300))
        if np.any(singular):
            at = q[np.flatnonzero(singular)[0]]
            raise ValueError(f"posture: {type(model).__name__}'s mass matrix is singular at q = {np.round(at, 6).tolist()} "
                             f"(eigenvalues {np.round(w[np.flatnonzero(singular)[0]], 12).tolist()}): no acceleration is "
                             "determined there; choose a posture away from the singular configuration")  # fmt: skip
        return np.mean(1.0 / np.diagonal(np.linalg.inv(J), axis1=-2, axis2=-1), axis=0)

    def _assembled(self, q_t: np.ndarray) -> np.ndarray:
        """Whole configurations from the tracked coordinates ``(..., m)`` (assembled from ``guess`` with constraints)."""
        return self.model.assemble(q_t, self.guess) if self.model.nc else np.asarray(q_t, float)

    def _state_from_tracked(self, q_t: np.ndarray, v_t: np.ndarray, model: Any) -> tuple[np.ndarray, np.ndarray]:
        if not model.nc:
            return q_t, v_t
        q = model.assemble(q_t, self.guess)
        return q, model.complete_velocity(q, v_t)

    def task_info(self, q, v, now, task, u) -> dict[str, Any]:
        return {**super().task_info(q, v, now, task, u), **self.constraint_info(q, v, u)}

    # -- drawing -----------------------------------------------------------------------------

    def _frame_configurations(self) -> np.ndarray:
        """The first tracked coordinate across its reference range (a whole turn when the reference turns), assembled."""
        centre = (self.center_low + self.center_high) / 2
        q_t = np.array(np.broadcast_to(centre, (25, len(centre))))
        low, high = (
            (-np.pi, np.pi)
            if self.rate_range
            else (self.center_low[0] - self.max_amplitude[0], self.center_high[0] + self.max_amplitude[0])
        )
        q_t[:, 0] = np.linspace(low, high, 25)
        return self._assembled(q_t)

    def _drawing(self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: Any = None) -> list[Shape]:
        ghost = self.draw_points(self._assembled(self.task_now(np.asarray(t), task)[0]))
        return arm_shapes(self.draw_points(q), ghost, ())


#: the tasks a derived model is registered with, by name: the env's entry point
TASKS = {"tracking": ENTRY_POINT, "swing-up": "mbs_envs.envs.derived_swingup:DerivedSwingUpEnv"}


def register(
    env_id: str, model: DerivedModel, max_episode_steps: int = 500, task: str = "tracking", **kwargs: Any
) -> None:
    """Register ``env_id`` for ``gym.make`` and ``gym.make_vec(..., vectorization_mode="vector_entry_point")``: the
    ``task`` (:data:`TASKS`: :class:`DerivedTrackingEnv`, or
    :class:`~mbs_envs.envs.derived_swingup.DerivedSwingUpEnv` with ``horizon = max_episode_steps``) on ``model``
    with ``kwargs`` (its parameters) as defaults."""
    import gymnasium as gym

    from .vector import make_vector

    if not isinstance(model, DerivedModel):
        raise ValueError(f"model must be a model from mbs_envs.models.symbolic.derive, got {type(model).__name__}")
    if task not in TASKS:
        raise ValueError(f"task must be one of {sorted(TASKS)}, got {task!r}")
    if task == "swing-up":
        kwargs.setdefault("horizon", max_episode_steps)
    entry = TASKS[task]
    gym.register(id=env_id, entry_point=entry, vector_entry_point=functools.partial(make_vector, entry),
                 max_episode_steps=max_episode_steps, kwargs={"model": model, **kwargs})  # fmt: skip
