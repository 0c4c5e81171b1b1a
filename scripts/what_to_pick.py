#!/usr/bin/env python
"""What to pick, per scene and regime, at the environments' control step (10 ms).

For each regime case (:func:`mbs_envs.studies.stiff_cases.regimes`: every scene's environment
model under a held torque, the disk at 100x its critical spin, stiff viscous, Coulomb and Stribeck
friction, a 200-link chain under a 1000 rad/s joint PD) and each fixed-step method, the control step
is split into 1, 2, 4, 8, 16 physics steps (the environments' ``substeps``) until the trajectory
error over 1 s (0.05 s grid, against the stiff set's reference) is at most 1e-6. Picked per case:
the cheapest run (median wall time, on the path an environment takes) reaching 1e-6, and the
cheapest merely *usable* one (not flagged, trajectory error at most 1e-2).

Writes ``what_to_pick.csv`` (every run), ``what_to_pick.json`` and ``what_to_pick.md`` to ``--out``.

    python scripts/what_to_pick.py --out results/what_to_pick    # about 20 min here
    python scripts/what_to_pick.py --out docs/figures/what_to_pick --add --cases "Acrobot (environment model, 0.3 u_max held)"
"""

from __future__ import annotations

import argparse
import pathlib
import sys

from mbs_envs.studies.what_to_pick import from_csv, run


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--cases", nargs="+", help="subset of case names")
    p.add_argument("--methods", nargs="+", help="subset of integrators")
    p.add_argument("--accurate", type=float, default=1e-6, help="trajectory error target (default 1e-6)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs after the warm-up (default 3)")
    p.add_argument(
        "--from-csv", action="store_true", help="rewrite the picks and the table from the CSV in --out, no runs"
    )
    p.add_argument(
        "--add", action="store_true", help="run only --cases and merge them into the results already in --out"
    )
    a = p.parse_args(argv)
    if a.from_csv:
        from_csv(a.out)
        return 0
    if a.add and not (a.cases and (a.out / "what_to_pick.json").exists()):
        p.error("--add needs --cases and earlier results in --out")
    run(a.out, a.cases, a.methods, a.accurate, a.repeats, a.add)
    return 0


if __name__ == "__main__":
    sys.exit(main())
