#!/usr/bin/env python
"""Design the score-designed swing-up of the DFKI protocol ids (``ScoredSwingUp``) against the leaderboard's score.

For each robot: first swing-ups by iLQR from sinusoids (each horizon of ``--horizons`` s), fitted as splines of
torque knots ``--knot-dt`` s apart, then the best ``--top`` searched on the protocol's simulation-v2 score by a (1+1)
evolution strategy of ``--evaluations`` rollouts (:mod:`mbs_envs.studies.dfki_swingup`). Every leaderboard entry is
tuned on the nominal protocol, and so is this. Writes ``<robot>/design.json``, ``<robot>/design.png`` and ``report.md`` to ``--out``;
``--write`` stores the designs in ``controllers/scored_swingup.json`` (what ``ScoredSwingUp`` loads).

    python scripts/dfki_design.py --out results/dfki_design --write      # both robots, about 10 minutes
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import gymnasium as gym

import mbs_envs  # noqa: F401
from mbs_envs.controllers.scored_swingup import DESIGNS
from mbs_envs.studies import dfki_swingup as ds
from mbs_envs.studies.parallel import run_tasks

IDS = {"Acrobot": "mbs_envs/AcrobotDFKI-v1", "Pendubot": "mbs_envs/PendubotDFKI-v1"}


def one(task: dict) -> dict:
    env_id = IDS[task["robot"]]
    plant = ds.Plant.of(gym.make(env_id))
    z, info = ds.design(plant, tuple(task["horizons"]), task["knot_dt"], task["top"], task["evaluations"], task["seed"],
                        progress=lambda m: print(f"{task['robot']}: {m}", flush=True))  # fmt: skip
    return ds.write_design(pathlib.Path(task["out"]) / task["robot"], env_id, z, info, task["knot_dt"], task["command"])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--robot", nargs="+", choices=sorted(IDS), default=sorted(IDS))
    p.add_argument("--horizons", type=float, nargs="+", default=[1.2, 1.5])
    p.add_argument("--knot-dt", type=float, default=0.05)
    p.add_argument("--top", type=int, default=2)
    p.add_argument("--evaluations", type=int, default=15000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--write", action="store_true", help="store the designs in controllers/scored_swingup.json")
    a = p.parse_args(argv)
    command = "python scripts/dfki_design.py " + " ".join(argv if argv is not None else sys.argv[1:])
    tasks = [{"robot": r, "horizons": a.horizons, "knot_dt": a.knot_dt, "top": a.top, "evaluations": a.evaluations,
              "seed": a.seed, "out": str(a.out), "command": command} for r in a.robot]  # fmt: skip
    entries = run_tasks(one, tasks, max_workers=a.workers, progress="designs")
    for e in entries:
        c = e["criteria"]
        print(f"{e['env_id']}: score {c['score']:.4f} (swing-up {c['swingup_time']:.3f} s, energy {c['energy']:.2f} J, "
              f"torque cost {c['tau_cost']:.2f}, smoothness {c['tau_smoothness']:.4f}, velocity cost {c['velocity_cost']:.1f})")  # fmt: skip
    # the report covers every robot designed into --out, by this run or an earlier one (one robot at a time works)
    (a.out / "report.md").write_text(ds.design_report(ds.designs_in(a.out, tuple(IDS))))
    if a.write:
        stored = json.loads(DESIGNS.read_text()) if DESIGNS.exists() else {}
        stored.update({e["env_id"]: {"knot_dt": e["knot_dt"], "knots": e["knots"]} for e in entries})
        DESIGNS.write_text(json.dumps(stored, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
