#!/usr/bin/env python
"""The main job: RL agents against model-based controllers on every scene.

For each scene (Planar2R, FourBar, SerialChain with 10 links, RollingDisk) the
model-based controllers (PD, PD + gravity, computed torque; on the disk LQR,
PD steering, no control) and the shipped agents (``agents/<id>/<algo>/``,
PPO and SAC) are rolled out on the same seeds through ``predict``:

- nominal plant; model mismatch (masses and lengths of the plant x (1 +- p),
  p = 10, 20, 30 %, while controllers keep the nominal model); observation noise;
- metrics: return, RMS (after 1 s) and max tracking error, RMS and peak
  torque, failure rate (falls, divergence), compute time per action;
- each agent's error against its training wall time (from its training log)
  beside the model-based controllers' error;
- actuator sizing by inverse dynamics for a reference motion of each actuated scene.

Writes ``report.md``, ``episodes.csv``, ``summary.json`` and PNG plots to ``--out``.
Cells run in local processes, or on Ray with ``--ray [ADDRESS]``.

    python scripts/compare.py --out results            # 20 seeds, all conditions (~2 min on 2 cores)
    python scripts/compare.py --out results --quick    # 3 seeds, nominal and +-20 % (~1 min)
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
from mbs_envs import comparison as cmp
from mbs_envs.parallel import run_tasks
from mbs_envs.plotting import pyplot, save
from mbs_envs.sizing import actuator_sizing

ROOT = pathlib.Path(__file__).resolve().parents[1]
METRICS = ["rms_error_settled", "max_error", "rms_torque", "peak_torque", "return", "failed", "latency_us"]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path, help="folder for the results")
    p.add_argument("--seeds", type=int, default=20, help="episodes per policy and condition (default 20)")
    p.add_argument("--quick", action="store_true", help="3 seeds, nominal and +-20 %% only")
    p.add_argument("--scene", action="append", choices=list(cmp.SCENES), help="scene(s) (default all)")
    p.add_argument("--agents", type=pathlib.Path, default=ROOT / "agents", help="folder of shipped agents")
    p.add_argument("--no-agents", action="store_true", help="model-based controllers only")
    p.add_argument("--workers", type=int, default=2, help="local processes")
    p.add_argument("--ray", nargs="?", const="local", help="run the cells on Ray (ADDRESS, or a local instance)")
    return p.parse_args(argv)


def run(args: argparse.Namespace) -> dict:
    n_seeds = 3 if args.quick else args.seeds
    if n_seeds < 1:
        raise SystemExit("--seeds must be >= 1")
    scenes = args.scene or list(cmp.SCENES)
    conds = cmp.conditions((0.2,), 0.01) if args.quick else cmp.conditions()
    args.out.mkdir(parents=True, exist_ok=True)
    seeds = list(range(n_seeds))
    tasks, agents = [], {}
    for scene in scenes:
        agents[scene] = {} if args.no_agents else cmp.find_agents(args.agents, scene)
        policies = {**cmp.SCENES[scene][2], **agents[scene]}
        for c in conds:
            tasks.append({"scene": scene, "condition": vars(c), "seeds": seeds, "policies": policies, "agents": list(agents[scene])})
    print(f"{len(tasks)} cells ({len(scenes)} scenes x {len(conds)} conditions), {n_seeds} seeds each")
    results = []
    if args.ray is None and args.workers > 1:
        results = run_tasks(cmp.evaluate_cell, tasks, max_workers=args.workers)
    elif args.ray is None:
        results = [cmp.evaluate_cell(t) for t in tqdm(tasks, desc="cells")]
    else:
        results = run_tasks(cmp.evaluate_cell, tasks, ray_address=args.ray)
    rows = [r for cell in results for r in cell]
    with open(args.out / "episodes.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    summary = summarize(rows)
    sizing = {scene: sizing_tables(scene) for scene in scenes if scene != "RollingDisk"}
    curves = {scene: training_curves(agents[scene]) for scene in scenes}
    for scene in scenes:
        plot_scene(scene, summary[scene], curves[scene], args.out / f"comparison_{scene}.png")
    report = make_report(summary, sizing, agents, n_seeds, conds)
    (args.out / "report.md").write_text(report)
    (args.out / "summary.json").write_text(json.dumps({"config": {"seeds": n_seeds, "conditions": [c.name for c in conds], "agents": agents},
                                                        "summary": summary, "sizing": sizing}, indent=2, default=float))  # fmt: skip
    print(headline(summary))
    print(f"written to {args.out}/report.md, episodes.csv, summary.json and comparison_<scene>.png")
    return {"summary": summary, "rows": rows, "sizing": sizing}


def summarize(rows: list[dict]) -> dict:
    """``summary[scene][condition][policy]`` = mean metrics over seeds (failure rate for ``failed``)."""
    out: dict = {}
    for r in rows:
        out.setdefault(r["scene"], {}).setdefault(r["condition"], {}).setdefault(r["policy"], []).append(r)
    for scene, by_cond in out.items():
        for cond, by_policy in by_cond.items():
            for policy, rs in by_policy.items():
                values = {m: np.array([float(x[m]) for x in rs]) for m in METRICS}
                # an episode that failed within the first second has no settled error:
                # means are over the episodes that have one (the failure rate says how many did not)
                means = {m: float(np.mean(v[np.isfinite(v)])) if np.isfinite(v).any() else float("nan") for m, v in values.items()}
                by_policy[policy] = {"kind": rs[0]["kind"], **means}
    return out


def worst_mismatch(by_cond: dict, policy: str, p: str = "20%") -> dict:
    """The worse (larger error) of the +p and -p mismatch conditions for ``policy``."""
    cells = [by_cond[c][policy] for c in (f"mismatch +{p}", f"mismatch -{p}") if c in by_cond]
    return max(cells, key=lambda m: (m["failed"], m["rms_error_settled"])) if cells else {}


def best(by_policy: dict, kind: str) -> str | None:
    """Best policy of a kind: fewest failures, then smallest settled RMS error."""
    names = [n for n, m in by_policy.items() if m["kind"] == kind]
    return min(names, key=lambda n: (by_policy[n]["failed"], by_policy[n]["rms_error_settled"])) if names else None


def headline(summary: dict) -> str:
    lines = ["| scene | | policy | RMS error t>=1 s [rad] | RMS torque [N m] | at 20 % mismatch: error / failures | compute per action [us] |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for scene, by_cond in summary.items():
        nominal = by_cond["nominal"]
        for kind in ("model-based", "RL"):
            name = best(nominal, kind)
            if name is None:
                lines.append(f"| {scene} | best {kind} | (none shipped) | | | | |")
                continue
            m, w = nominal[name], worst_mismatch(by_cond, name)
            rob = f"{w['rms_error_settled']:.3g} / {w['failed']:.0%}" if w else "-"
            lines.append(f"| {scene} | best {kind} | {name} | {m['rms_error_settled']:.3g} | {m['rms_torque']:.3g} | {rob} | {m['latency_us']:.0f} |")
    return "\n".join(lines)


def sizing_tables(scene: str) -> dict:
    """Inverse-dynamics sizing for the reference of seed 0 of the scene's task."""
    env_id, kwargs, _ = cmp.SCENES[scene]
    env = gym.make(env_id, **kwargs).unwrapped
    env.reset(seed=0)
    s = actuator_sizing(env.model, env.reference, t_final=5.0, dt=1e-3, branch=getattr(env, "branch", 1))
    out = {"drives": s.table(), "torque_limit": env.u_max.tolist()}
    if s.peak_joint_force is not None:
        out["peak_joint_force_N"] = dict(zip(["O (ground-crank)", "A (crank-coupler)", "B (coupler-rocker)", "C (rocker-ground)"], s.peak_joint_force.tolist()))
    return out


