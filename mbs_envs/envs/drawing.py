"""Drawing an environment: :class:`Drawable`, the rendering half of :class:`~mbs_envs.envs.base.MBSEnv`.

A scene supplies what to draw of a state (:meth:`Drawable._drawing`, the extent and centre of the picture, a trail);
this mixin turns it into Gymnasium's ``render`` (the env's ``render_mode``: a window or RGB arrays) with a caption
(the time and the tracking error) and arcs for the torques of the inputs that act on one joint, through
:class:`~mbs_envs.envs.rendering.PlanarRenderer`.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from .rendering import PlanarRenderer, Shape, Text


class Drawable:
    """The rendering methods of :class:`~mbs_envs.envs.base.MBSEnv` (module docstring); they read the env's
    ``render_mode``, ``metadata``, ``model``, ``u_max`` and state, and keep its renderer in ``_renderer``."""

    _renderer: PlanarRenderer | None = None

    def _drawing(
        self, q: np.ndarray, t: float, task: Any, u: np.ndarray, trail: np.ndarray | None = None
    ) -> list[Shape]:
        """What to draw of the state ``q`` at time ``t`` of an episode's ``task`` under the input
        ``u`` [SI] (:mod:`mbs_envs.envs.rendering` shapes, world coordinates); ``trail`` the
        scene's recent path where it keeps one (the disk's contact points, :meth:`trail`)."""
        raise NotImplementedError

    #: what the caption calls ``info["tracking_error"]`` (its norm is shown)
    error_label: ClassVar[str] = "tracking error"

    def _caption(self, q: np.ndarray, v: np.ndarray, t: float, task: Any, u: np.ndarray) -> list[Shape]:
        """The time and the norm of the tracking error [rad] as text."""
        e = self.task_info(q, v, self.task_now(np.asarray(t), task), task, u).get("tracking_error")
        lines = [f"t = {t:5.2f} s"]
        if e is not None:
            lines.append(f"{self.error_label} {float(np.linalg.norm(e)):.3g} rad")
        return [Text(line, row) for row, line in enumerate(lines)]

    def _torque_arcs(self, u: np.ndarray) -> list[tuple[int, float]]:
        """``(joint, u / u_max)`` of each input acting on one joint alone (a column of ``B``
        with one nonzero entry, e.g. the driven joints of an arm)."""
        B = np.asarray(self.model.actuation)
        out = []
        for k in range(B.shape[1]):
            (rows,) = np.nonzero(B[:, k])
            if len(rows) == 1:
                out.append((int(rows[0]), float(u[k] * B[rows[0], k] / self.u_max[k])))
        return out

    def _render_extent(self) -> float:
        raise NotImplementedError

    def _render_center(self, q: np.ndarray) -> tuple[float, float]:
        """World point at the centre of the picture of ``q`` [m]."""
        return (0.0, 0.0)

    def render(self):
        if self.render_mode is None:
            gym.logger.warn(
                "You are calling render method without specifying any render mode. "
                'Set render_mode at initialization, e.g. gym.make(id, render_mode="rgb_array")'
            )
            return None
        self._require_reset("render")
        return self.render_state(self._q, self._t, self._task, self._v, self._u, self.trail())

    def trail(self) -> np.ndarray | None:
        """The recent path drawn behind the scene (None: the scene keeps none)."""
        return None

    #: whether the renderer draws the ground line ``y = 0``
    draws_ground: ClassVar[bool] = True

    def render_state(self, q: np.ndarray, t: float, task: Any, v: np.ndarray | None = None, u: np.ndarray | None = None,
                     trail: np.ndarray | None = None) -> Any:  # fmt: skip
        """Draw the state ``(q, v)`` at time ``t`` of an episode's ``task`` under the input ``u`` [SI]
        (this env's renderer and mode); without ``v`` no error caption, without ``u`` no torque arcs."""
        if self._renderer is None:
            self._renderer = PlanarRenderer(
                self._render_extent(),
                self.render_mode,
                self.metadata["render_fps"],
                center=(0.0, 0.0),
                ground=self.draws_ground,
            )
        self._renderer.center = np.asarray(self._render_center(q), float)  # the camera follows (the disk rolls away)
        u_draw = np.zeros(self.model.nu) if u is None else np.asarray(u, float)
        shapes = self._drawing(q, t, task, u_draw, trail)
        if v is not None:
            shapes = shapes + self._caption(q, v, t, task, u_draw)
        else:
            shapes = shapes + [Text(f"t = {t:5.2f} s")]
        return self._renderer.draw(shapes)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
