"""The six-axis robustness sweep on every scene: every model-based controller and every shipped agent.

The DFKI benchmark's robustness-v2 axes (model parameters, velocity-measurement noise, torque noise, torque
response, time delay, torque pulses) with ranges that suit each scene (``mbs_envs/studies/scene_robustness.py``
states them), success by the scene's own rule, the score as the mean of the six success fractions. One batched
rollout per axis; the policies run in parallel processes (``--workers``) or on Ray (``--ray``). Writes
``robustness.csv`` (one row per member: scene, policy, training seed, axis, parameter, value, seed, success),
``robustness.json`` (fractions, scores, wall times, the settings and the command), ``report.md`` (a table per
scene) and ``robustness_<scene>.png`` (success against each axis) to ``--out``::

    python scripts/robustness.py --out results/robustness                       # every scene, every policy
    python scripts/robustness.py --out results/robustness --scene Planar2R --values 21
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import pathlib
import sys
import time

# every core busy with this script's processes: kernels compile before they run (mbs_envs/dynamics/background.py)
os.environ.setdefault("MBS_ENVS_JIT", "sync")

import mbs_envs  # noqa: F401
from mbs_envs.studies import scene_robustness as sr
from mbs_envs.studies import provenance
from mbs_envs.studies.parallel import run_tasks
from mbs_envs.studies.comparison import find_agents


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--scene", action="append", choices=sorted(sr.SWEEPS), help="scene(s) (default every one)")
    p.add_argument(
        "--policy", action="append", help="policy display name(s), e.g. 'PD' or 'PPO + LQR' (default every one)"
    )
    p.add_argument(
        "--agents",
        type=pathlib.Path,
        default=pathlib.Path("agents"),
        help="root of the shipped agents (default agents/)",
    )
    p.add_argument("--no-agents", action="store_true", help="model-based controllers only")
    p.add_argument(
        "--values",
        type=int,
        default=sr.N_VALUES,
        help=f"values per axis (default {sr.N_VALUES}; the DFKI benchmark's 21)",
    )
    p.add_argument("--seeds", type=int, default=sr.N_SEEDS, help=f"test seeds per value (default {sr.N_SEEDS})")
    p.add_argument(
        "--pulse-episodes",
        type=int,
        default=sr.PULSE_EPISODES,
        help=f"perturbation episodes (default {sr.PULSE_EPISODES})",
    )
    p.add_argument("--seed", type=int, default=0, help="seeds the noise and the pulses")
    p.add_argument("--workers", type=int, default=None, help="local processes (default one per core)")
    p.add_argument(
        "--ray", nargs="?", const="local", default=None, help="run on Ray (cluster ADDRESS, or a local instance)"
    )
    return p.parse_args(argv)


def run(args: argparse.Namespace) -> dict:
    args.out.mkdir(parents=True, exist_ok=True)
    chosen = {scene: {name: specs for name, specs in sr.policies(scene, {} if args.no_agents else find_agents(args.agents, scene)).items()
                      if not args.policy or name in args.policy}
              for scene in args.scene or list(sr.SWEEPS)}  # fmt: skip
    jobs = sr.tasks(chosen, args.values, args.seeds, args.pulse_episodes, args.seed)
    if not jobs:
        raise SystemExit("robustness.py: no policy matches --scene / --policy")
    tic = time.perf_counter()
    results = run_tasks(
        sr.sweep_job, jobs, ray_address=args.ray, max_workers=args.workers, progress="robustness sweeps"
    )
    wall = time.perf_counter() - tic
    rows, summary, sweeps = sr.collect(jobs, results)
    with open(args.out / "robustness.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    sr.plot(sweeps, args.out)
    command = provenance.command_line("robustness.py")
    record = {"command": command, "values_per_axis": args.values, "seeds_per_value": args.seeds, "pulse_episodes": args.pulse_episodes,
              "seed": args.seed, "tolerance_rad": sr.TOLERANCE, "wall_s": wall, "scenes": summary,
              "ranges": {s: {k: (dict(v) if hasattr(v, "items") else v) for k, v in vars(sr.SWEEPS[s]).items()} for s in summary}}  # fmt: skip
    (args.out / "robustness.json").write_text(json.dumps(record, indent=2))
    (args.out / "report.md").write_text(report(record))
    for scene, by_policy in summary.items():
        for name, s in by_policy.items():
            print(f"{scene}, {name}: score {s['score']:.3f}")
    print(f"wall time {wall:.0f} s; written {args.out}")
    return record


def report(record: dict) -> str:
    out = [
        "# Robustness sweep on every scene",
        "",
        sr.describe(record["values_per_axis"], record["seeds_per_value"], record["pulse_episodes"]),
        "",
    ]
    for scene, by_policy in record["scenes"].items():
        out += [f"## {scene}", "", *sr.markdown_table(by_policy), "", f"![{scene}](robustness_{scene}.png)", ""]
    out += [f"Command: `{record['command']}`; total wall time {record['wall_s']:.0f} s."]
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    provenance.pin_numerics()  # before torch loads, here and in the workers (mbs_envs/studies/provenance.py)
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
