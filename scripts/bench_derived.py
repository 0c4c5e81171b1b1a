#!/usr/bin/env python
"""Derived scenes against their hand-written twins, in one run.

Two mechanisms written as a student would (``T`` and ``V``, and the loop closure; ``mbs_envs.models.symbolic``)
and registered by ``mbs_envs.envs.derived.register`` with the hand-written scene's limits, reference ranges and
steps: the 2R arm against ``mbs_envs/Planar2R-v0`` (unconstrained: the generated SIMD kernels), the four-bar
against ``mbs_envs/FourBar-v0`` (a closed loop: the generated SIMD batch kernels, the general member loops of
``mbs_envs.dynamics.constraints`` behind them; the episodes are FourBar-v0's to 1e-10, tested) and the 2R arm with
only the elbow driven on the derived swing-up task against ``mbs_envs/Acrobot-v1`` (the same plant and starts; the
task's height is the potential energy instead of the tip's: tested):

- single step [us] (median of interleaved repeats) and the batched step per env-step at ``--num-envs``
  members, and their ratios (target <= 2x);
- the first ``gym.make`` + ``reset`` + ``step`` in a fresh process of the derived 2R arm and of the built-in
  derived scenes ``SliderCrank-v0``, ``CartDoublePendulum-v0`` and ``CartPoleSwingUp-v0``: with the derivation cache and numba's cache
  empty (``MBS_ENVS_DERIVED_CACHE`` and ``NUMBA_CACHE_DIR`` new folders), then again with both warm (targets
  <= 30 s and <= 2 s).

    python scripts/bench_derived.py --out results/derived

Writes ``bench_derived.json`` and ``bench_derived.md`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
from tqdm import tqdm

from mbs_envs.studies.derived_bench import FIRST_MAKES, PAIRS, first_make, steps


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--steps", type=int, default=400)
    p.add_argument("--num-envs", type=int, default=1024)
    p.add_argument("--no-cold", action="store_true", help="skip the fresh-process first-make times")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    res = {"steps": {pair: steps(pair, args.repeats, args.steps, args.num_envs) for pair in PAIRS}}
    if not args.no_cold:
        res["first_make"] = {
            label: first_make(user, env_id) for label, (user, env_id) in tqdm(FIRST_MAKES.items(), desc="first makes")
        }
    (args.out / "bench_derived.json").write_text(json.dumps(res, indent=2))
    lines = [
        f"| mechanism | scene | single step [us] | batched per env-step at {args.num_envs} [us] |",
        "|---|---|---|---|",
    ]
    for pair, r in res["steps"].items():
        for k in ("derived", "hand-written"):
            lines.append(f"| {pair} | {k} | {r['single_us'][k]:.1f} | {r['batched_us'][k]:.3f} |")
        lines.append(f"| {pair} | derived / hand-written | {r['single_ratio']:.2f}x | {r['batched_ratio']:.2f}x |")
    if "first_make" in res:
        lines += ["", "| first make + reset + step, fresh process | empty caches [s] | warm [s] |", "|---|---|---|"]
        lines += [f"| {label} | {r['cold_s']:.1f} | {r['warm_s']:.2f} |" for label, r in res["first_make"].items()]
    text = "\n".join(lines)
    (args.out / "bench_derived.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
