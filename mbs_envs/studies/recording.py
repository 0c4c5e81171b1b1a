"""Recording episodes of controllers and agents as videos (the logic of ``scripts/record.py``).

A policy is named as on the command line: a controller of the scene by a short name
(:func:`policy_names`: ``pd``, ``pdgravity``, ``ct``, ``lqr``, ``steering``, ``swingup``, ...),
a shipped agent group (``ppo``, ``sac``, ``td3``, ``residual-ppo``: the run of training
seed 0 under ``agents/<id>/<group>/``), a ``"module:Class"`` controller, or a folder with an
``agent.zip``. :func:`record_episode` rolls it out from ``reset(seed=...)`` in
``render_mode="rgb_array"`` and keeps every k-th frame; :func:`side_by_side` puts two
episodes of the same seed next to each other (the one that ends first holds its last
frame); :func:`write_video` writes MP4 (ffmpeg through imageio and imageio-ffmpeg) or GIF
(Pillow), where Gymnasium's ``RecordVideo`` would need moviepy.

Requires the ``render`` extra (pygame, imageio, imageio-ffmpeg).
"""

from __future__ import annotations

import dataclasses
import pathlib
import re

import gymnasium as gym
import numpy as np

from ..envs import registry
from .comparison import AGENT_GROUPS, load_policy

ROOT = pathlib.Path(__file__).resolve().parents[2]
#: short names of controllers beside their display names' squeezed form
ALIASES = {"ct": "computed torque", "swingup": "swing-up + LQR", "steering": "PD steering"}


