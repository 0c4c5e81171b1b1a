"""Planar rendering with pygame, as Gymnasium's classic-control environments do.

pygame is an optional dependency (``pip install mbs-envs[render]``); it is
imported only when an environment first renders.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from gymnasium.error import DependencyNotInstalled

#: A polyline to draw: points in world coordinates [m], shape (k, 2), an RGB colour.
Polyline = tuple[np.ndarray, tuple[int, int, int]]


class PlanarRenderer:
    """Draw polylines (links) with joint markers in a square world window.

    Parameters
    ----------
    extent : float
        Half-width of the shown world square [m].
    render_mode : {"human", "rgb_array"}
    fps : int
        Frame rate of the ``human`` window.
    screen_size : int
        Window size in pixels.
    center : (float, float)
        World point at the centre of the window [m].
    """

    def __init__(
        self, extent: float, render_mode: str, fps: int, screen_size: int = 500, center=(0.0, 0.0)
    ):
        try:
            import pygame
        except ImportError as e:  # pragma: no cover - exercised without pygame only
            raise DependencyNotInstalled(
                'pygame is not installed, run `pip install "mbs-envs[render]"`'
            ) from e
        self._pygame = pygame
        self.extent = float(extent)
        self.center = np.asarray(center, float)
        self.render_mode = render_mode
        self.fps = fps
        self.size = screen_size
        pygame.init()
        if render_mode == "human":
            pygame.display.init()
            self.screen = pygame.display.set_mode((screen_size, screen_size))
        else:
            self.screen = pygame.Surface((screen_size, screen_size))
        self.clock = pygame.time.Clock()

    def _to_pixels(self, points: np.ndarray) -> list[tuple[int, int]]:
        scale = self.size / (2 * self.extent)
        rel = np.asarray(points) - self.center
        px = (rel[:, 0] + self.extent) * scale
        py = (self.extent - rel[:, 1]) * scale  # y up in the world
        return [(int(round(x)), int(round(y))) for x, y in zip(px, py)]

    def draw(self, polylines: Sequence[Polyline]) -> np.ndarray | None:
        """Draw one frame; return it as an ``(H, W, 3)`` uint8 array in ``rgb_array`` mode."""
        pygame = self._pygame
        from pygame import gfxdraw

        surf = pygame.Surface((self.size, self.size))
        surf.fill((255, 255, 255))
        origin = self._to_pixels(np.zeros((1, 2)))[0]  # the ground line y = 0
        gfxdraw.hline(surf, 0, self.size, origin[1], (200, 200, 200))
        for points, colour in polylines:
            pix = self._to_pixels(points)
            if len(pix) > 1:
                pygame.draw.lines(surf, colour, False, pix, 6)
            for x, y in pix:
                gfxdraw.filled_circle(surf, x, y, 5, (30, 30, 30))
        self.screen.blit(surf, (0, 0))
        if self.render_mode == "human":
            pygame.event.pump()
            self.clock.tick(self.fps)
            pygame.display.flip()
            return None
        return np.transpose(np.array(pygame.surfarray.pixels3d(self.screen)), axes=(1, 0, 2))

    def close(self) -> None:
        """Close the window (if any) and quit pygame."""
        pygame = self._pygame
        if self.render_mode == "human":
            pygame.display.quit()
        pygame.quit()
