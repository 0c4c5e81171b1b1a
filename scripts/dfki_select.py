"""Run every checkpoint of a training run on the DFKI protocol, and ship the one with the best simulation-v2 score.

``--run`` is a folder written by ``scripts/train.py --checkpoint-every ...`` on ``mbs_envs/AcrobotDFKI-v2`` or
``mbs_envs/PendubotDFKI-v2`` (or the protocol ids). Each checkpoint runs the protocol's episode holding its decisions
as trained and deciding at every control step (``--action-repeats``; :mod:`mbs_envs.studies.dfki_selection` gives the
reasons); ``selection.csv``, ``selection.json`` and ``selection.png`` (score against control steps) go to ``--out``.
With ``--ship DST`` the best (checkpoint, decision interval) is shipped there (:func:`mbs_envs.studies.training.ship`:
no optimizer state, the whole chain's learning curve and budget, the choice recorded)::

    python scripts/dfki_select.py --run runs/AcrobotDFKI-v2/sac/seed0 --out results/select-acrobot
    python scripts/dfki_select.py --run runs/AcrobotDFKI-v2/sac/seed0 --out results/select-acrobot \\
        --ship agents/AcrobotDFKI-v2/sac/seed0
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys

from mbs_envs.studies import provenance


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--run", required=True, type=pathlib.Path, help="a training run's folder (with checkpoints/)")
    p.add_argument("--out", required=True, type=pathlib.Path, help="folder for selection.csv/json/png")
    p.add_argument("--action-repeats", type=int, nargs="+", default=None,
                   help="decision intervals to try [control steps] (default: the training's and 1)")  # fmt: skip
    p.add_argument("--ship", type=pathlib.Path, default=None, help="ship the best checkpoint to this folder")
    return p.parse_args(argv)


def run(args: argparse.Namespace) -> dict:
    # imported here: they load torch, which main() pins first
    from mbs_envs.studies import dfki_selection as sel
    from mbs_envs.studies.training import ship

    record = json.loads((args.run / "config.json").read_text()) if (args.run / "config.json").exists() else {}
    sel.checkpoints(args.run)  # refuses a folder without config.json or checkpoints before anything is written
    sel.protocol_id(record["env_id"])
    rows = sel.evaluate_run(args.run, args.action_repeats, progress=True)
    chosen = sel.best(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "selection.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    result = {"run": str(args.run), "env_id": record["env_id"], "rows": rows, "best": chosen,
              "command": provenance.command_line("dfki_select.py")}  # fmt: skip
    (args.out / "selection.json").write_text(json.dumps(result, indent=2))
    sel.plot(rows, args.out / "selection.png", f"{record['env_id']}: checkpoints on the protocol")
    print(f"best: checkpoint {chosen['checkpoint']} control steps, deciding every {chosen['action_repeat']}, "
          f"score {chosen['score']:.3f}")  # fmt: skip
    if args.ship is not None:
        kept = {"by": "simulation v2 score on the DFKI protocol", "score": chosen["score"],
                "action_repeat": chosen["action_repeat"]}  # fmt: skip
        size = ship(args.run, args.ship, checkpoint=chosen["checkpoint"], kept=kept,
                    evaluated_action_repeat=chosen["action_repeat"])  # fmt: skip
        print(f"shipped to {args.ship}: agent.zip {size / 1e6:.2f} MB")
    return result


def main(argv: list[str] | None = None) -> int:
    provenance.pin_numerics()  # before torch loads: the scores bit-equal with scripts/dfki.py's report
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
