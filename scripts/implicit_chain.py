#!/usr/bin/env python
"""The O(N) implicit joint step (``joint_implicit_euler``) on long chains, beside RK4 and SDIRK2.

1. Step time at N = 50, 100, 200, 500 (SerialChain-v0's chain, held zero torque,
   one step of 10 ms as an environment takes it; warm-up, then the median of
   repeated loops): ``joint_implicit_euler`` (numpy path around the compiled ABA),
   RK4 on the numpy and on the compiled path, SDIRK2 (dense Jacobian and solve).
2. Largest stable step on a stiff case: the chain under a joint PD of 1000 rad/s
   bandwidth per joint (:func:`mbs_envs.studies.stiff_cases.stiff_pd_chain`), ``dt``
   halved from 0.02 s until a run neither diverges nor ends more than 1e-3 rad
   from the target after 5 s.

Writes ``implicit_chain.csv`` (step times), ``implicit_chain_stability.csv``,
``implicit_chain.json``, ``implicit_chain.md`` and ``implicit_chain.png`` to ``--out``.

    python scripts/implicit_chain.py --out results/implicit_chain            # about 3 min here
    python scripts/implicit_chain.py --out results/implicit_chain --quick    # N = 20, 50
"""

from __future__ import annotations

import argparse
import pathlib
import sys

from mbs_envs.studies.implicit_chain_report import run


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--quick", action="store_true", help="N = 20 and 50, 3 repeats")
    p.add_argument("--n", type=int, nargs="+", help="chain lengths (default 50 100 200 500)")
    p.add_argument("--repeats", type=int)
    a = p.parse_args(argv)
    run(a.out, a.n, a.quick, a.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
