#!/usr/bin/env python
"""Soak and reliability: random-action episodes, determinism, long runs, parameters at the edges.

1. ``--episodes`` random-action episodes per registered id (10 % of actions out
   of range, up to 1e6) on the batched env: non-finite observations and rewards
   (target 0), divergences reported, terminations.
2. Determinism: the same seeds and actions through Gymnasium's Sync and Async
   (spawn) vector envs, the batched env, and SB3's SubprocVecEnv with spawn and
   forkserver; largest observation difference (target 0).
3. Long runs, 1e5 fixed steps of free motion: energy and constraint drift.
4. Parameters at the edges (0, -1, NaN, inf, 1e-6, 1e6 for masses and lengths
   of every model): ``ValueError`` naming the parameter, or a 1 s run's outcome.
5. Every integrator name on every id (:func:`mbs_envs.studies.reliability.integrator_soak`):
   random-action episodes, then runaway episodes (1e200 N m torque limit):
   non-finite outputs, exceptions, hangs (a single step over 60 s), divergences
   flagged, and the worst wall time of a diverging step.
6. Adversarial sequences on every id's batched env beside a twin
   (:func:`mbs_envs.studies.reliability.adversarial_soak`): steps with NaN actions for
   the members being reset, copies and pickles mid-episode, ``set_attr`` of every setting with bad
   values and of names that are not settings, refused resets, seeds, masks and actions: refusals
   accepted, state changed by a refusal, disagreements with the twin, exceptions other than ``ValueError``.
7. Threads on a cold cache (:func:`mbs_envs.studies.reliability.threads_cold`): fresh interpreters with empty
   kernel and derivation caches, four threads per id at once, each making, resetting and stepping its own env.

Writes ``soak.json``, ``soak.md`` and ``soak.png`` to ``--out``.

    python scripts/soak.py --out results/soak                  # 1e4 episodes per id, ~10 min
    python scripts/soak.py --out results/soak --quick          # 200 episodes, short runs
"""

from __future__ import annotations

import argparse
import pathlib
import sys

from mbs_envs.studies.soak import run


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--episodes", type=int, default=10_000)
    p.add_argument("--quick", action="store_true")
    a = p.parse_args(argv)
    run(a.out, 200 if a.quick else a.episodes, a.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
