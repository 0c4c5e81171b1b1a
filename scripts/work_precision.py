#!/usr/bin/env python
"""Work-precision: error against run time (and right-hand-side evaluations) for every scene and integrator.

Protocol and definitions: :mod:`mbs_envs.studies.work_precision`. In short: per
scene a free (frictionless, energy-conserving) and a forced problem (the scene as
its environment runs it: default friction, a smooth torque held per control
step); fixed-step methods swept over ``dt``, adaptive ones over ``rtol`` (one
whole-trajectory solve of free problems; restarted per control step on forced
ones, as environments do, and labelled so); each run warmed up, then the median
and minimum of ``--repeats`` timed runs of the stepping loop, on the numpy path
and on the compiled path where the environment takes it; errors against DOP853
at 1e-13, whose difference from Radau IIA at 1e-13 is the drawn floor.

Writes to ``--out``: ``work_precision.csv`` (one row per problem x integrator x
setting x path), ``work_precision.json`` (references, floors, protocol, run
time), ``work_precision.md`` (the cheapest run per problem and target) and
``work_precision_<problem>.png`` (trajectory error against median time and
against evaluations, with the floor; energy drift or constraint residual).

    python scripts/work_precision.py --out results/numerics            # about 25 min here
    python scripts/work_precision.py --out results/numerics --quick    # about 2 min
"""

from __future__ import annotations

import argparse
import pathlib
import sys


import mbs_envs  # noqa: E402,F401  (registers the ids)
from mbs_envs.studies.work_precision_report import replot, run  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--quick", action="store_true", help="0.4 s horizons, fewer settings, 3 repeats")
    p.add_argument("--problems", nargs="+", help="subset, e.g. planar2r-free fourbar-forced (default all)")
    p.add_argument("--methods", nargs="+", help="subset of integrators (default all)")
    p.add_argument("--repeats", type=int, help="timed runs per setting after the warm-up (default 5, quick 3)")
    p.add_argument("--n-fixed", type=int, help="number of dt values (halving from the interval)")
    p.add_argument("--n-adaptive", type=int, help="number of rtol values")
    p.add_argument(
        "--add", action="store_true", help="merge into the results already in --out (same problems replaced)"
    )
    p.add_argument("--replot", action="store_true", help="redraw the plots from the CSV and JSON in --out, no runs")
    a = p.parse_args(argv)
    if a.replot:
        replot(a.out)
        return 0
    run(a.out, a.quick, a.problems, a.methods, a.repeats, a.n_fixed, a.n_adaptive, a.add)
    return 0


if __name__ == "__main__":
    sys.exit(main())