def training_curves(agents: dict[str, str]) -> dict[str, dict]:
    curves = {}
    for name, folder in agents.items():
        path = pathlib.Path(folder) / "training_log.csv"
        if path.exists():
            rows = list(csv.DictReader(open(path)))
            cfg = json.loads((pathlib.Path(folder) / "config.json").read_text())
            curves[name] = {"train_wall_s": [float(r["train_wall_s"]) for r in rows],
                            "rms_error_settled": [float(r["rms_error_settled"]) for r in rows],
                            "failure_rate": [float(r["failure_rate"]) for r in rows],
                            "steps": cfg["steps"], "command": cfg.get("command"), "wall": cfg["train_wall_s"]}  # fmt: skip
    return curves


def plot_scene(scene: str, by_cond: dict, curves: dict, path: pathlib.Path) -> None:
    plt = pyplot()
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(13, 4.5))
    conds = list(by_cond)
    policies = list(by_cond["nominal"])
    x = np.arange(len(conds))
    width = 0.8 / len(policies)
    for k, name in enumerate(policies):
        y = [by_cond[c][name]["rms_error_settled"] for c in conds]
        a0.bar(x + k * width, y, width, label=name)
    a0.set_yscale("log")
    a0.set_xticks(x + 0.4 - width / 2, conds, rotation=30, ha="right", fontsize=7)
    a0.set_ylabel("RMS tracking error, t >= 1 s [rad]")
    a0.legend(fontsize=7)
    a0.set_title(f"{scene}: error per condition (mean over seeds)")
    for name, c in curves.items():
        a1.plot(c["train_wall_s"], c["rms_error_settled"], "o-", label=f"{name} (training)")
    for name, m in by_cond["nominal"].items():
        if m["kind"] == "model-based":
            a1.axhline(m["rms_error_settled"], ls="--", lw=1, color="gray")
            a1.text(a1.get_xlim()[1] if curves else 1, m["rms_error_settled"], f" {name}", fontsize=7, va="center")
    a1.set_yscale("log")
    a1.set_xlabel("training wall time [s]")
    a1.set_ylabel("RMS error, t >= 1 s [rad]")
    a1.set_title("agents' error against training time (dashed: model-based)")
    if curves:
        a1.legend(fontsize=7)
    save(fig, path)


