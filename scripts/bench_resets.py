#!/usr/bin/env python
"""Batched steps with episodes ending, against Gymnasium's CartPole vector env, in one run.

Per registered scene (the registry's ``bench_kwargs``, the 100-link chain left out): its vector env at
``--num-envs`` members (``full_info=False``, as ``scripts/bench_scenes.py``), stepped under zero actions
and under uniform random ones for long runs in which episodes end as they do (falls, terminations,
truncation by the id's ``max_episode_steps``) and members autoreset; the median per env-step [us] over
interleaved repeats, and its ratio to ``CartPoleVectorEnv`` under the same kind of action (zero: always
push left; random: uniform) timed in the same process. Each scene runs twice: with the starts of its
autoresets drawn ahead in batches (``draw_ahead=True``, the default) and drawn at the autoreset
(``draw_ahead=False``, the members reset in a step as one batch): before and after, same run.

    python scripts/bench_resets.py --out results/resets                 # ~4 min
    python scripts/bench_resets.py --out results/resets --scenes RollingDisk-v0 --repeats 9

Writes ``resets.json`` and ``resets.md`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import pathlib

from mbs_envs.studies.reset_bench import measure, report


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=pathlib.Path, required=True, help="folder for resets.json and resets.md")
    ap.add_argument("--num-envs", type=int, default=1024)
    ap.add_argument("--steps", type=int, default=300, help="steps per timed run")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--scenes", nargs="*", default=None, help="labels (prefixes) of the scenes to time; default all")
    a = ap.parse_args(argv)
    result = measure(a.num_envs, a.steps, a.repeats, a.scenes)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "resets.json").write_text(json.dumps(result, indent=2))
    text = report(result)
    (a.out / "resets.md").write_text(text)
    print(text)
    print(f"written to {a.out}/resets.json, resets.md")


if __name__ == "__main__":
    main()
