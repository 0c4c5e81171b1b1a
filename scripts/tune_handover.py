"""Tune where an RL agent's swing-up hands over to the LQR (RL + LQR) on the swing-up scenes.

For each swing-up scene with shipped RL agents, a grid of catch levels of ``x^T S x`` (and the
hysteresis factor) is scored by the success of every agent of the scene (every training seed of
every algorithm) on tuning seeds, at the nominal plant and +-20 % mismatch, as the model-based
controllers' gains are (``mbs_envs/studies/handover.py``). Writes ``handover_tuning.csv``,
``handover_tuning.json`` and ``handover_tuning.png`` to ``--out``; ``--write`` stores each
scene's pick (where some level made an agent succeed) in ``controllers/tuned.json`` as its ``"RL + LQR"`` entry, which the comparison's
``<agent> + LQR`` pairs then use::

    python scripts/tune_handover.py --out results/tune-handover --write    # a few minutes per scene
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys
import time

import numpy as np
from tqdm import tqdm

import mbs_envs  # noqa: F401
from mbs_envs.controllers import tuned
from mbs_envs.envs import registry
from mbs_envs.studies.comparison import SCENES, find_agents, kind_of
from mbs_envs.studies.handover import TUNED_NAME, tune_catch
from mbs_envs.studies.plotting import pyplot, save
from mbs_envs.studies.tuning import tuning_seeds
from mbs_envs.studies.training import load_agent
from mbs_envs.studies.provenance import command_line

#: catch levels from 300 to 1e7 (the first grid ended at 3e4, where the pendubot's pick sat at its edge: widened),
#: each with the hysteresis factors 2, 4 (the model-based controller's) and 16 (added in the third round)
GRID = [
    {"catch": c, "release": r}
    for c in (300.0, 1000.0, 3000.0, 10000.0, 30000.0, 1e5, 3e5, 1e6, 3e6, 1e7)
    for r in (2.0, 4.0, 16.0)
]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument(
        "--agents",
        type=pathlib.Path,
        default=pathlib.Path("agents"),
        help="root of the shipped agents (default agents/)",
    )
    p.add_argument("--seeds", type=int, default=40, help="tuning seeds per condition (default 40)")
    p.add_argument("--scene", action="append", help="scene(s) (default every swing-up scene)")
    p.add_argument("--write", action="store_true", help="store the picks in controllers/tuned.json")
    return p.parse_args(argv)


def run(args: argparse.Namespace) -> dict:
    scenes = args.scene or [s for s in SCENES if registry.scene(s).scoring == "swing-up"]
    args.out.mkdir(parents=True, exist_ok=True)
    seeds = tuning_seeds(args.seeds)
    record, rows = {"grid": GRID, "tuning_seeds": [seeds[0], seeds[-1]], "picks": {}}, []
    for scene in tqdm(scenes, desc="scenes"):
        folders = [f for name, fs in find_agents(args.agents, scene).items() if kind_of(name) == "RL" for f in fs]
        if not folders:
            print(f"{scene}: no shipped RL agents, skipped")
            continue
        tic = time.perf_counter()
        best, scene_rows = tune_catch(scene, [load_agent(pathlib.Path(f))[0] for f in folders], GRID, seeds)
        rows += [{"scene": scene, "agent_folder": folders[r["agent"]], **r} for r in scene_rows]
        chosen = [r for r in scene_rows if r["catch"] == best["catch"] and r["release"] == best["release"]]
        record["picks"][SCENES[scene][0]] = {"entry": best, "success": float(np.mean([r["success"] for r in chosen])),
                                             "agents": folders, "wall_s": time.perf_counter() - tic}  # fmt: skip
        print(f"{scene}: catch {best['catch']:g}, release {best['release']:g}: success {record['picks'][SCENES[scene][0]]['success']:.0%} "
              f"over {len(folders)} agents x nominal, +-20 %")  # fmt: skip
    if not rows:
        raise SystemExit("tune_handover.py: no swing-up scene has shipped RL agents")
    with open(args.out / "handover_tuning.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    command = command_line("tune_handover.py")
    record["command"] = command
    (args.out / "handover_tuning.json").write_text(json.dumps(record, indent=2))
    plot(rows, args.out / "handover_tuning.png")
    if args.write:
        stored = json.loads(tuned.PATH.read_text())
        for env_id, pick in record["picks"].items():
            if pick["success"] == 0:  # nothing to pick from: the pair keeps the swing-up + LQR's level
                print(f"{env_id}: no level made any agent succeed; not written")
                continue
            stored["gains"].setdefault(env_id, {})[TUNED_NAME] = pick["entry"]
            stored["scores"].setdefault(env_id, {})[TUNED_NAME] = {"success": pick["success"], "agents": pick["agents"],
                                                                   "wall_s": pick["wall_s"], "command": command}  # fmt: skip
        tuned.PATH.write_text(json.dumps(stored, indent=2) + "\n")
        tuned.clear_cache()
        print(f"written {tuned.PATH}")
    return record


def plot(rows: list[dict], path: pathlib.Path) -> None:
    """Success (mean over agents) against the catch level, one line per scene and condition."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for scene in dict.fromkeys(r["scene"] for r in rows):
        for cond in dict.fromkeys(r["condition"] for r in rows):
            mine = [r for r in rows if r["scene"] == scene and r["condition"] == cond]
            levels = sorted({r["catch"] for r in mine})
            ax.plot(
                levels,
                [np.mean([r["success"] for r in mine if r["catch"] == c]) for c in levels],
                marker="o",
                label=f"{scene}, {cond}",
            )
    ax.set(
        xscale="log",
        xlabel="catch level of x^T S x",
        ylabel="success (mean over agents)",
        title="RL + LQR: where the LQR takes over",
    )
    ax.legend(fontsize=7)
    save(fig, path)


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
