#!/usr/bin/env python
"""Constraint drift and energy drift of the four-bar over a long run, per stabilization.

Simulates FourBar (no torque, no friction: energy must be conserved) from a
consistent state for ``--steps`` RK4 steps with each of ``none``,
``baumgarte`` and ``projection``; records the loop-closure residual ``|phi|``
and the relative energy drift over the run. Writes ``constraint_drift.json``,
``constraint_drift.csv`` and ``constraint_drift.png`` to ``--out``.

    python scripts/constraint_drift.py --out results/drift              # 1e5 steps, ~3 min
    python scripts/constraint_drift.py --out results/drift --steps 2000
"""

from __future__ import annotations
import argparse
import pathlib
import sys
from mbs_envs.studies.drift_report import run


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--steps", type=int, default=100_000)
    p.add_argument("--dt", type=float, default=1e-3)
    a = p.parse_args(argv)
    run(a.out, a.steps, a.dt)
    return 0


if __name__ == "__main__":
    sys.exit(main())
