"""Every scene's step against Gymnasium's peers (the logic of ``scripts/bench_scenes.py``, whose help says what is
measured), optionally on an earlier checkout beside this one.

Only the public API of the package is used, so the measurement of this module runs as well on another checkout:
:func:`child` executes this file (``python -c "runpy.run_path(...)"``, the other checkout first on ``PYTHONPATH``) in
a fresh process, which prints :func:`measure`'s JSON.
"""

from __future__ import annotations

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


def child(root: pathlib.Path, repeats: int, steps: int, num_envs: int, cold: bool) -> dict:
    """:func:`measure` in a fresh process on the checkout ``root`` (this module's file runs there, importing that
    checkout's package)."""
    code = (f"import runpy, sys; sys.argv = ['scene_bench', {repeats}, {steps}, {num_envs}, {int(cold)}]; "
            f"runpy.run_path({str(pathlib.Path(__file__).resolve())!r}, run_name='__main__')")  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(root.resolve())}
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=root)
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


def run(out: pathlib.Path, repeats: int = 5, steps: int = 400, num_envs: int = 1024, cold: bool = True,
        baseline: pathlib.Path | None = None, sizes: list[int] | None = None, processes: int = 1) -> str:  # fmt: skip
    """The whole benchmark (``scripts/bench_scenes.py``'s options): writes ``scenes.json`` (and ``baseline.json``,
    ``sizes.json``) and ``scenes.md`` to ``out`` and returns the tables' text."""
    out.mkdir(parents=True, exist_ok=True)
    sections = []
    here = pathlib.Path(__file__).resolve().parents[2]
    if processes > 1:
        roots = ([baseline] if baseline is not None else []) + [here]
        runs: list[list[dict]] = [[] for _ in roots]
        for p in range(processes):  # alternating: drift hits both checkouts alike
            print(f"process {p + 1} of {processes}", file=sys.stderr)
            for j, root in enumerate(roots):
                runs[j].append(child(root, repeats, steps, num_envs, cold=cold and p == 0))
        results = [combine(r) for r in runs]
        names = (["baseline.json"] if baseline is not None else []) + ["scenes.json"]
        for name, r in zip(names, results):
            (out / name).write_text(json.dumps(r, indent=2))
        if baseline is not None:
            sections.append(table(results[0], f"Before: {baseline}"))
        sections.append(table(results[-1], f"After: {here}" if baseline is not None else "This checkout"))
    else:
        if baseline is not None:
            base = child(baseline, repeats, steps, num_envs, cold=cold)
            (out / "baseline.json").write_text(json.dumps(base, indent=2))
            sections.append(table(base, f"Before: {baseline}"))
        now = measure(repeats, steps, num_envs, cold)
        (out / "scenes.json").write_text(json.dumps(now, indent=2))
        sections.append(table(now, f"After: {now['python_path']}" if baseline else "This checkout"))
    if sizes:
        swept = sweep(sizes, repeats, steps)
        (out / "sizes.json").write_text(json.dumps(swept, indent=2))
        sections.append(sweep_table(swept))
    text = "\n".join(sections)
    (out / "scenes.md").write_text(text)
    return text


if __name__ == "__main__":  # :func:`child`'s process: ``argv`` = repeats, steps, num_envs, cold
    _, _repeats, _steps, _num_envs, _cold = sys.argv
    print(json.dumps(measure(int(_repeats), int(_steps), int(_num_envs), bool(int(_cold)))))
