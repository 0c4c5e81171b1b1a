#!/usr/bin/env python
"""Tune the gains of every model-based controller (the procedure of ``mbs_envs.studies.tuning``).

Rolls out each controller's grid of gains on the tuning seeds (disjoint from
the comparison's test seeds), nominal and at +-20 % mass/length mismatch, and
picks per scene the candidate with the fewest failures, then the smallest
mean settled tracking error. The pre-tuning defaults are scored beside them.
Writes ``tuning.csv``, ``tuning.json`` and ``tuning.png`` to ``--out``; with
``--write`` the chosen gains become the controllers' defaults
(``controllers/tuned.json``).

    python scripts/tune.py --out results/tune --write        # about 15 minutes on 2 cores
    python scripts/tune.py --scene Acrobot --refine-only --seeds 20 --out results/tune   # only the second stage

A controller with a second stage (:data:`mbs_envs.studies.tuning.REFINE`: the swing-up's LQR
weight and catch level) searches it around the first stage's pick; ``--refine-only`` starts it
from the stored pick instead of running the first stage again.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import mbs_envs  # noqa: F401
from mbs_envs.studies.comparison import SCENES

from mbs_envs.studies.gain_tuning import run


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path, help="folder for the results")
    p.add_argument("--seeds", type=int, default=10, help="tuning seeds per condition (default 10)")
    p.add_argument("--scene", action="append", choices=list(SCENES), help="scene(s) (default all)")
    p.add_argument(
        "--controller",
        action="append",
        help="controller(s) by display name, e.g. 'adaptive swing-up + LQR' (default all)",
    )
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--write", action="store_true", help="store the chosen gains in controllers/tuned.json")
    p.add_argument(
        "--refine-only",
        action="store_true",
        help="skip the first stage: refine the stored pick (controllers/tuned.json) in the second stage, where one exists",
    )
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    run(parse_args(argv))
    return 0


if __name__ == "__main__":
    sys.exit(main())
