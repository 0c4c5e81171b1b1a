#!/usr/bin/env python
"""Speed against peers, in one run: single step, batched step, chain dynamics, SB3 throughput.

Sections (each a median over repeats, printed as a ratio to its peer timed in
the same process):

1. ``single``: Planar2R-v0 against Gymnasium's Acrobot-v1, both through
   ``gym.make`` (their default wrappers); and the integration error each
   makes over one control step at its default settings, against DOP853 at
   rtol 1e-12 on the same equations. Also Planar2R-v0 at Acrobot's control
   step (0.2 s, 40 RK4 substeps: the default 5 ms physics step), time and error.
2. ``batched``: Planar2R-v0 as the numpy-batched vector env (RK4) against
   Gymnasium's CartPole-v1 vector env (``vector_entry_point``), per env-step at
   1024 envs.
3. ``chain``: SerialChain forward dynamics (ABA) at N = 100, single call and per
   env in a batch of 256, against Pinocchio's ``aba`` (when ``pin`` is
   installed); ``t(N=400) / t(N=50)``.
4. ``mujoco``: MuJoCo's InvertedDoublePendulum-v5 single step, and its error
   per control step against the same MuJoCo model at a 200x finer RK4 step (when
   ``mujoco`` is installed: ``pip install -e ".[bench]"``, which also brings ``pin``).
5. ``sb3``: PPO env-steps per second with our batched env through the SB3
   adapter against SB3's ``make_vec_env`` of single envs (DummyVecEnv), both
   for the whole ``learn`` and for rollouts alone, at 64, 256 and 1024 envs, with
   torch on one thread and on its default (one per core).

Writes ``bench.json`` and ``bench.png`` to ``--out``.

    python scripts/bench.py --out results/bench            # ~4-6 min here
    python scripts/bench.py --out results/bench --quick    # ~1 min
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys

os.environ.setdefault("MBS_ENVS_JIT", "sync")  # the steps timed are compiled ones (mbs_envs.dynamics.background)

import mbs_envs  # noqa: E402,F401  (registers the ids)
from mbs_envs.studies.bench_peers import run, sb3_scenes  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--sb3-only", nargs="+", metavar="ID", help="only PPO's throughput on these ids (1024 envs)")
    a = p.parse_args(argv)
    if a.sb3_only:
        sb3_scenes(a.sb3_only, a.out)
    else:
        run(a.out, a.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
