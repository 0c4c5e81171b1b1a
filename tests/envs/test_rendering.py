"""What the scenes draw: frames are non-blank, follow the state, the disk shows its lean,
heading and spin; torques and the chain at 100 links are drawn; record.py writes playable videos."""

from __future__ import annotations

import json
import os
import pathlib
import runpy

import gymnasium as gym
import numpy as np
import pytest

import mbs_envs
from mbs_envs.envs import registry

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
pytest.importorskip("pygame")

ROOT = pathlib.Path(__file__).resolve().parents[2]
IDS = list(mbs_envs.ENV_IDS)


def drawn(frame: np.ndarray) -> int:
    """Pixels that are not the white background."""
    return int(np.count_nonzero(np.any(frame < 250, axis=-1)))


@pytest.mark.parametrize("env_id", IDS)
def test_frames_are_drawn_and_follow_the_state(env_id):
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    assert first.shape == (500, 500, 3) and first.dtype == np.uint8
    assert drawn(first) > 2000  # links, joints and captions: more than a few stray pixels
    rng = np.random.default_rng(0)
    for _ in range(30):
        env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
    later = env.render()
    assert drawn(later) > 2000
    assert np.count_nonzero(np.any(first != later, axis=-1)) > 200  # the picture moved with the state
    env.reset(seed=0)
    np.testing.assert_array_equal(env.render(), first)  # a frame is a function of the state
    env.close()


def test_torque_arcs_follow_the_applied_input():
    env = gym.make("mbs_envs/Planar2R-v0", render_mode="rgb_array").unwrapped
    env.reset(seed=0)
    q, v, t, task = env.q, env.v, 0.0, env._task
    quiet = env.render_state(q, t, task, v, np.zeros(2))
    ccw = env.render_state(q, t, task, v, 0.8 * env.u_max)
    cw = env.render_state(q, t, task, v, -0.8 * env.u_max)
    orange = lambda f: np.count_nonzero((f[..., 0] > 200) & (f[..., 1] > 80) & (f[..., 1] < 140) & (f[..., 2] < 60))  # noqa: E731
    assert orange(quiet) == 0 and orange(ccw) > 50 and orange(cw) > 50
    assert np.any(ccw != cw)  # the arc's direction is the torque's sign


def test_the_disk_shows_its_lean_heading_and_spin():
    env = gym.make("mbs_envs/RollingDisk-v0", render_mode="rgb_array")
    model = env.unwrapped.model

    def frame(**state):
        q, v = model.rolling_state(dspin=10.0, **state)
        env.reset(seed=0, options={"q": q, "v": v})
        return env.render()

    base = frame()
    for change in ({"lean": 0.3}, {"heading": 1.0}, {"spin": 1.0}):
        other = frame(**change)
        assert np.count_nonzero(np.any(other != base, axis=-1)) > 100, change
    # heading: the map from above (top right, north up) turns with it, not only the caption
    inset = (slice(4, 154), slice(346, 496))
    assert np.any(frame(heading=1.0)[inset] != base[inset])
    # a fall is said as such
    q, v = model.rolling_state(lean=1.0, dspin=10.0)
    env.reset(seed=0, options={"q": q, "v": v})
    fallen = env.render()
    red_text = np.count_nonzero(
        (fallen[..., 0] > 150) & (fallen[..., 1] < 60) & (fallen[..., 2] < 60) & (np.arange(500)[:, None] < 90)
    )
    assert red_text > 20
    env.close()


def test_the_contact_path_is_traced_behind_the_disk():
    env = gym.make("mbs_envs/RollingDisk-v0", render_mode="rgb_array")
    env.reset(seed=0)
    assert len(env.unwrapped.trail()) == 1
    for _ in range(100):
        env.step(np.zeros(2, np.float32))
    path = env.unwrapped.trail()
    assert path.shape == (101, 3) and np.ptp(path[:, :2], axis=0).max() > 0.1  # it rolled away
    np.testing.assert_allclose(
        path[-1], env.unwrapped.q[:3] + env.unwrapped.model.contact_offset(env.unwrapped.q), atol=1e-12
    )
    env.close()


