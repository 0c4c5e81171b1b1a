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
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

#: the peer's label: Gymnasium's Acrobot-v1 (apart from our own mbs_envs/Acrobot-v1, labelled "Acrobot-v1")
PEER = "gymnasium Acrobot-v1"


def scenes() -> dict[str, tuple[str, dict]]:
    """Label -> (id, kwargs) of every configuration timed: each registered scene's ``bench_kwargs``
    (:mod:`mbs_envs.envs.registry`; a checkout without them: its ``kwargs``; one from before the
    registry, e.g. an older checkout's scenes)."""
    try:
        from mbs_envs.envs import registry
    except ImportError:
        return {"Planar2R-v0": ("mbs_envs/Planar2R-v0", {}), "FourBar-v0": ("mbs_envs/FourBar-v0", {}),
                "SerialChain-v0 (n_links=10)": ("mbs_envs/SerialChain-v0", {"n_links": 10}),
                "SerialChain-v0 (n_links=100)": ("mbs_envs/SerialChain-v0", {"n_links": 100}),
                "RollingDisk-v0": ("mbs_envs/RollingDisk-v0", {})}  # fmt: skip
    out = {}
    for s in registry.SCENES:
        for kw in getattr(s, "bench_kwargs", ()) or (dict(s.kwargs),):
            label = s.id.split("/")[-1] + (" (" + ", ".join(f"{k}={v}" for k, v in kw.items()) + ")" if kw else "")
            out[label] = (s.id, dict(kw))
    return out


COLD = """
import time, sys
t0 = time.perf_counter()
import gymnasium as gym
import numpy as np
if {mine!r}:
    import mbs_envs
env = gym.make({env_id!r}, **{kwargs!r})
env.reset(seed=0)
env.step(env.action_space.sample())
t1 = time.perf_counter() - t0
try:
    from mbs_envs.dynamics import background  # compiling in the background meanwhile (versions that do)
    background.wait()
except ImportError:
    pass
print(t1, time.perf_counter() - t0)
"""


def step_time(env, actions, reset_every=400) -> float:
    """Mean seconds per ``env.step`` over ``actions`` (resets not timed)."""
    from mbs_envs.studies.benchmarking import time_steps  # the checkout's own (an earlier version has it too)

    return time_steps(env, actions, reset_every)


def cold_start(env_id: str, kwargs: dict, python_path: str) -> dict:
    """Fresh-process seconds to the first step, numba cache empty then warm."""
    mine = env_id.startswith("mbs_envs/")
    env = {**os.environ, "PYTHONPATH": python_path}
    env.pop("MBS_ENVS_JIT", None)  # what a user gets: the default (this process compiles before it times)
    out, compiled = {}, {}
    with tempfile.TemporaryDirectory() as cache:
        env["NUMBA_CACHE_DIR"] = cache
        for label in ("cold", "warm", "warm again"):
            code = COLD.format(mine=mine, env_id=env_id, kwargs=kwargs)
            res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
            out[label], compiled[label] = map(float, res.stdout.strip().splitlines()[-1].split())
    return {"cold_s": out["cold"], "warm_s": min(out["warm"], out["warm again"]), "cold_compiled_s": compiled["cold"]}


def batch_timed(name: str) -> bool:
    """Whether the batched step is timed for the configuration ``name`` (not at 100 links)."""
    return "n_links=100" not in name


def cartpole_vector(num_envs: int, n_calls: int, rng: np.random.Generator) -> tuple:
    """Gymnasium's CartPole-v1 vector env of ``num_envs`` members and ``n_calls`` random actions for it."""
    import gymnasium as gym

    env = gym.make_vec("CartPole-v1", num_envs=num_envs, vectorization_mode="vector_entry_point")
    return env, [rng.integers(0, 2, num_envs) for _ in range(n_calls)]


def scene_vector(env_id: str, kwargs: dict, num_envs: int, n_calls: int, rng: np.random.Generator) -> tuple:
    """A scene's vector env (``full_info=False``) of ``num_envs`` members and ``n_calls`` random actions for it."""
    import gymnasium as gym

    env = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", full_info=False, **kwargs)
    return env, list(rng.uniform(-1, 1, (n_calls, num_envs, env.single_action_space.shape[0])))


