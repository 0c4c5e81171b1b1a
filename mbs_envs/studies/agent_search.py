"""An RL agent's hyperparameter search on the validation seeds (:mod:`mbs_envs.studies.agent_tuning`) (the logic of ``scripts/tune_agent.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import numpy as np
import mbs_envs  # noqa: F401
from .agent_tuning import agent_grid, tune_agent
from .plotting import pyplot, save
from .training import hyper_setting
from .provenance import command_line


def grid_setting(text: str) -> tuple[str, list[int | float]]:
    """``"gamma=0.99,0.998"`` -> ``("gamma", [0.99, 0.998])``."""
    key, sep, values = text.partition("=")
    if not sep or not values:
        raise argparse.ArgumentTypeError(f"expected KEY=V1,V2,..., got {text!r}")
    return key, [hyper_setting(f"{key}={v}")[1] for v in values.split(",")]


def run(args: argparse.Namespace) -> dict:
    grid = agent_grid(dict(args.grid))
    extra = {"n_envs": args.n_envs, "net_arch": tuple(args.net_arch) if args.net_arch else None}
    try:
        best, rows = tune_agent(args.env, args.algo, args.steps, grid, args.out, seed=args.seed,
                                eval_seeds=args.eval_seeds, workers=args.workers, **extra)  # fmt: skip
    except ValueError as exc:
        raise SystemExit(f"tune_agent.py: {exc}") from None
    with open(args.out / "tuning.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows([dict(r, hyper=json.dumps(r["hyper"])) for r in rows])
    record = {"env_id": args.env, "algo": args.algo, "steps": args.steps, "seed": args.seed, "grid": dict(args.grid),
              "best": best, "rows": rows, "command": command_line("tune_agent.py")}  # fmt: skip
    (args.out / "tuning.json").write_text(json.dumps(record, indent=2))
    plot(rows, args.out / "learning_curves.png", args.env, args.algo)
    for r in rows:
        mark = "*" if r["hyper"] == best else " "
        print(
            f"{mark} {r['hyper']}: failures {r['failure_rate']:.0%}, return {r['return']:.1f}, {r['train_wall_s']:.0f} s"
        )
    flags = [f"--action-repeat {v}" if k == "action_repeat" else f"--hyper {k}={v}" for k, v in best.items()]
    print(f"best {best}; train the shipped seeds with: " + " ".join(flags))
    return record


def plot(rows: list[dict], path: pathlib.Path, env_id: str, algo: str) -> None:
    """Return and failure rate on the validation seeds against training steps, one line per candidate."""
    plt = pyplot()
    fig, (ax_r, ax_f) = plt.subplots(1, 2, figsize=(10, 4))
    for r in rows:
        with open(pathlib.Path(r["folder"]) / "training_log.csv") as f:
            log = list(csv.DictReader(f))
        steps = np.array([float(x["timesteps"]) for x in log])
        label = ", ".join(f"{k}={v}" for k, v in r["hyper"].items())
        ax_r.plot(steps, [float(x["return"]) for x in log], label=label)
        ax_f.plot(steps, [float(x["failure_rate"]) for x in log], label=label)
    ax_r.set_ylabel("mean return (validation seeds)")
    ax_f.set_ylabel("failure rate (validation seeds)")
    for ax in (ax_r, ax_f):
        ax.set_xlabel("training env-steps")
    ax_r.legend(fontsize=7)
    fig.suptitle(f"{algo} on {env_id}: hyperparameter candidates", fontsize=10)
    save(fig, path)
