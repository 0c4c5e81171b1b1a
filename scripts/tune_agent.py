#!/usr/bin/env python
"""Search an RL agent's hyperparameters on the validation seeds (``mbs_envs.studies.agent_tuning``).

Trains one agent per combination of the ``--grid`` values (the same training seed and
budget for all), scores each by its last evaluation on the validation seeds (never the
comparison's test seeds) and ranks them by failure rate, then the scene's error metric,
then return. Writes ``OUT/candidate<k>/`` (each run, as ``scripts/train.py`` does),
``tuning.csv``, ``tuning.json`` and ``learning_curves.png`` to ``--out``. Then train the
shipped seeds with the pick: ``scripts/train.py --hyper KEY=VALUE ...``.

    python scripts/tune_agent.py --env mbs_envs/Acrobot-v0 --algo ppo --steps 1000000 \\
        --grid gamma=0.99,0.995,0.998 --grid ent_coef=0,0.01 --out results/tune-acrobot-ppo

``--grid action_repeat=1,4,8`` searches the control steps each action is held for
(a training setting, not an SB3 argument; ``scripts/train.py --action-repeat``).
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import mbs_envs  # noqa: F401
from mbs_envs.studies.training import ALGOS

from mbs_envs.studies.agent_search import grid_setting, run


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", required=True, choices=list(mbs_envs.ENV_IDS))
    p.add_argument("--algo", required=True, choices=sorted(ALGOS))
    p.add_argument("--steps", required=True, type=int, help="training steps of every candidate")
    p.add_argument("--grid", required=True, action="append", type=grid_setting, metavar="KEY=V1,V2,...")
    p.add_argument("--seed", type=int, default=0, help="training seed of every candidate (default 0)")
    p.add_argument("--eval-seeds", type=int, default=20, help="validation episodes per evaluation (default 20)")
    p.add_argument("--n-envs", type=int)
    p.add_argument("--net-arch", type=int, nargs="+")
    p.add_argument("--workers", type=int, help="parallel runs (default: the cores)")
    p.add_argument("--out", required=True, type=pathlib.Path)
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