def make_report(summary: dict, sizing: dict, agents: dict, n_seeds: int, conds: list) -> str:
    L = ["# RL agents against model-based controllers", ""]
    L.append(f"{n_seeds} seeds per policy and condition (the same starts and references for every policy); "
             "errors are the Euclidean norm over tracked joints (the disk: its heading error), after the first second; "
             "failure: the episode ended early (fell or diverged); errors average the episodes that lasted past 1 s. "
             "Compute per action: one `predict` on a single observation. Mismatch: the plant's masses and lengths "
             "x (1 +- p), inertias x (1 +- p)^3, controllers and actuator limits nominal; noise: Gaussian, std 0.01 on every observation entry.")  # fmt: skip
    L += ["", "## Headline", "", headline(summary), ""]
    for scene, by_cond in summary.items():
        L += [f"## {scene}", "", f"![{scene}](comparison_{scene}.png)", ""]
        L.append("| condition | policy | RMS error t>=1 s | max error | RMS torque | peak torque | failures | return |")
        L.append("|---|---|---|---|---|---|---|---|")
        for cond, by_policy in by_cond.items():
            for name, m in by_policy.items():
                L.append(f"| {cond} | {name} | {m['rms_error_settled']:.3g} | {m['max_error']:.3g} | {m['rms_torque']:.3g} | "
                         f"{m['peak_torque']:.3g} | {m['failed']:.0%} | {m['return']:.1f} |")  # fmt: skip
        L.append("")
        for name, folder in agents.get(scene, {}).items():
            cfg = json.loads((pathlib.Path(folder) / "config.json").read_text())
            L.append(f"- {name}: `{cfg.get('command')}` ({cfg['train_wall_s']:.0f} s of training)")
        L.append("")
    if sizing:
        L += ["## Actuator sizing (inverse dynamics along the reference of seed 0, 5 s)", ""]
        for scene, s in sizing.items():
            L += [f"### {scene}", "", "| drive | peak torque [N m] | RMS torque [N m] | peak power [W] | RMS power [W] | torque limit [N m] |", "|---|---|---|---|---|---|"]
            for d in s["drives"]:
                L.append(f"| {d['drive'] + 1} | {d['peak_torque']:.3g} | {d['rms_torque']:.3g} | {d['peak_power']:.3g} | {d['rms_power']:.3g} | {s['torque_limit'][d['drive']]:.3g} |")
            if "peak_joint_force_N" in s:
                L.append("")
                L.append("Peak joint reaction forces [N] (from the Lagrange multipliers): " + ", ".join(f"{k} {v:.3g}" for k, v in s["peak_joint_force_N"].items()))
            L.append("")
    return "\n".join(L) + "\n"


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
