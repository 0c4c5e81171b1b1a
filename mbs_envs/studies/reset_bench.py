"""Batched steps with episodes ending, timed against Gymnasium's CartPole vector env (the logic of ``scripts/bench_resets.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import sys
import time
import warnings
import numpy as np


MODES = ("zero", "random")


def scenes(only: list[str] | None) -> dict[str, tuple[str, dict]]:
    """Label -> (id, kwargs) of the scenes timed (each registered scene's ``bench_kwargs``)."""
    from mbs_envs.envs import registry

    out = {}
    for s in registry.SCENES:
        for kw in getattr(s, "bench_kwargs", ()) or (dict(s.kwargs),):
            if kw.get("n_links") == 100:
                continue
            label = s.id.split("/")[-1] + (" (" + ", ".join(f"{k}={v}" for k, v in kw.items()) + ")" if kw else "")
            if only is None or any(label.startswith(o) for o in only):
                out[label] = (s.id, dict(kw))
    return out


def actions(space, mode: str, steps: int, seed: int) -> list:
    """``steps`` batched actions: zeros (CartPole: push left), or uniform draws from ``space``."""
    space.seed(seed)
    if mode == "zero":
        return [np.zeros(space.shape, space.dtype)] * steps
    return [space.sample() for _ in range(steps)]


def run(env, acts: list) -> tuple[float, int]:
    """Seconds per step over ``acts`` and the episodes that ended."""
    ended = 0
    t0 = time.perf_counter()
    for a in acts:
        _, _, term, trunc, _ = env.step(a)
        ended += int(np.count_nonzero(term | trunc))
    return (time.perf_counter() - t0) / len(acts), ended


def measure(num_envs: int, steps: int, repeats: int, only: list[str] | None, seed: int = 0) -> dict:
    import gymnasium as gym
    from tqdm import tqdm

    import mbs_envs  # noqa: F401  (registers the ids)

    # the older versions of a scene (Acrobot-v0, ...) are timed on purpose: not Gymnasium's "out of date" warning
    warnings.filterwarnings("ignore", message=".*is out of date.*", category=DeprecationWarning)
    configs = {}  # (label, mode, variant) -> (env, actions)
    for mode in MODES:
        cp = gym.make_vec("CartPole-v1", num_envs=num_envs, vectorization_mode="vector_entry_point")
        cp.reset(seed=seed)
        configs[("CartPole-v1", mode, "gymnasium")] = (cp, actions(cp.action_space, mode, steps, seed))
        for label, (env_id, kw) in scenes(only).items():
            for ahead in (True, False):
                v = gym.make_vec(
                    env_id,
                    num_envs=num_envs,
                    vectorization_mode="vector_entry_point",
                    full_info=False,
                    draw_ahead=ahead,
                    **kw,
                )
                v.reset(seed=seed)
                configs[(label, mode, "drawn ahead" if ahead else "drawn at the reset")] = (
                    v,
                    actions(v.action_space, mode, steps, seed),
                )
    times = {k: [] for k in configs}
    ends = {k: 0 for k in configs}
    for env, acts in tqdm(configs.values(), desc="warm-up", file=sys.stderr):
        run(env, acts)  # compiles, fills the first batch of starts ahead, settles the episode lengths
    for _ in tqdm(range(repeats), desc="repeats", file=sys.stderr):
        for key, (env, acts) in configs.items():  # interleaved: drift hits every configuration alike
            t, e = run(env, acts)
            times[key].append(t)
            ends[key] += e
    rows = []
    for (label, mode, variant), ts in times.items():
        per = float(np.median(ts)) / num_envs * 1e6
        peer = float(np.median(times[("CartPole-v1", mode, "gymnasium")])) / num_envs * 1e6
        env = configs[(label, mode, variant)][0].unwrapped
        served = getattr(getattr(env, "_ahead", None), "taken", None) if variant == "drawn ahead" else None
        rows.append({"scene": label, "actions": mode, "starts": variant, "per_env_step_us": per, "ratio_to_cartpole": per / peer,
                     "episodes_ended_per_step": ends[(label, mode, variant)] / (repeats * steps), "resets_served_ahead": served})  # fmt: skip
    return {"num_envs": num_envs, "steps": steps, "repeats": repeats, "rows": rows}


def report(result: dict) -> str:
    n = result["num_envs"]
    lines = [
        f"# Batched steps with episodes ending ({n} members, median of {result['repeats']} interleaved runs of "
        f"{result['steps']} steps after a warm-up run)",
        "",
        "Per env-step [us] and the ratio to Gymnasium's `CartPoleVectorEnv` under the same kind of action, timed in the "
        "same process; episodes ended per step (all members) in brackets.",
        "",
        "| scene | actions | starts drawn ahead | at the reset |",
        "|---|---|---|---|",
    ]
    by = {(r["scene"], r["actions"], r["starts"]): r for r in result["rows"]}
    for (scene, mode, variant), r in by.items():
        if variant == "gymnasium":
            lines.append(
                f"| CartPole-v1 (gymnasium) | {mode} | {r['per_env_step_us']:.3f} us ({r['episodes_ended_per_step']:.1f}) | |"
            )
    for (scene, mode, variant), r in by.items():
        if variant != "drawn ahead":
            continue
        b = by[(scene, mode, "drawn at the reset")]
        cell = lambda x: (
            f"{x['per_env_step_us']:.3f} us, **{x['ratio_to_cartpole']:.1f}x** ({x['episodes_ended_per_step']:.1f})"
        )  # noqa: E731
        lines.append(f"| {scene} | {mode} | {cell(r)} | {cell(b)} |")
    return "\n".join(lines) + "\n"
