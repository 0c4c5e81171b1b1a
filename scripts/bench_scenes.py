#!/usr/bin/env python
"""Every scene's step against Gymnasium's peers, in one run; optionally an earlier version beside it.

Per registered scene (``gym.make`` defaults; the registry's ``bench_kwargs``: SerialChain at
``n_links`` 10 and 100):

- ``single``: median wall time of one ``env.step`` [us] over repeats, and its
  ratio to Acrobot-v1's step timed in the same process (interleaved);
- ``batched``: per env-step [us] of the vector env (``vector_entry_point``,
  ``full_info=False``) at ``--num-envs`` members, and the ratio to CartPole-v1's
  vector env timed in the same process;
- ``--processes K``: every figure above measured in ``K`` fresh processes (with ``--baseline``, the two checkouts'
  processes alternating) and the median of each taken, ratios per process first: the time of a compiled step moves
  by up to +-15 % from one process to the next on our machines (where the heap puts a kernel's work arrays), which
  repeats within one process do not see; the cold starts in the first process only;
- ``--sizes N1 N2 ...``: the batched per env-step again at each of these ``num_envs``, every scene and
  CartPole-v1 interleaved (CartPole's vector env pays a fixed numpy cost per call, so its time per env-step
  falls with the batch while a compiled step's stays about flat: the ratio depends on the batch size);
- ``cold start``: a fresh process's ``import`` + ``gym.make`` + ``reset`` +
  first ``step`` [s], with numba's on-disk cache empty (``NUMBA_CACHE_DIR`` a new
  folder: every kernel compiled) and then warm (the same folder again), in the default
  ``MBS_ENVS_JIT`` mode (a first step on the kernels' Python while a child process compiles
  them; ``(all compiled)``: until that child is done); Acrobot-v1 alike for scale. The steps timed
  in this process are compiled ones (``MBS_ENVS_JIT=sync`` here).

Only the public API is used, so ``--baseline DIR`` runs the very same
measurement on another checkout (e.g. ``git worktree add /tmp/old <rev>``) in
a subprocess and prints both tables: before and after, same run.

    python scripts/bench_scenes.py --out results/scenes                     # ~3 min
    python scripts/bench_scenes.py --out results/scenes --baseline /tmp/old
    python scripts/bench_scenes.py --out results/scenes --no-cold --sizes 64 256 1024 4096

Writes ``scenes.json`` (and ``baseline.json``, ``sizes.json``) and ``scenes.md`` to ``--out``.
"""

from __future__ import annotations

import argparse
import pathlib

from mbs_envs.studies import scene_bench


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=pathlib.Path)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--num-envs", type=int, default=1024)
    ap.add_argument("--no-cold", action="store_true", help="skip the fresh-process first-step timings")
    ap.add_argument("--baseline", type=pathlib.Path, help="another checkout to measure the same way (before/after)")
    ap.add_argument("--sizes", type=int, nargs="+", help="also time the batched step at each of these num_envs")
    ap.add_argument("--processes", type=int, default=1, help="measure in this many fresh processes, take medians")
    args = ap.parse_args(argv)
    text = scene_bench.run(args.out, args.repeats, args.steps, args.num_envs, not args.no_cold, args.baseline,
                           args.sizes, args.processes)  # fmt: skip
    print(text)


if __name__ == "__main__":
    main()