def _squeeze(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def policy_names(env_id: str) -> list[str]:
    """The short names :func:`resolve_policy` accepts on ``env_id`` (controllers, then agent groups)."""
    scene = registry.scene(env_id)
    names = [_squeeze(c) for c in scene.controllers]
    names += [a for a, full in ALIASES.items() if full in scene.controllers]
    folder = ROOT / "agents" / env_id.split("/")[-1]
    names += [g for g in AGENT_GROUPS if (folder / g).is_dir()]
    return names


def resolve_policy(env_id: str, name: str) -> tuple[str, str]:
    """``(spec, label)`` of a policy name: ``spec`` for :func:`~mbs_envs.studies.comparison.load_policy`
    (``"module:Class"`` or an agent folder) and a display label.

    Raises
    ------
    ValueError
        Naming the policy and the names known on the scene.
    """
    scene = registry.scene(env_id)
    squeezed = {_squeeze(c): c for c in scene.controllers}
    display = ALIASES.get(name) if ALIASES.get(name) in scene.controllers else squeezed.get(_squeeze(name))
    if display is not None:
        return scene.controllers[display], display
    group = ROOT / "agents" / env_id.split("/")[-1] / name
    if name in AGENT_GROUPS and group.is_dir():
        run = group / "seed0" if (group / "seed0" / "agent.zip").exists() else group
        label = AGENT_GROUPS[name][0] + (" (training seed 0)" if run.name == "seed0" else "")
        return str(run), label
    if ":" in name and not pathlib.Path(name).exists():
        return name, next((c for c, spec in scene.controllers.items() if spec == name), name.split(":")[-1])
    if (pathlib.Path(name) / "agent.zip").exists():
        return name, pathlib.Path(name).name
    raise ValueError(
        f"policy {name!r} is not known on {env_id}; one of {policy_names(env_id)}, 'module:Class' or an agent folder"
    )


@dataclasses.dataclass(frozen=True)
class Recording:
    """The kept frames of one episode, ``(k, H, W, 3)`` uint8, and what they show."""

    frames: np.ndarray
    label: str
    fps: float
    steps: int
    episode_return: float
    ended: str


def record_episode(env_id: str, policy: str, seed: int, seconds: float | None = None, fps: float = 25.0,
                   env_kwargs: dict | None = None) -> Recording:  # fmt: skip
    """Roll out ``policy`` (a name, :func:`resolve_policy`) from ``reset(seed=seed)`` and keep a frame
    every ``round(control rate / fps)`` steps (the first and last always), for at most ``seconds``
    (default: the whole episode)."""
    spec, label = resolve_policy(env_id, policy)
    kwargs = dict(registry.scene(env_id).kwargs) | dict(env_kwargs or {})
    env = gym.make(env_id, render_mode="rgb_array", **kwargs)
    controller = load_policy(spec, gym.make(env_id, **kwargs))
    dt = env.unwrapped.dt
    every = max(int(round(1.0 / (fps * dt))), 1)
    limit = None if seconds is None else int(round(seconds / dt))
    obs, _ = env.reset(seed=seed)
    frames, state, start, total, k = [env.render()], None, np.ones(1, bool), 0.0, 0
    ended = "time limit"
    while True:
        action, state = controller.predict(obs, state=state, episode_start=start, deterministic=True)
        start = np.zeros(1, bool)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        k += 1
        last = terminated or truncated or (limit is not None and k >= limit)
        if k % every == 0 or last:
            frames.append(env.render())
        if last:
            ended = "terminated" if terminated else ("episode end" if truncated else f"{seconds:g} s shown")
            break
    env.close()
    return Recording(np.stack(frames), label, 1.0 / (every * dt), k, total, ended)


def _label(frame: np.ndarray, text: str) -> np.ndarray:
    """The frame with ``text`` written at its bottom (Pillow)."""
    from PIL import Image, ImageDraw

    img = Image.fromarray(frame)
    draw = ImageDraw.Draw(img)
    h = img.height
    draw.rectangle([0, h - 22, img.width, h], fill=(240, 240, 240))
    draw.text((6, h - 18), text, fill=(20, 20, 20))
    return np.asarray(img)


def side_by_side(recordings: list[Recording], size: int | None = None) -> np.ndarray:
    """The recordings' frames next to each other, each labelled and scaled to ``size`` pixels
    (square; default unchanged); a shorter one holds its last frame. Shape ``(k, H, W n, 3)``."""
    from PIL import Image

    n = max(len(r.frames) for r in recordings)
    columns = []
    for r in recordings:
        frames = [r.frames[min(i, len(r.frames) - 1)] for i in range(n)]
        if size is not None:
            frames = [np.asarray(Image.fromarray(f).resize((size, size), Image.LANCZOS)) for f in frames]
        columns.append(np.stack([_label(f, r.label) for f in frames]))
    return np.concatenate(columns, axis=2)


def write_video(frames: np.ndarray, path: pathlib.Path, fps: float, colours: int = 64) -> pathlib.Path:
    """Write ``frames`` (k, H, W, 3) uint8 to ``path``: ``.mp4`` (H.264, yuv420p, imageio-ffmpeg) or
    ``.gif`` (looping; Pillow, one palette of ``colours`` for all frames, no dithering: the line
    drawings stay crisp and the file small)."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == ".gif":
        from PIL import Image

        images = [Image.fromarray(f) for f in frames]
        sample = Image.fromarray(np.concatenate([frames[0], frames[len(frames) // 2], frames[-1]], axis=0))
        palette = sample.quantize(colors=colours, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        paletted = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
        paletted[0].save(
            path, save_all=True, append_images=paletted[1:], duration=int(round(1000.0 / fps)), loop=0, optimize=True
        )
    elif path.suffix == ".mp4":
        import imageio.v2 as imageio

        h, w = frames.shape[1:3]  # H.264 in yuv420p needs even sides
        frames = frames[:, : h - h % 2, : w - w % 2]
        with imageio.get_writer(path, fps=fps, codec="libx264", pixelformat="yuv420p", macro_block_size=1) as writer:
            for f in frames:
                writer.append_data(f)
    else:
        raise ValueError(f"video path must end in .mp4 or .gif, got {path.name!r}")
    return path


def gallery_pairs() -> list[tuple[str, str, str]]:
    """``(env id, model-based controller, agent group)`` of the README gallery: each scene's best
    model-based controller (:attr:`~mbs_envs.envs.registry.Scene.residual_base`) against PPO
    (the compared scenes: an earlier task version kept registered is not shown)."""
    pairs = []
    for s in registry.SCENES:
        if not s.compared:
            continue
        display = next(c for c, spec in s.controllers.items() if spec == s.residual_base)
        pairs.append((s.id, _squeeze(display), "ppo"))
    return pairs
