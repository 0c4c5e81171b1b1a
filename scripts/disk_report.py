#!/usr/bin/env python
"""Rolling disk: the critical spin derived and simulated, and balance controllers compared.

1. The derived critical spin ``W_c = sqrt(m g r A / (C (C + m r^2)))`` beside the
   threshold found by simulation alone: bisection on the spin, a run counting
   as unstable when the lean grows 1000x from 1e-6 rad within 40 s (a bounded
   oscillation above W_c reaches 1000x only within 0.1 % of W_c; exponential
   growth below it needs W < 0.9994 W_c), plus a sweep of the largest lean.
2. RollingDisk-v0 over ``--seeds`` seeds with no control, the PD steering law
   and LQR: episodes that stay upright, heading error, spin error, torque,
   compute per action.

Writes ``disk_report.json``, ``episodes.csv``, ``summary.md``,
``critical_spin.png`` and ``lean_traces.png`` to ``--out``.

    python scripts/disk_report.py --out results/disk            # ~5 minutes
"""

from __future__ import annotations

import argparse
import pathlib
import sys


import mbs_envs  # noqa: E402,F401  (registers the ids)
from mbs_envs.studies.disk_report import run  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--seeds", type=int, default=20)
    a = p.parse_args(argv)
    run(a.out, a.seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
