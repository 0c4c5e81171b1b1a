#!/usr/bin/env python
"""Chain algorithms against N, and against Pinocchio when it is installed.

Two chains, both timed for N = 2 ... 500, single call and per member of a batch of 256, with
log-log slopes (target ~1 for RNEA and ABA):

- **the planar special case** (:class:`SerialChain`: z-revolutes in the plane, whose Newton-Euler
  collapses to prefix sums): RNEA, ABA, CRBA + Cholesky; Pinocchio on the same chain of RZ joints;
- **the spatial chain** (:class:`SpatialChain`: revolute joints about alternating axes, full 3-D
  spatial-vector algorithms, the general case): ABA, RNEA, CRBA; Pinocchio's ``aba``, ``rnea``,
  ``crba`` on the same model (``JointModelRevoluteUnaligned``), single and member by member over the
  same batch, with the agreement of each.

Pinocchio runs in the same process when the ``pin`` package is importable (``pip install pin``,
optional). Medians over repeats; prints ratios; writes ``bench_chain.json`` and ``bench_chain.png``.

    python scripts/bench_chain.py --out results/chain
"""

from __future__ import annotations

import argparse
import pathlib
import sys

from mbs_envs.studies.chain_bench import SIZES, run


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--sizes", type=int, nargs="+", default=SIZES)
    a = p.parse_args(argv)
    run(a.out, a.sizes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
