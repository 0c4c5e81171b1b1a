#!/usr/bin/env python
"""Single-environment step time: Planar2R-v0 against Gymnasium's Acrobot-v1.

Both are made with ``gym.make`` (so both carry Gymnasium's default wrappers)
and stepped in the same process, in interleaved repeats; the medians and their
ratio are printed and written to ``--out`` as ``bench_step.json`` and
``bench_step.png``. Not a test: machines are noisy, read the ratio.

    python scripts/bench_step.py --out results/bench
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import sys
import time

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import mbs_envs  # noqa: F401
from mbs_envs.plotting import pyplot, save


def time_steps(env: gym.Env, actions: list, reset_every: int) -> float:
    """Mean wall time of one ``env.step`` over ``actions`` [s] (resets excluded)."""
    env.reset(seed=0)
    total = 0.0
    for k, a in enumerate(actions):
        tic = time.perf_counter()
        _, _, term, trunc, _ = env.step(a)
        total += time.perf_counter() - tic
        if term or trunc or (k + 1) % reset_every == 0:
            env.reset()
    return total / len(actions)


def run(out: pathlib.Path, repeats: int, steps: int) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    peers = {
        "Acrobot-v1": (gym.make("Acrobot-v1"), [int(a) for a in rng.integers(0, 3, steps)]),
        "Planar2R-v0 (rk4, dt=0.01)": (
            gym.make("mbs_envs/Planar2R-v0"),
            list(rng.uniform(-1, 1, (steps, 2)).astype(np.float32)),
        ),
        "Planar2R-v0 (rk4, dt=0.2 as Acrobot)": (
            gym.make("mbs_envs/Planar2R-v0", dt=0.2),
            list(rng.uniform(-1, 1, (steps, 2)).astype(np.float32)),
        ),
    }
    times: dict[str, list[float]] = {name: [] for name in peers}
    for _ in tqdm(range(repeats), desc="repeats"):
        for name, (env, actions) in peers.items():  # interleaved: drift hits all alike
            times[name].append(time_steps(env, actions, reset_every=400))
    med = {name: float(np.median(t)) for name, t in times.items()}
    ref = med["Acrobot-v1"]
    result = {
        "machine": {"python": platform.python_version(), "processor": platform.processor(), "numpy": np.__version__},
        "repeats": repeats,
        "steps_per_repeat": steps,
        "median_step_us": {k: v * 1e6 for k, v in med.items()},
        "ratio_to_acrobot": {k: v / ref for k, v in med.items()},
        "all_step_us": {k: [x * 1e6 for x in t] for k, t in times.items()},
    }
    (out / "bench_step.json").write_text(json.dumps(result, indent=2))
    plot(times, out / "bench_step.png")
    print(f"{'env':40s} {'median step [us]':>18s} {'ratio to Acrobot-v1':>20s}")
    for name in peers:
        print(f"{name:40s} {med[name] * 1e6:18.1f} {med[name] / ref:20.2f}")
    print(f"written to {out}/bench_step.json and bench_step.png")
    return result


def plot(times: dict, path: pathlib.Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 3.5))
    names = list(times)
    ax.boxplot([np.array(times[n]) * 1e6 for n in names], orientation="horizontal")
    ax.set_yticks(range(1, len(names) + 1), names)
    ax.set_xlabel("time per env.step [us] (per repeat)")
    ax.set_xscale("log")
    save(fig, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--repeats", type=int, default=15)
    p.add_argument("--steps", type=int, default=2000)
    a = p.parse_args(argv)
    run(a.out, a.repeats, a.steps)
    return 0


if __name__ == "__main__":
    sys.exit(main())
