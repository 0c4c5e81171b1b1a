#!/usr/bin/env python
"""Record an episode of a controller or a shipped agent to MP4 and GIF (``mbs_envs.studies.recording``).

    python scripts/record.py --env mbs_envs/Acrobot-v1 --policy swingup --seed 0 --out results/videos
    python scripts/record.py --env mbs_envs/RollingDisk-v0 --policy lqr --vs ppo --seed 3 --out results/videos

``--policy`` (and ``--vs``, for a second panel on the same seed): a controller's short name
(``pd``, ``pdgravity``, ``ct``, ``lqr``, ``steering``, ``swingup``, ...), a shipped agent group
(``ppo``, ``sac``, ``td3``, ``residual-ppo``; training seed 0), ``module:Class`` or an agent
folder. Writes ``<scene>_<policy>[_vs_<policy>]_seed<S>.mp4`` and ``.gif`` (``--format``) and a
``.json`` with what was recorded (steps, return, how the episode ended, run time).

    python scripts/record.py --gallery --out docs/gallery     # the README's gallery: every scene, GIF
    python scripts/record.py --gallery --env mbs_envs/Acrobot-v1 --out docs/gallery   # that scene's GIF again

``--gallery`` records every scene's best model-based controller beside PPO (training seed 0) on
test seed 0, GIFs (320 px panels, 10 frames/s, the first 8 s; 10 s on swing-up scenes; the
frame rate halved while a GIF is over 1.2 MB), one full-size PNG frame per scene and ``gallery.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import mbs_envs  # noqa: F401
from mbs_envs.studies import cli
from mbs_envs.studies.recording import record_episode, side_by_side, write_video
from mbs_envs.studies.provenance import command_line


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", choices=list(mbs_envs.ENV_IDS))
    p.add_argument("--policy", help="controller short name, agent group, module:Class or agent folder")
    p.add_argument(
        "--gallery", action="store_true", help="every scene: its best controller beside PPO, GIFs for the docs"
    )
    p.add_argument("--vs", help="a second policy, recorded on the same seed beside the first")
    p.add_argument("--seed", type=int, default=0, help="reset seed (default 0)")
    p.add_argument(
        "--seconds", type=cli.positive_float, help="at most this much of the episode (default the whole episode)"
    )
    p.add_argument("--fps", type=cli.positive_float, default=25.0, help="frames per second of the video (default 25)")
    p.add_argument("--size", type=cli.positive_int, help="pixels per panel (default 500, the env's frame)")
    p.add_argument("--format", nargs="+", choices=["mp4", "gif"], default=["mp4", "gif"])
    p.add_argument("--out", required=True, type=cli.out_folder)
    return p.parse_args(argv)


def run(args: argparse.Namespace) -> dict:
    if args.gallery:
        return gallery(args)
    if not (args.env and args.policy):
        raise SystemExit("record.py: --env and --policy are required (or --gallery)")
    tic = time.perf_counter()
    try:
        recordings = [
            record_episode(args.env, name, args.seed, args.seconds, args.fps)
            for name in [args.policy] + ([args.vs] if args.vs else [])
        ]
    except ValueError as exc:
        raise SystemExit(f"record.py: {exc}") from None
    frames = side_by_side(recordings, args.size)
    scene = args.env.split("/")[-1]
    names = [n.replace(":", "-").replace("/", "-") for n in [args.policy] + ([args.vs] if args.vs else [])]
    stem = f"{scene}_{'_vs_'.join(names)}_seed{args.seed}"
    paths = [str(write_video(frames, args.out / f"{stem}.{fmt}", recordings[0].fps)) for fmt in args.format]
    record = {
        "env_id": args.env, "seed": args.seed, "fps": recordings[0].fps, "frames": len(frames), "files": paths,
        "panels": [{"policy": n, "label": r.label, "steps": r.steps, "return": r.episode_return, "ended": r.ended}
                   for n, r in zip([args.policy, args.vs], recordings)],
        "run_time_s": time.perf_counter() - tic,
        "command": command_line("record.py"),
    }  # fmt: skip
    (args.out / f"{stem}.json").write_text(json.dumps(record, indent=2))
    for p in record["panels"]:
        print(f"{p['label']}: {p['steps']} steps, return {p['return']:.1f} ({p['ended']})")
    print(f"written {', '.join(paths)} in {record['run_time_s']:.1f} s")
    return record


def gallery(args: argparse.Namespace, budget: int = 1_200_000, panel: int = 320) -> dict:
    """The README gallery: one GIF per scene, model-based controller beside PPO (module docstring);
    a GIF over ``budget`` bytes is written again with every other frame (half the frame rate)."""
    from PIL import Image

    from mbs_envs.envs import registry
    from mbs_envs.studies.recording import gallery_pairs

    index = args.out / "gallery.json"
    records = (
        json.loads(index.read_text()) if args.env and index.exists() else {}
    )  # --env: that scene again, the rest kept
    for env_id, controller, agent in gallery_pairs():
        if args.env and env_id != args.env:
            continue
        tic = time.perf_counter()
        seconds = 10.0 if registry.scene(env_id).scoring == "swing-up" else 8.0
        recordings = [record_episode(env_id, name, 0, seconds, 10.0) for name in (controller, agent)]
        frames, fps = side_by_side(recordings, panel), recordings[0].fps
        still = args.out / f"{env_id.split('/')[-1]}.png"  # one full-size frame of the controller's episode, at mid-way
        Image.fromarray(recordings[0].frames[len(recordings[0].frames) // 2]).save(still)
        path = args.out / f"{env_id.split('/')[-1]}_{controller}_vs_{agent}_seed0.gif"
        while write_video(frames, path, fps).stat().st_size > budget and len(frames) > 10:
            frames, fps = frames[::2], fps / 2
        records[env_id] = {"file": str(path), "frame": str(still), "bytes": path.stat().st_size, "fps": fps, "frames": len(frames),
                           "panels": [{"policy": n, "label": r.label, "steps": r.steps, "return": r.episode_return, "ended": r.ended}
                                      for n, r in zip((controller, agent), recordings)],
                           "run_time_s": time.perf_counter() - tic}  # fmt: skip
        print(
            f"{path}: {path.stat().st_size / 1e3:.0f} kB, {len(frames)} frames at {fps:g}/s, {records[env_id]['run_time_s']:.1f} s"
        )
    index.write_text(
        json.dumps({k: v for k, v in records.items() if k in {e for e, _, _ in gallery_pairs()}}, indent=2)
    )
    return records


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
