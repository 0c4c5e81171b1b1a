#!/usr/bin/env python
"""Our swing-up controllers on the AI Olympics' global-policy protocol (the DFKI simulation leaderboard v3).

Each model-based swing-up controller (with its protocol gains) on both protocol ids for ``--seeds`` schedules of 15
disturbances in 60 s (:mod:`mbs_envs.studies.dfki_v3`: the disturbance's PID, the schedule and the uptime score as the
leaderboard's code defines them), in a pool of processes. Writes ``v3.json`` (every run's score and wall time, the
summary), ``v3.csv``, ``report.md`` (our rows beside the published leaders) and ``<robot>_<controller>.png`` (the best
seed's run) to ``--out``::

    python scripts/dfki_v3.py --out results/dfki_v3                 # every model-based controller x 2 robots x 3 seeds
    python scripts/dfki_v3.py --out results/dfki_v3 --seeds 0 --controller "swing-up + LQR"
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib

import mbs_envs  # noqa: F401
from mbs_envs.studies import dfki_v3
from mbs_envs.studies.dfki_job import MODEL_BASED
from mbs_envs.studies.parallel import run_tasks


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--scene", nargs="+", choices=["Acrobot", "Pendubot"], default=["Acrobot", "Pendubot"])
    p.add_argument("--controller", nargs="+", choices=sorted(MODEL_BASED), default=list(MODEL_BASED))
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--workers", type=int, default=None)
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    tasks = [{"scene": s, "name": n, "spec": MODEL_BASED[n], "seed": k} for s in a.scene for n in a.controller
             for k in a.seeds]  # fmt: skip
    results = run_tasks(dfki_v3.job, tasks, max_workers=a.workers, progress="v3 runs")
    rows = [r["row"] for r in results]
    summ = dfki_v3.summary(rows)
    (a.out / "v3.json").write_text(
        json.dumps({"rows": rows, "summary": summ, "published": dfki_v3.PUBLISHED_V3}, indent=1)
    )
    with open(a.out / "v3.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    text = dfki_v3.table(summ)
    (a.out / "report.md").write_text(text)
    import gymnasium as gym

    for s in summ:
        mine = [
            (r, res)
            for r, res in zip(rows, results)
            if r["env_id"] == s["env_id"] and r["controller"] == s["controller"]
        ]
        best_row, best = max(mine, key=lambda m: m[0]["score"])
        prm = gym.make(s["env_id"]).unwrapped.model.params
        name = (
            s["env_id"].split("/")[-1].replace("DFKI-v1", "")
            + "_"
            + s["controller"].replace(" ", "_").replace("+", "plus")
        )
        dfki_v3.plot_run(best["run"], prm.l1, prm.l2, f"{s['env_id']}, {s['controller']}: seed {best_row['seed']}, "
                         f"uptime {best_row['score']:.3f}", a.out / f"{name}.png")  # fmt: skip
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
