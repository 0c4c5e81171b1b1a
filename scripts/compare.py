#!/usr/bin/env python
"""Model-based controllers on every tracking scene: PD, PD + gravity, computed torque.

Runs each controller on each scene (Planar2R-v0, FourBar-v0) over the same
seeds, prints a table of tracking error and torque per scene, and writes
``episodes.csv``, ``summary.json``, ``summary.md`` and one
``comparison_<scene>.png`` per scene to ``--out``.

Gains: computed torque uses kp = 100, kd = 20 [1/s^2, 1/s]; PD and PD + gravity
use each env's ``pd_gains``: the same numbers on Planar2R-v0, and on FourBar-v0
those scaled by the mean effective crank inertia (same bandwidth on average).

    python scripts/compare.py --out results            # 20 seeds
    python scripts/compare.py --out results --quick    # 3 seeds
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import mbs_envs  # noqa: F401  (registers the ids)
from mbs_envs.plotting import pyplot, save
from controllers import PD, ComputedTorque, PDGravity
from mbs_envs.evaluation import episode_metrics, rollout

ENV_IDS = ["mbs_envs/Planar2R-v0", "mbs_envs/FourBar-v0"]
CONTROLLERS = {"PD": PD, "PD+gravity": PDGravity, "computed torque": ComputedTorque}
COLUMNS = ["rms_error", "rms_error_settled", "max_error", "rms_torque", "peak_torque", "return", "compute_us_per_action"]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path, help="folder for the results")
    p.add_argument("--seeds", type=int, default=20, help="episodes per controller (default 20)")
    p.add_argument("--quick", action="store_true", help="3 seeds, for a smoke run")
    p.add_argument("--env", action="append", choices=ENV_IDS, help="scene(s) to run (default: all)")
    return p.parse_args(argv)


def run(args: argparse.Namespace) -> dict:
    n_seeds = 3 if args.quick else args.seeds
    if n_seeds < 1:
        raise SystemExit("--seeds must be >= 1")
    env_ids = args.env or ENV_IDS
    args.out.mkdir(parents=True, exist_ok=True)
    rows, examples = [], {}
    jobs = [(env_id, name, seed) for env_id in env_ids for name in CONTROLLERS for seed in range(n_seeds)]
    envs = {env_id: gym.make(env_id) for env_id in env_ids}
    for env_id, name, seed in tqdm(jobs, desc="episodes", unit="ep"):
        controller = CONTROLLERS[name](envs[env_id])
        ep = rollout(envs[env_id], controller, seed=seed)
        rows.append({"env": env_id, "controller": name, "seed": seed, **episode_metrics(ep)})
        if seed == 0:
            examples.setdefault(env_id, {})[name] = ep
    gains = {
        env_id: {name: {"kp": CONTROLLERS[name](env).kp.tolist(), "kd": CONTROLLERS[name](env).kd.tolist()} for name in CONTROLLERS}
        for env_id, env in envs.items()
    }
    for env in envs.values():
        env.close()

    with open(args.out / "episodes.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)

    summary, ratios, text = {}, {}, ""
    for env_id in env_ids:
        summary[env_id] = {}
        for name in CONTROLLERS:
            mine = [r for r in rows if r["env"] == env_id and r["controller"] == name]
            summary[env_id][name] = {c: float(np.mean([r[c] for r in mine])) for c in COLUMNS}
            summary[env_id][name]["failures"] = int(sum(r["diverged"] for r in mine))
        pd_err, ct_err = summary[env_id]["PD"], summary[env_id]["computed torque"]
        ratios[env_id] = {
            "pd_over_ct_rms_error": pd_err["rms_error"] / ct_err["rms_error"],
            "pd_over_ct_rms_error_settled": pd_err["rms_error_settled"] / ct_err["rms_error_settled"],
        }
        text += markdown_table(env_id, summary[env_id], n_seeds, gains[env_id])
        text += (
            f"\nPD / computed torque RMS error: {ratios[env_id]['pd_over_ct_rms_error']:.1f}x over the whole "
            f"episode, {ratios[env_id]['pd_over_ct_rms_error_settled']:.1f}x after the first second.\n\n"
        )
        plot(env_id, [r for r in rows if r["env"] == env_id], examples[env_id], args.out / f"comparison_{scene(env_id)}.png")
    meta = {"envs": env_ids, "seeds": n_seeds, "settle_time_s": 1.0, "gains": gains}
    (args.out / "summary.json").write_text(json.dumps({"config": meta, "summary": summary, "ratios": ratios}, indent=2))
    (args.out / "summary.md").write_text(text)
    print(text)
    print(f"results written to {args.out}/ (episodes.csv, summary.json, summary.md, comparison_*.png)")
    return {"summary": summary, "ratios": ratios}


def scene(env_id: str) -> str:
    return env_id.split("/")[-1].split("-")[0]


def markdown_table(env_id: str, summary: dict, n_seeds: int, gains: dict) -> str:
    gain_text = ", ".join(f"{n}: kp={g['kp'][0]:.3g}, kd={g['kd'][0]:.3g}" for n, g in gains.items())
    head = (
        f"## {env_id}: model-based controllers, mean over {n_seeds} seeds\n\n"
        f"Gains ({gain_text}); errors are the norm over tracked joints.\n\n"
        "| controller | RMS error [rad] | RMS error t>=1s [rad] | max error [rad] | RMS torque [N m] | "
        "peak torque [N m] | return | compute/action [us] | diverged |\n"
        "|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {name} | {s['rms_error']:.2e} | {s['rms_error_settled']:.2e} | {s['max_error']:.2e} | "
        f"{s['rms_torque']:.2f} | {s['peak_torque']:.2f} | {s['return']:.2f} | "
        f"{s['compute_us_per_action']:.0f} | {s['failures']} |"
        for name, s in summary.items()
    ]
    return head + "\n".join(lines) + "\n"


def plot(env_id: str, rows: list[dict], examples: dict, path: pathlib.Path) -> None:
    plt = pyplot()
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12, 4.5))
    names = list(CONTROLLERS)
    for i, name in enumerate(names):
        for k, col in enumerate(("rms_error", "rms_error_settled")):
            vals = [r[col] for r in rows if r["controller"] == name]
            x = i + (k - 0.5) * 0.3
            ax0.scatter(np.full(len(vals), x), vals, s=12, color=f"C{k}", label=None if i else ("whole episode", "t >= 1 s")[k])
            ax0.hlines(np.mean(vals), x - 0.12, x + 0.12, color=f"C{k}")
    ax0.set_xticks(range(len(names)), names)
    ax0.set_yscale("log")
    ax0.set_ylabel("RMS tracking error [rad]")
    ax0.set_title(f"{env_id}: per seed (bars: means)")
    ax0.legend()
    for i, (name, ep) in enumerate(examples.items()):
        ax1.semilogy(ep.t, np.linalg.norm(ep.tracking_error, axis=-1) + 1e-12, label=name, color=f"C{i + 2}")
    ax1.set_xlabel("t [s]")
    ax1.set_ylabel("|q_ref - q| [rad]")
    ax1.set_title("seed 0")
    ax1.legend()
    save(fig, path)


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