def test_a_100_link_chain_stays_legible():
    env = gym.make("mbs_envs/SerialChain-v0", n_links=100, render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (500, 500, 3) and drawn(frame) > 2000
    blue = (frame[..., 2] > 150) & (frame[..., 0] < 60)
    rows = np.nonzero(blue.any(axis=1))[0]
    assert rows.max() - rows.min() > 150  # the hanging chain spans the picture ...
    assert len(rows) == rows.max() - rows.min() + 1  # ... as one unbroken line (no joint dots hiding it) ...
    assert blue.sum() / len(rows) >= 1.8  # ... two pixels thick
    env.close()


def test_vector_render_gives_captioned_frames_per_member():
    venv = gym.make_vec(
        "mbs_envs/Acrobot-v0", num_envs=2, vectorization_mode="vector_entry_point", render_mode="rgb_array"
    )
    venv.reset(seed=[0, 1])
    frames = venv.render()
    assert len(frames) == 2 and all(f.shape == (500, 500, 3) for f in frames)
    assert np.any(frames[0] != frames[1])
    venv.close()


def test_record_writes_playable_videos_side_by_side(tmp_path):
    imageio = pytest.importorskip("imageio.v2")
    pytest.importorskip("imageio_ffmpeg")
    script = runpy.run_path(str(ROOT / "scripts" / "record.py"))
    record = script["run"](script["parse_args"](["--env", "mbs_envs/Acrobot-v1", "--policy", "swingup", "--vs", "ppo", "--seed", "0",
                                                 "--seconds", "0.4", "--fps", "25", "--size", "120", "--out", str(tmp_path)]))  # fmt: skip
    assert [p["steps"] for p in record["panels"]] == [40, 40] and record["panels"][1]["label"].startswith("PPO")
    frames = imageio.mimread(tmp_path / "Acrobot-v1_swingup_vs_ppo_seed0.gif")
    assert len(frames) == record["frames"] == 11 and frames[0].shape[:2] == (120, 240)  # t = 0 and every 4th step
    reader = imageio.get_reader(tmp_path / "Acrobot-v1_swingup_vs_ppo_seed0.mp4")
    video = [f for f in reader]
    assert len(video) == 11 and video[0].shape == (120, 240, 3) and reader.get_meta_data()["fps"] == pytest.approx(25.0)
    assert json.loads((tmp_path / "Acrobot-v1_swingup_vs_ppo_seed0.json").read_text())["files"]


def test_record_names_unknown_policies():
    from mbs_envs.studies.recording import policy_names, resolve_policy

    assert {"swingup", "ppo"} <= set(policy_names("mbs_envs/Acrobot-v1"))
    assert {"swingup", "sac"} <= set(policy_names("mbs_envs/Acrobot-v2"))  # the agents of each task version
    assert {"pd", "pdgravity", "ct", "computedtorque"} <= set(policy_names("mbs_envs/Planar2R-v0"))
    assert resolve_policy("mbs_envs/Planar2R-v0", "ct") == ("mbs_envs.controllers:ComputedTorque", "computed torque")
    with pytest.raises(ValueError, match="'dance'.*one of"):
        resolve_policy("mbs_envs/Planar2R-v0", "dance")
    with pytest.raises(ValueError, match="swingup"):  # a controller of another scene
        resolve_policy("mbs_envs/Planar2R-v0", "swingup")


def test_every_compared_scene_shows_its_gallery_animation_on_its_page_and_the_readme_a_few():
    import re

    readme = (ROOT / "README.md").read_text()
    assert 2 <= len(re.findall(r"\((docs/gallery/[^)]+\.gif)\)", readme)) <= 4
    for s in registry.SCENES:
        if not s.compared:
            continue
        page = (ROOT / "docs" / "environments" / f"{s.id.split('/')[-1]}.md").read_text()
        gifs = re.findall(r"\(\.\./gallery/([^)]+\.gif)\)", page)
        assert len(gifs) == 1, s.id
        path = ROOT / "docs" / "gallery" / gifs[0]
        assert path.exists() and 10_000 < path.stat().st_size < 1_500_000, gifs[0]


@pytest.mark.parametrize("env_id", IDS)
def test_human_mode_draws_each_step_in_a_window(env_id):
    env = gym.make(env_id, render_mode="human")  # SDL's dummy video driver stands in for the screen
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.zeros(env.action_space.shape, np.float32))
    assert env.render() is None and env.unwrapped._renderer.fps == round(1 / env.unwrapped.dt)  # the control rate
    env.close()


def test_rendering_without_display_or_sound_card_prints_nothing_alarming():
    """issue 37: pygame.init() opened the audio device (ALSA "cannot find card", XDG_RUNTIME_DIR errors on
    a headless machine); drawing an rgb_array frame needs neither."""
    import os
    import subprocess
    import sys

    pytest.importorskip("pygame", reason="pygame (the render extra) is not installed")
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("DISPLAY", "SDL_VIDEODRIVER", "SDL_AUDIODRIVER", "XDG_RUNTIME_DIR")
    }
    code = ("import gymnasium as gym, mbs_envs\n"
            "e = gym.make('mbs_envs/Planar2R-v0', render_mode='rgb_array'); e.reset(seed=0); print(e.render().shape)")  # fmt: skip
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0 and "(500, 500, 3)" in r.stdout, r.stderr
    assert "ALSA" not in r.stderr and "XDG_RUNTIME_DIR" not in r.stderr, r.stderr