def measure(repeats: int, steps: int, num_envs: int, cold: bool) -> dict:
    os.environ.setdefault(
        "MBS_ENVS_JIT", "sync"
    )  # steps timed here are compiled ones (not the kernels' Python meanwhile)
    import gymnasium as gym

    import mbs_envs

    rng = np.random.default_rng(0)
    n_calls = max(steps // 10, 20)
    singles = {PEER: (gym.make("Acrobot-v1"), [int(a) for a in rng.integers(0, 3, steps)])}
    vectors = {"CartPole-v1": cartpole_vector(num_envs, n_calls, rng)}
    for name, (env_id, kwargs) in scenes().items():
        e = gym.make(env_id, **kwargs)
        singles[name] = (e, list(rng.uniform(-1, 1, (steps, e.action_space.shape[0])).astype(np.float32)))
        if batch_timed(name):
            vectors[name] = scene_vector(env_id, kwargs, num_envs, n_calls, rng)
    single_t = {k: [] for k in singles}
    vector_t = {k: [] for k in vectors}
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        tqdm = lambda x, **k: x  # noqa: E731
    for _ in tqdm(range(repeats), desc="scenes", file=sys.stderr):
        for name, (env, acts) in singles.items():  # interleaved: drift hits every scene alike
            single_t[name].append(step_time(env, acts))
        for name, (env, acts) in vectors.items():
            vector_t[name].append(step_time(env, acts, reset_every=10**9))
    single = {k: float(np.median(v)) * 1e6 for k, v in single_t.items()}
    batched = {k: float(np.median(v)) / num_envs * 1e6 for k, v in vector_t.items()}
    out = {
        "python_path": str(pathlib.Path(mbs_envs.__file__).parent.parent),
        "num_envs": num_envs,
        "single_step_us": single,
        "single_ratio_to_acrobot": {k: v / single[PEER] for k, v in single.items()},
        "batched_per_env_step_us": batched,
        "batched_ratio_to_cartpole": {k: v / batched["CartPole-v1"] for k, v in batched.items()},
    }
    if cold:
        root = out["python_path"]
        starts = {PEER: cold_start("Acrobot-v1", {}, root)}
        for name, (env_id, kwargs) in tqdm(list(scenes().items()), desc="cold starts", file=sys.stderr):
            starts[name] = cold_start(env_id, kwargs, root)
        out["first_step_s"] = starts
    return out


#: the figures :func:`combine` takes the median of, over processes (ratios per process first)
PER_PROCESS = ("single_step_us", "single_ratio_to_acrobot", "batched_per_env_step_us", "batched_ratio_to_cartpole")


def combine(runs: list[dict]) -> dict:
    """One result from :func:`measure`'s results in several processes: the median of each figure of
    :data:`PER_PROCESS`, the range of the batched ratios, every run kept (``runs``), the cold starts of the first."""
    out = {k: v for k, v in runs[0].items() if k not in PER_PROCESS}
    for key in PER_PROCESS:
        out[key] = {name: float(np.median([r[key][name] for r in runs])) for name in runs[0][key]}
    out["batched_ratio_range"] = {name: [min(r["batched_ratio_to_cartpole"][name] for r in runs),
                                         max(r["batched_ratio_to_cartpole"][name] for r in runs)]
                                  for name in runs[0]["batched_ratio_to_cartpole"]}  # fmt: skip
    out["processes"] = len(runs)
    out["runs"] = runs
    return out


def child(root: pathlib.Path, args: argparse.Namespace, cold: bool) -> dict:
    """:func:`measure` in a fresh process on the checkout ``root`` (this script's copy of it runs there)."""
    cmd = [sys.executable, __file__, "--out", str(args.out), "--repeats", str(args.repeats), "--steps", str(args.steps),
           "--num-envs", str(args.num_envs), "--json-only"] + ([] if cold else ["--no-cold"])  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(root.resolve())}
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True, cwd=root)
    return json.loads(res.stdout.strip().splitlines()[-1])


