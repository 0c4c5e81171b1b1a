#!/usr/bin/env python
"""A derived scene against its hand-written twin, in one run (issue 36's step-time and first-make targets).

The 2R arm written as a student would (centres of mass, then ``T`` and ``V``; ``mbs_envs.models.symbolic``)
and registered by ``mbs_envs.envs.derived.register`` with Planar2R-v0's limits, reference ranges and steps,
against ``mbs_envs/Planar2R-v0``:

- single step [us] (median of interleaved repeats) and the batched step per env-step at ``--num-envs``
  members, and their ratios (target <= 2x);
- the first ``gym.make`` + ``reset`` + ``step`` of the derived scene in a fresh process: with the derivation
  cache and numba's cache empty (``MBS_ENVS_DERIVED_CACHE`` and ``NUMBA_CACHE_DIR`` new folders), then again
  with both warm (targets <= 30 s and <= 2 s).

    python scripts/bench_derived.py --out results/derived

Writes ``bench_derived.json`` and ``bench_derived.md`` to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
from tqdm import tqdm

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: the user's code: the 2R arm from its Lagrangian, registered (Planar2R-v0's defaults)
USER_CODE = """
import numpy as np, sympy as sp
from sympy.physics.mechanics import dynamicsymbols
from mbs_envs.models import symbolic
from mbs_envs.envs import derived
from mbs_envs.envs.planar2r import Planar2REnv

t = dynamicsymbols._t
q1, q2 = dynamicsymbols("q1 q2")
m1, m2, l1, l2, r1, r2, I1, I2, g = sp.symbols("m1 m2 l1 l2 r1 r2 I1 I2 g")
x1, y1 = r1 * sp.cos(q1), r1 * sp.sin(q1)
x2, y2 = l1 * sp.cos(q1) + r2 * sp.cos(q1 + q2), l1 * sp.sin(q1) + r2 * sp.sin(q1 + q2)
d = lambda e: e.diff(t)
T = (m1 * (d(x1)**2 + d(y1)**2) + I1 * d(q1)**2 + m2 * (d(x2)**2 + d(y2)**2) + I2 * (d(q1) + d(q2))**2) / 2
V = g * (m1 * y1 + m2 * y2)
params = dict(m1=1.0, m2=1.0, l1=1.0, l2=1.0, r1=0.5, r2=0.5, I1=1 / 12, I2=1 / 12, g=9.81, b1=0.0, b2=0.0)
model = symbolic.derive("Arm2R", [q1, q2], T, V, params, damping={q1: "b1", q2: "b2"})
centre = (Planar2REnv.center_low + Planar2REnv.center_high) / 2
derived.register("bench/Arm2R-v0", model, torque_limit=(40.0, 20.0), posture=centre, substeps=2,
                 spread=(Planar2REnv.center_high - Planar2REnv.center_low) / 2, amplitude=Planar2REnv.max_amplitude,
                 coordinates=(q1, q2), points=[(0, 0), (l1 * sp.cos(q1), l1 * sp.sin(q1)), (x2 + (l2 - r2) * sp.cos(q1 + q2), y2 + (l2 - r2) * sp.sin(q1 + q2))])
"""

FIRST = """
import time
t0 = time.perf_counter()
import gymnasium as gym
import mbs_envs
{user}
env = gym.make("bench/Arm2R-v0")
env.reset(seed=0)
env.step(env.action_space.sample())
print(time.perf_counter() - t0)
"""


def first_make() -> dict:
    """Fresh-process seconds to the first step of the derived scene: caches empty, then warm (twice, the least)."""
    out = {}
    with tempfile.TemporaryDirectory() as derived_cache, tempfile.TemporaryDirectory() as numba_cache:
        env = {**os.environ, "MBS_ENVS_DERIVED_CACHE": derived_cache, "NUMBA_CACHE_DIR": numba_cache}
        code = FIRST.format(user=USER_CODE)
        for label in ("cold", "warm", "warm again"):
            res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=ROOT)
            out[label] = float(res.stdout.strip().splitlines()[-1])
    return {"cold_s": out["cold"], "warm_s": min(out["warm"], out["warm again"])}


def steps(repeats: int, n_steps: int, num_envs: int) -> dict:
    import gymnasium as gym

    import mbs_envs  # noqa: F401
    from mbs_envs.studies.benchmarking import time_steps

    exec(USER_CODE, {})
    rng = np.random.default_rng(0)
    ids = {"derived": "bench/Arm2R-v0", "hand-written": "mbs_envs/Planar2R-v0"}
    singles = {k: gym.make(v) for k, v in ids.items()}
    vectors = {k: gym.make_vec(v, num_envs=num_envs, vectorization_mode="vector_entry_point", full_info=False) for k, v in ids.items()}
    a1 = list(rng.uniform(-1, 1, (n_steps, 2)).astype(np.float32))
    aB = list(rng.uniform(-1, 1, (max(n_steps // 10, 20), num_envs, 2)))
    single = {k: [] for k in ids}
    batched = {k: [] for k in ids}
    for _ in tqdm(range(repeats), desc="interleaved repeats"):
        for k in ids:  # interleaved: both see the same machine state
            single[k].append(time_steps(singles[k], a1, 400))
            batched[k].append(time_steps(vectors[k], aB, 10**9) / num_envs)
    med = lambda xs: float(np.median(xs))  # noqa: E731
    return {"single_us": {k: med(v) * 1e6 for k, v in single.items()}, "batched_us": {k: med(v) * 1e6 for k, v in batched.items()},
            "single_ratio": med(single["derived"]) / med(single["hand-written"]),
            "batched_ratio": med(batched["derived"]) / med(batched["hand-written"])}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--steps", type=int, default=400)
    p.add_argument("--num-envs", type=int, default=1024)
    p.add_argument("--no-cold", action="store_true", help="skip the fresh-process first-make times")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    res = steps(args.repeats, args.steps, args.num_envs)
    if not args.no_cold:
        res["first_make"] = first_make()
    (args.out / "bench_derived.json").write_text(json.dumps(res, indent=2))
    lines = ["| scene | single step [us] | batched per env-step [us] |", "|---|---|---|"]
    for k in ("derived", "hand-written"):
        lines.append(f"| {k} | {res['single_us'][k]:.1f} | {res['batched_us'][k]:.3f} |")
    lines.append(f"| derived / hand-written | {res['single_ratio']:.2f}x | {res['batched_ratio']:.2f}x |")
    if "first_make" in res:
        lines.append(f"\nFirst make + reset + step of the derived scene in a fresh process: {res['first_make']['cold_s']:.1f} s with "
                     f"empty caches, {res['first_make']['warm_s']:.2f} s warm.")  # fmt: skip
    text = "\n".join(lines)
    (args.out / "bench_derived.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
