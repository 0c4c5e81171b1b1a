#!/usr/bin/env python
"""Stiff and extreme cases: which integrators stay stable at which step, drift, cost,
and whether failures are reported.

Cases (see :mod:`mbs_envs.studies.stiff_cases`): large viscous friction; smoothed
Coulomb friction with a small smoothing speed; a high-gain PD and a
high-bandwidth computed-torque closed loop; extreme mass and inertia ratios;
the four-bar through toggles and through a change point; chains of 200 and
500 links (with SerialChain-v0's drives, and bare); the disk falling flat
(a singularity that must be reported); long horizons (1e5 steps).

For every case and fixed-step integrator the step is halved from 0.05 s until
the run is *usable* (not flagged, final state within 1e-2 of a Radau/DOP853
reference); flagged failures and silent failures (bounded but wrong, not
flagged) above it are counted. Adaptive methods are run once at rtol 1e-6.

Writes ``stiff_cases.md`` (the tables), ``stiff_cases.csv`` (every run),
``stiff_summary.csv``, ``stiff_cases.json`` and ``stiff_cases.png`` to ``--out``.

    python scripts/stiff_cases.py --out results/stiff           # ~15 min
    python scripts/stiff_cases.py --out results/stiff --quick   # 4 cases, ~1 min
"""

from __future__ import annotations

import argparse
import pathlib
import sys

from mbs_envs.studies.stiff_report import run


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--cases", nargs="+", help="subset of case names")
    p.add_argument(
        "--methods", nargs="+", help="subset of integrators (fixed-step scans; also the singular and long-run tables)"
    )
    a = p.parse_args(argv)
    run(a.out, a.quick, a.cases, a.methods)
    return 0


if __name__ == "__main__":
    sys.exit(main())