def sweep(sizes: list[int], repeats: int, steps: int) -> dict:
    """Batched per env-step [us] of every scene and CartPole-v1's vector env at each of ``sizes`` members
    (``full_info=False``; medians over ``repeats``, the scenes interleaved), with the ratios to CartPole."""
    os.environ.setdefault("MBS_ENVS_JIT", "sync")
    import mbs_envs  # noqa: F401

    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        tqdm = lambda x, **k: x  # noqa: E731
    rng = np.random.default_rng(0)
    n_calls = max(steps // 10, 20)
    out: dict = {"sizes": sizes, "per_env_step_us": {}, "ratio_to_cartpole": {}}
    for n in tqdm(sizes, desc="sizes", file=sys.stderr):
        vectors = {"CartPole-v1": cartpole_vector(n, n_calls, rng)}
        vectors.update(
            {
                name: scene_vector(env_id, kwargs, n, n_calls, rng)
                for name, (env_id, kwargs) in scenes().items()
                if batch_timed(name)
            }
        )
        times: dict = {k: [] for k in vectors}
        for _ in range(repeats):
            for name, (env, acts) in vectors.items():
                times[name].append(step_time(env, acts, reset_every=10**9))
        per = {k: float(np.median(t)) / n * 1e6 for k, t in times.items()}
        out["per_env_step_us"][str(n)] = per
        out["ratio_to_cartpole"][str(n)] = {k: v / per["CartPole-v1"] for k, v in per.items()}
        for env, _ in vectors.values():
            env.close()
    return out


def sweep_table(r: dict) -> str:
    sizes = [str(n) for n in r["sizes"]]
    lines = ["### Batched per env-step by batch size [us] (ratio to CartPole-v1's vector env)", "",
             "| scene | " + " | ".join(f"{n} envs" for n in sizes) + " |", "|---|" + "---|" * len(sizes)]  # fmt: skip
    for name in r["per_env_step_us"][sizes[0]]:
        cells = []
        for n in sizes:
            t, x = r["per_env_step_us"][n][name], r["ratio_to_cartpole"][n][name]
            cells.append(f"{t:.3f}" if name == "CartPole-v1" else f"{t:.3f} ({x:.1f}x)")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def table(r: dict, title: str) -> str:
    if "processes" in r:
        lo_hi = r["batched_ratio_range"]
        title += f" (medians of {r['processes']} fresh processes; the batched ratios' range in brackets)"
    lines = [
        f"### {title}", "",
        f"| scene | single step [us] | vs Acrobot-v1 ({r['single_step_us'][PEER]:.0f} us) "
        f"| batched per env-step at {r['num_envs']} [us] | vs CartPole-v1 vector ({r['batched_per_env_step_us']['CartPole-v1']:.3f} us) "
        "| first step, fresh process: cold (all compiled) / warm cache [s] |",
        "|---|---|---|---|---|---|",
    ]  # fmt: skip
    for name in (k for k in r["single_step_us"] if k != PEER):
        b = r["batched_per_env_step_us"].get(name)
        fs = r.get("first_step_s", {}).get(name)
        lines.append(
            f"| {name} | {r['single_step_us'][name]:,.1f} | {r['single_ratio_to_acrobot'][name]:.2f}x | "
            + (
                "- | - |"
                if b is None
                else f"{b:.3f} | {r['batched_ratio_to_cartpole'][name]:.1f}x"
                + (f" [{lo_hi[name][0]:.1f}, {lo_hi[name][1]:.1f}]" if "processes" in r else "")
                + " |"
            )
            + (
                ""
                if fs is None
                else f" {fs['cold_s']:.1f} ({fs.get('cold_compiled_s', fs['cold_s']):.1f}) / {fs['warm_s']:.2f} |"
            )
        )
    if "first_step_s" in r:
        a = r["first_step_s"][PEER]
        lines.append(f"\nAcrobot-v1's first step in a fresh process: {a['cold_s']:.2f} s (no compiled code).")
    return "\n".join(lines) + "\n"


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
    ap.add_argument("--json-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.json_only:  # the baseline's subprocess
        print(json.dumps(measure(args.repeats, args.steps, args.num_envs, not args.no_cold)))
        return
    sections = []
    if args.processes > 1:
        here = pathlib.Path(__file__).resolve().parent.parent
        roots = ([args.baseline] if args.baseline is not None else []) + [here]
        runs: list[list[dict]] = [[] for _ in roots]
        for p in range(args.processes):  # alternating: drift hits both checkouts alike
            print(f"process {p + 1} of {args.processes}", file=sys.stderr)
            for j, root in enumerate(roots):
                runs[j].append(child(root, args, cold=not args.no_cold and p == 0))
        results = [combine(r) for r in runs]
        names = (["baseline.json"] if args.baseline is not None else []) + ["scenes.json"]
        for name, r in zip(names, results):
            (args.out / name).write_text(json.dumps(r, indent=2))
        if args.baseline is not None:
            sections.append(table(results[0], f"Before: {args.baseline}"))
        sections.append(table(results[-1], f"After: {here}" if args.baseline is not None else "This checkout"))
    elif args.baseline is not None:
        base = child(args.baseline, args, cold=not args.no_cold)
        (args.out / "baseline.json").write_text(json.dumps(base, indent=2))
        sections.append(table(base, f"Before: {args.baseline}"))
    if args.processes <= 1:
        now = measure(args.repeats, args.steps, args.num_envs, not args.no_cold)
        (args.out / "scenes.json").write_text(json.dumps(now, indent=2))
        sections.append(table(now, f"After: {now['python_path']}" if args.baseline else "This checkout"))
    if args.sizes:
        sizes = sweep(args.sizes, args.repeats, args.steps)
        (args.out / "sizes.json").write_text(json.dumps(sizes, indent=2))
        sections.append(sweep_table(sizes))
    text = "\n".join(sections)
    (args.out / "scenes.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
