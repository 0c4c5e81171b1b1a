"""Drawing the scenes with pygame, as Gymnasium's classic-control environments do.

A scene describes a frame as a list of shapes in world coordinates [m] (:class:`Line`,
:class:`Polygon`, :class:`Dot`, :class:`TorqueArc`, :class:`Arrow`, :class:`Text`); the
:class:`PlanarRenderer` maps them to pixels in a square window centred on a world point.
Serial arms share :func:`arm_shapes` (links with thickness, joints as circles, the
reference as a ghost, applied torques as arcs); the rolling disk projects its 3-D scene
with :func:`oblique` first (``mbs_envs.envs.rolling_disk``).

pygame is an optional dependency (``pip install mbs-envs[render]``); it is imported only
when an environment first renders.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from gymnasium.error import DependencyNotInstalled

Colour = tuple[int, int, int]

LINK = (0, 90, 200)
GHOST = (190, 205, 235)
JOINT = (30, 30, 30)
TORQUE = (220, 110, 0)
GROUND = (150, 150, 150)
TEXT = (20, 20, 20)


@dataclasses.dataclass(frozen=True)
class Line:
    """A polyline through ``points`` (k, 2) [m]; ``width`` in pixels."""

    points: np.ndarray
    colour: Colour = LINK
    width: int = 6
    closed: bool = False


@dataclasses.dataclass(frozen=True)
class Polygon:
    """A filled polygon with corners ``points`` (k, 2) [m]."""

    points: np.ndarray
    colour: Colour


@dataclasses.dataclass(frozen=True)
class Dot:
    """A filled circle of ``radius`` pixels at ``at`` (2,) [m]."""

    at: np.ndarray
    radius: int = 5
    colour: Colour = JOINT


@dataclasses.dataclass(frozen=True)
class TorqueArc:
    """An applied torque at ``at``: an arc of ``fraction * 300`` degrees (``fraction = u / u_max``
    in [-1, 1]; counter-clockwise positive) with an arrowhead at its end, ``radius`` [m]
    (at most 18 pixels; not drawn below 4)."""

    at: np.ndarray
    fraction: float
    radius: float
    colour: Colour = TORQUE


@dataclasses.dataclass(frozen=True)
class Arrow:
    """An arrow from ``start`` to ``end`` (2,) [m]."""

    start: np.ndarray
    end: np.ndarray
    colour: Colour = (40, 160, 60)
    width: int = 3


@dataclasses.dataclass(frozen=True)
class Inset:
    """``shapes`` drawn in their own square view (world centre ``center``, half-width ``extent``
    [m]) in a framed box of ``size`` pixels at the window's top-right corner, with a ``title``."""

    shapes: tuple
    center: np.ndarray
    extent: float
    size: int = 150
    title: str = ""


@dataclasses.dataclass(frozen=True)
class Text:
    """A line of text in the top-left corner, ``row`` lines down."""

    text: str
    row: int = 0
    colour: Colour = TEXT


Shape = Line | Polygon | Dot | TorqueArc | Arrow | Text | Inset


