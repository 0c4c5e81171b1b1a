"""An environment from a derived model (issue 36): joint tracking on a model of :mod:`mbs_envs.models.symbolic`.

A user's mechanism becomes a registered Gymnasium id in a few lines::

    model = symbolic.derive("Arm2R", [q1, q2], T, V, params, damping={q1: "b1", q2: "b2"})
    derived.register("my/Arm2R-v0", model, torque_limit=(40.0, 20.0), posture=(-1.57, 0.0),
                     coordinates=[q1, q2], points=[(0, 0), (x1, y1), (x2, y2)])
    env = gym.make("my/Arm2R-v0")                  # and gym.make_vec(..., vectorization_mode="vector_entry_point")

The task is :class:`~mbs_envs.envs.tracking.JointTrackingEnv`'s (every coordinate driven; a random smooth
reference about ``posture``, observation, reward and ``info`` as ``Planar2R-v0``'s), stepped by the compiled
engine with the derived model's generated kernels (its ``step_kernel``), single and batched; the drawing is a
line through the points the user names (planar ``(x, y)`` expressions in the coordinates).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np

from .. import validation as check
from ..models.symbolic import DerivedModel
from .rendering import Shape, arm_shapes
from .tracking import JointTrackingEnv

ENTRY_POINT = "mbs_envs.envs.derived:DerivedTrackingEnv"


class DerivedTrackingEnv(JointTrackingEnv):
    """Joint tracking on a derived model (module docstring).

    Parameters
    ----------
    model : DerivedModel
        From :func:`mbs_envs.models.symbolic.derive`; every coordinate driven (``B`` selects one per input).
    torque_limit : float or array_like
        Per input [N m or N].
    posture : array_like, shape (n,)
        The reference's centre [rad or m].
    spread : float or array_like
        Centres drawn from ``posture +- spread``.
    amplitude : float or array_like
        The largest total amplitude of each coordinate's reference.
    coordinates, points : optional
        The user's coordinates (sympy dynamicsymbols) and the points to draw, ``(x, y)`` expressions in them
        (or numbers); without them no drawing.
    params : mapping, optional
        Parameter overrides of the model.
    **kwargs
        :class:`~mbs_envs.envs.base.MBSEnv`'s (``dt``, ``integrator``, ``substeps``, ...).
    """

    @property
    def step_kernel(self) -> Any:
        """The compiled step: the derived model's generated binding of the engine to its kernels and this task's."""
        return type(self.model).generated.step_kernel

    def __init__(self, model: DerivedModel, torque_limit: Any, posture: Any, spread: Any = 0.5, amplitude: Any = 0.3,
                 coordinates: Sequence[Any] = (), points: Sequence[Any] = (), params: Any = None, **kwargs: Any):  # fmt: skip
        if not isinstance(model, DerivedModel):
            raise ValueError(f"model must be a model from mbs_envs.models.symbolic.derive, got {type(model).__name__}")
        if params is not None:
            model = type(model)(check.mapping(params, "params"))
        n = model.nq
        posture = check.vector(posture, "posture", n, broadcast=False)
        self.center_low = posture - check.vector(spread, "spread", n, 0.0)
        self.center_high = posture + check.vector(spread, "spread", n, 0.0)
        self.max_amplitude = check.vector(amplitude, "amplitude", n, 0.0)
        self._coordinates, self._points = tuple(coordinates), tuple(points)
        if self._points and len(self._coordinates) != n:
            raise ValueError(f"points need the {n} coordinates they are written in (coordinates=...)")
        super().__init__(model, torque_limit, **kwargs)
        J = 1.0 / np.diag(np.linalg.inv(model.mass_matrix(posture)))
        self.joint_inertia = J
        self.pd_gains = (100.0 * J, 20.0 * J)

    # -- drawing -----------------------------------------------------------------------------

    @functools.cached_property
    def _point_function(self):
        import sympy as sp

        plain = sp.symbols(f"p0:{len(self._coordinates)}")
        exprs = sp.Matrix([[sp.sympify(x), sp.sympify(y)] for x, y in self._points]).xreplace(dict(zip(self._coordinates, plain)))
        return sp.lambdify([plain], exprs, "numpy")

    def draw_points(self, q: np.ndarray) -> np.ndarray:
        """The named points at ``q`` [m], shape (k, 2)."""
        return np.asarray(self._point_function(np.asarray(q, float)), float).reshape(-1, 2)

    def _render_extent(self) -> float:
        if not self._points:
            raise ValueError("no points to draw: pass coordinates= and points= to the env")
        reach = np.max(np.linalg.norm(self.draw_points(np.asarray(self.center_low + self.center_high) / 2), axis=1))
        return 1.5 * float(max(reach, 1e-3))

    def _drawing(self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: Any = None) -> list[Shape]:
        ghost = self.draw_points(self.task_now(np.asarray(t), task)[0])
        return arm_shapes(self.draw_points(q), ghost, ())

    def __getstate__(self) -> dict:
        state = super().__getstate__()
        state.pop("_point_function", None)  # a lambdified function: made again on demand
        return state


def register(env_id: str, model: DerivedModel, max_episode_steps: int = 500, **kwargs: Any) -> None:
    """Register ``env_id`` for ``gym.make`` and ``gym.make_vec(..., vectorization_mode="vector_entry_point")``:
    :class:`DerivedTrackingEnv` on ``model`` with ``kwargs`` (its parameters) as defaults."""
    import gymnasium as gym

    from .vector import make_vector

    if not isinstance(model, DerivedModel):
        raise ValueError(f"model must be a model from mbs_envs.models.symbolic.derive, got {type(model).__name__}")
    gym.register(id=env_id, entry_point=ENTRY_POINT, vector_entry_point=functools.partial(make_vector, ENTRY_POINT),
                 max_episode_steps=max_episode_steps, kwargs={"model": model, **kwargs})  # fmt: skip
