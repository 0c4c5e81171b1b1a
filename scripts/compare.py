#!/usr/bin/env python
"""Model-based controllers on Planar2R-v0: PD, PD + gravity, computed torque.

Runs each controller over the same seeds, prints a table of tracking error and
torque, and writes ``episodes.csv``, ``summary.json``, ``summary.md`` and
``comparison.png`` to ``--out``.

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
from controllers import PD, ComputedTorque, PDGravity
from mbs_envs.evaluation import episode_metrics, rollout

ENV_ID = "mbs_envs/Planar2R-v0"
CONTROLLERS = {"PD": PD, "PD+gravity": PDGravity, "computed torque": ComputedTorque}
COLUMNS = ["rms_error", "rms_error_settled", "max_error", "rms_torque", "peak_torque", "return", "compute_us_per_action"]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path, help="folder for the results")
    p.add_argument("--seeds", type=int, default=20, help="episodes per controller (default 20)")
    p.add_argument("--quick", action="store_true", help="3 seeds, for a smoke run")
    p.add_argument("--kp", type=float, default=100.0, help="proportional gain of all three (default 100)")
    p.add_argument("--kd", type=float, default=20.0, help="derivative gain of all three (default 20)")
    return p.parse_args(argv)


def run(args: argparse.Namespace) -> dict:
    n_seeds = 3 if args.quick else args.seeds
    if n_seeds < 1:
        raise SystemExit("--seeds must be >= 1")
    args.out.mkdir(parents=True, exist_ok=True)
    env = gym.make(ENV_ID)
    rows, examples = [], {}
    jobs = [(name, seed) for name in CONTROLLERS for seed in range(n_seeds)]
    for name, seed in tqdm(jobs, desc="episodes", unit="ep"):
        controller = CONTROLLERS[name](env, kp=args.kp, kd=args.kd)
        ep = rollout(env, controller, seed=seed)
        rows.append({"controller": name, "seed": seed, **episode_metrics(ep)})
        if seed == 0:
            examples[name] = ep
    env.close()

    with open(args.out / "episodes.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)

    summary = {}
    for name in CONTROLLERS:
        mine = [r for r in rows if r["controller"] == name]
        summary[name] = {c: float(np.mean([r[c] for r in mine])) for c in COLUMNS}
        summary[name]["failures"] = int(sum(r["diverged"] for r in mine))
    pd_err = summary["PD"]
    ct_err = summary["computed torque"]
    ratios = {
        "pd_over_ct_rms_error": pd_err["rms_error"] / ct_err["rms_error"],
        "pd_over_ct_rms_error_settled": pd_err["rms_error_settled"] / ct_err["rms_error_settled"],
    }
    meta = {"env": ENV_ID, "seeds": n_seeds, "kp": args.kp, "kd": args.kd, "settle_time_s": 1.0}
    (args.out / "summary.json").write_text(json.dumps({"config": meta, "summary": summary, "ratios": ratios}, indent=2))

    table = markdown_table(summary, n_seeds, args)
    table += (
        f"\nPD / computed torque RMS error: {ratios['pd_over_ct_rms_error']:.1f}x over the whole episode, "
        f"{ratios['pd_over_ct_rms_error_settled']:.1f}x after the first second.\n"
    )
    (args.out / "summary.md").write_text(table)
    plot(rows, examples, args.out / "comparison.png")
    print(table)
    print(f"results written to {args.out}/ (episodes.csv, summary.json, summary.md, comparison.png)")
    return {"summary": summary, "ratios": ratios}


def markdown_table(summary: dict, n_seeds: int, args: argparse.Namespace) -> str:
    head = (
        f"# {ENV_ID}: model-based controllers, mean over {n_seeds} seeds (kp={args.kp:g}, kd={args.kd:g})\n\n"
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


def plot(rows: list[dict], examples: dict, path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
    ax0.set_title("per seed (bars: means)")
    ax0.legend()
    for i, (name, ep) in enumerate(examples.items()):
        ax1.semilogy(ep.t, np.linalg.norm(ep.tracking_error, axis=-1) + 1e-12, label=name, color=f"C{i + 2}")
    ax1.set_xlabel("t [s]")
    ax1.set_ylabel("|q_ref - q| [rad]")
    ax1.set_title("seed 0")
    ax1.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