def arm_shapes(points: np.ndarray, ghost: np.ndarray | None = None, torques: Sequence[tuple[int, float]] = (),
               width: int = 8) -> list[Shape]:  # fmt: skip
    """A serial arm: links through ``points`` (k, 2) with joint circles, the reference pose
    ``ghost`` (k, 2) drawn faint underneath, and ``(joint index, u / u_max)`` torque arcs.

    The link thickness shrinks with the number of links and past 20 links only the base joint
    is marked (a 100-link chain stays legible).
    """
    n = len(points) - 1
    w = int(np.clip(round(width * 10 / max(n, 10)), 2, width))
    arc = 0.35 * float(np.min(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    dot = int(np.clip(w - 1, 2, 5))
    shapes: list[Shape] = []
    if ghost is not None:
        shapes.append(Line(ghost, GHOST, w))
    shapes.append(Line(points, LINK, w))
    shapes += [
        Dot(p, dot) for p in (points[:-1] if n <= 20 else points[:1])
    ]  # past 20 links the dots would hide the links
    shapes.append(Dot(points[-1], max(dot - 1, 2), LINK))
    shapes += [TorqueArc(points[j], float(np.clip(f, -1.0, 1.0)), arc) for j, f in torques if np.isfinite(f)]
    return shapes


def oblique(points: np.ndarray, azimuth: float = -np.pi / 3, elevation: float = np.pi / 6) -> np.ndarray:
    """Orthographic projection of world points ``(..., 3)`` [m] onto a camera's picture plane ``(..., 2)``.

    The camera looks along ``-c``, ``c = (cos el cos az, cos el sin az, sin el)``; the picture's
    right is ``(-sin az, cos az, 0)`` and its up ``(-sin el cos az, -sin el sin az, cos el)``
    (so vertical lines stay vertical and the ground plane is foreshortened by ``sin el``).
    """
    ca, sa, ce, se = np.cos(azimuth), np.sin(azimuth), np.cos(elevation), np.sin(elevation)
    right = np.array([-sa, ca, 0.0])
    up = np.array([-se * ca, -se * sa, ce])
    p = np.asarray(points, float)
    return np.stack([p @ right, p @ up], axis=-1)


class PlanarRenderer:
    """Draw shapes in a square world window.

    Parameters
    ----------
    extent : float
        Half-width of the shown world square [m].
    render_mode : {"human", "rgb_array"}
    fps : int
        Frame rate of the ``human`` window (the env's control rate).
    screen_size : int
        Window size in pixels.
    center : (float, float)
        World point at the centre of the window [m].
    ground : bool
        Draw the line ``y = 0``.
    """

    def __init__(
        self, extent: float, render_mode: str, fps: int, screen_size: int = 500, center=(0.0, 0.0), ground: bool = True
    ):
        try:
            import pygame
        except ImportError as e:  # pragma: no cover - exercised without pygame only
            raise DependencyNotInstalled('pygame is not installed, run `pip install "mbs-envs[render]"`') from e
        self._pygame = pygame
        self.extent = float(extent)
        self.center = np.asarray(center, float)
        self.render_mode = render_mode
        self.fps = fps
        self.size = screen_size
        self.ground = ground
        # no pygame.init(): it would also open the audio device, which on a machine without a sound card
        # prints ALSA errors ("cannot find card") and an XDG_RUNTIME_DIR complaint though no sound is
        # made; drawing needs the display (human mode) and, lazily, the font module (:meth:`_text`)
        if render_mode == "human":
            pygame.display.init()
            self.screen = pygame.display.set_mode((screen_size, screen_size))
        else:
            self.screen = pygame.Surface((screen_size, screen_size))
        self.clock = pygame.time.Clock()
        self._font = None
        self._view = (self.center, self.extent, self.size, (0, 0))

    def to_pixels(self, points: np.ndarray) -> list[tuple[int, int]]:
        """World points (k, 2) [m] to pixel coordinates (y down) of the current view."""
        center, extent, size, (ox, oy) = self._view
        scale = size / (2 * extent)
        rel = np.asarray(points, float).reshape(-1, 2) - center
        rel = np.clip(np.nan_to_num(rel), -1e3 * extent, 1e3 * extent)  # far-off points stay drawable integers
        px = ox + (rel[:, 0] + extent) * scale
        py = oy + (extent - rel[:, 1]) * scale  # y up in the world
        return [(int(round(x)), int(round(y))) for x, y in zip(px, py)]

    @property
    def _scale(self) -> float:
        center, extent, size, _ = self._view
        return size / (2 * extent)

    def draw(self, shapes: Sequence[Shape]) -> np.ndarray | None:
        """Draw one frame; return it as an ``(H, W, 3)`` uint8 array in ``rgb_array`` mode."""
        pygame = self._pygame
        self._view = (self.center, self.extent, self.size, (0, 0))
        surf = pygame.Surface((self.size, self.size))
        surf.fill((255, 255, 255))
        if self.ground:
            y0 = self.to_pixels(np.zeros((1, 2)))[0][1]
            pygame.draw.line(surf, (200, 200, 200), (0, y0), (self.size, y0), 1)
        for s in shapes:
            self._draw_one(surf, s)
        self.screen.blit(surf, (0, 0))
        if self.render_mode == "human":
            pygame.event.pump()
            self.clock.tick(self.fps)
            pygame.display.flip()
            return None
        return np.transpose(np.array(pygame.surfarray.pixels3d(self.screen)), axes=(1, 0, 2))

    def _draw_one(self, surf, s: Shape) -> None:
        pygame = self._pygame
        from pygame import gfxdraw

        if isinstance(s, Line):
            pix = self.to_pixels(s.points)
            if len(pix) > 1:
                pygame.draw.lines(surf, s.colour, s.closed, pix, s.width)
                if s.width > 3:  # round the corners of thick links
                    for x, y in pix:
                        pygame.draw.circle(surf, s.colour, (x, y), s.width // 2)
        elif isinstance(s, Polygon):
            pix = self.to_pixels(s.points)
            if len(pix) > 2:
                pygame.draw.polygon(surf, s.colour, pix)
        elif isinstance(s, Dot):
            x, y = self.to_pixels(s.at)[0]
            gfxdraw.aacircle(surf, x, y, s.radius, s.colour)
            gfxdraw.filled_circle(surf, x, y, s.radius, s.colour)
        elif isinstance(s, TorqueArc):
            self._draw_arc(surf, s)
        elif isinstance(s, Arrow):
            a, b = self.to_pixels(np.stack([s.start, s.end]))
            pygame.draw.line(surf, s.colour, a, b, s.width)
            d = np.subtract(b, a, dtype=float)
            if np.hypot(*d) > 1:
                d /= np.hypot(*d)
                n = np.array([-d[1], d[0]])
                tip = np.array(b, float)
                head = [tip, tip - 10 * d + 5 * n, tip - 10 * d - 5 * n]
                pygame.draw.polygon(surf, s.colour, [tuple(p) for p in head])
        elif isinstance(s, Inset):
            box = pygame.Rect(self.size - s.size - 4, 4, s.size, s.size)
            pygame.draw.rect(surf, (248, 248, 248), box)
            outer = self._view
            self._view = (np.asarray(s.center, float), s.extent, s.size, box.topleft)
            surf.set_clip(box)
            for inner in s.shapes:
                self._draw_one(surf, inner)
            surf.set_clip(None)
            self._view = outer
            pygame.draw.rect(surf, (120, 120, 120), box, 1)
            if s.title:
                img = self._text(s.title, (90, 90, 90), small=True)
                surf.blit(img, (box.left + 3, box.bottom - img.get_height() - 2))
        elif isinstance(s, Text):
            img = self._text(s.text, s.colour)
            surf.blit(img, (6, 4 + s.row * (img.get_height() + 1)))

    def _text(self, text: str, colour: Colour, small: bool = False):
        pygame = self._pygame
        if self._font is None:
            pygame.font.init()
            self._font = {k: pygame.font.Font(None, max(12, self.size // d)) for k, d in ((False, 26), (True, 34))}
        return self._font[small].render(text, True, colour)

    def _draw_arc(self, surf, s: TorqueArc) -> None:
        pygame = self._pygame
        if abs(s.fraction) < 1e-3:
            return
        radius = min(s.radius * self._scale, 18.0)
        if radius < 4.0:
            return
        cx, cy = self.to_pixels(s.at)[0]
        sweep = np.deg2rad(300.0) * s.fraction
        # start at the top (pi/2, world angles counter-clockwise); pixels have y down
        ang = np.pi / 2 + np.linspace(0.0, sweep, max(int(abs(sweep) * 12), 3))
        pts = [(cx + radius * np.cos(a), cy - radius * np.sin(a)) for a in ang]
        pygame.draw.lines(surf, s.colour, False, pts, 3)
        end, tangent = np.array(pts[-1]), np.sign(sweep) * np.array([-np.sin(ang[-1]), -np.cos(ang[-1])])
        normal = np.array([-tangent[1], tangent[0]])
        head = [end + 7 * tangent, end - 4 * tangent + 5 * normal, end - 4 * tangent - 5 * normal]
        pygame.draw.polygon(surf, s.colour, [tuple(p) for p in head])

    def close(self) -> None:
        """Close the window (if any) and quit pygame."""
        pygame = self._pygame
        if self.render_mode == "human":
            pygame.display.quit()
        pygame.quit()
