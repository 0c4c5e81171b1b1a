"""Soak and reliability runs: random-action episodes, determinism, long runs, parameters at the edges (the logic of ``scripts/soak.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import json
import pathlib
import numpy as np
from tqdm import tqdm
import mbs_envs
from .. import integrators
from ..envs import registry
from . import reliability as rl
from . import stiff_cases as sc
from .plotting import pyplot, save


def run(out: pathlib.Path, episodes: int, quick: bool = False, ids: list[str] | None = None, processes: bool = True,
        integrator_episodes: int | None = None, integrator_envs: int = 16, adversarial_rounds: int | None = None) -> dict:  # fmt: skip
    """All parts of the soak; ``integrator_episodes`` (default 8 with ``quick``, else 32) random episodes
    per integrator and id on ``integrator_envs`` members."""
    out.mkdir(parents=True, exist_ok=True)
    ids = ids or list(mbs_envs.ENV_IDS)
    soak = [rl.random_episodes(i, episodes) for i in tqdm(ids, desc="random episodes")]
    det = [rl.determinism(i, steps=20 if quick else 100) for i in tqdm(ids, desc="determinism")] if processes else []
    long = [sc.long_run_row(r, "rk4") for r in tqdm(sc.long_runs(quick), desc="long runs")]
    edges = rl.parameter_edges()
    models = {i: registry.load(registry.scene(i).model)() for i in ids}
    pairs = [(i, name) for name in integrators.available() for i in ids if integrators.applies(name, models[i])]
    n_int = integrator_episodes or (8 if quick else 32)
    per_integrator = [
        rl.integrator_soak(i, name, episodes=n_int, num_envs=integrator_envs)
        for i, name in tqdm(pairs, desc="integrators")
    ]
    adversarial = [
        rl.adversarial_soak(i, rounds=adversarial_rounds or (100 if quick else 2000))
        for i in tqdm(ids, desc="adversarial sequences")
    ]
    threads = rl.threads_cold(ids, per_id=4, runs=1 if quick else 3) if processes else None
    result = {"episodes_per_id": episodes, "soak": soak, "determinism": det, "long_runs": long, "edges": edges,
              "integrators": per_integrator, "adversarial": adversarial, "threads_cold": threads}  # fmt: skip
    (out / "soak.json").write_text(json.dumps(result, indent=2, default=float))
    text = report(result)
    (out / "soak.md").write_text(text)
    plot(result, out / "soak.png")
    print(text)
    print(f"written to {out}/soak.json, soak.md, soak.png")
    return result


def report(r: dict) -> str:
    L = ["# Soak and reliability", "", "## Random-action episodes (batched env, 10 % of actions out of range)", "",
         "| id | episodes | steps | non-finite observations | non-finite rewards | divergences reported | terminations | max abs observation |",
         "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for s in r["soak"]:
        L.append(f"| {s['env_id']} | {s['episodes']} | {s['steps']} | {s['nonfinite_observations']} | {s['nonfinite_rewards']} | "
                 f"{s['divergences_reported']} | {s['terminations']} | {s['max_abs_observation']:.3g} |")  # fmt: skip
    if r["determinism"]:
        kinds = list(r["determinism"][0]["max_difference"])
        L += ["", "## Determinism (largest observation difference to SyncVectorEnv; same seeds and actions)", "",
              "| id | steps | " + " | ".join(kinds) + " |", "|---|---|" + "---|" * len(kinds)]  # fmt: skip
        for d in r["determinism"]:
            L.append(
                f"| {d['env_id']} | {d['steps_compared']} | "
                + " | ".join(f"{d['max_difference'][k]:.1e}" for k in kinds)
                + " |"
            )
    L += ["", "## Long runs (free motion, RK4)", "", "| case | steps | dt [s] | max energy drift [J] | relative | constraint error | diverged |",
          "|---|---|---|---|---|---|---|"]  # fmt: skip
    for x in r["long_runs"]:
        c = "-" if not np.isfinite(x["constraint_error"]) else f"{x['constraint_error']:.1e}"
        L.append(
            f"| {x['scene']} | {x['steps']} | {x['dt']:g} | {x['energy_drift']:.2e} | {x['energy_drift_relative']:.2e} | {c} | {x['diverged']} |"
        )
    first = r["integrators"][0] if r["integrators"] else {}
    L += ["", f"## Every integrator (random-action episodes of {first.get('episode_steps', 100)} steps on {first.get('num_envs', 16)} batched "
          "members; then 4 runaway episodes at a 1e200 N m torque limit)", "",
          "| integrator | id | episodes | steps | slowest batched step [ms] | divergences reported | non-finite outputs | exceptions | hangs | runaway steps flagged | worst diverging step [ms] |",
          "|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for x in r.get("integrators", []):
        L.append(f"| {x['integrator']} | {x['env_id'].split('/')[-1]} | {x.get('episodes', 0)} | {x.get('steps', 0)} | {1e3 * x.get('slowest_step_s', float('nan')):.1f} | {x.get('divergences_reported', 0)} | "
                 f"{x['nonfinite']} | {x['exceptions']} | {x['hangs']} | {x.get('runaway_flagged', 0)} / {x.get('runaway_episodes', 0)} | "
                 f"{1e3 * x.get('runaway_worst_step_s', float('nan')):.1f} |")  # fmt: skip
        for e in x["errors"]:
            L.append(f"|  | error: {e} | | | | | | | | | |")
    if r.get("adversarial"):
        L += ["", "## Adversarial sequences (batched env beside a twin)", "",
              "| id | rounds | copies | refused calls | refusals accepted | state changed by a refusal | disagreements with the twin | other exceptions |",
              "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for x in r["adversarial"]:
            L.append(f"| {x['env_id'].split('/')[-1]} | {x['rounds']} | {x['counts'].get('copy', 0)} | {x['refused']} | {x['accepted_bad']} | "
                     f"{x['changed_by_refusal']} | {x['disagreements']} | {x['other_exceptions']} |")  # fmt: skip
            for e in x["errors"]:
                L.append(f"|  | error: {e} | | | | | | |")
    if r.get("threads_cold"):
        t = r["threads_cold"]
        L += ["", "## Threads on a cold cache", "",
              f"{t['runs']} fresh interpreter(s) with empty kernel and derivation caches, {t['per_id']} threads per id at "
              f"once ({len(t['ids'])} ids): {t['jobs']} jobs, **{t['failed']}** failed."]  # fmt: skip
        L += [f"- error: {e}" for e in t["errors"]]
    L += [
        "",
        "## Parameters at the edges",
        "",
        "| model | parameter | value | outcome | detail |",
        "|---|---|---|---|---|",
    ]
    for e in r["edges"]:
        detail = (
            e.get("message") or f"finite: {e['all_finite']}, relative energy drift {e['relative_energy_drift']:.1e}"
        )
        L.append(f"| {e['model']} | {e['parameter']} | {e['value']:g} | {e['outcome']} | {detail[:110]} |")
    return "\n".join(L) + "\n"


def plot(r: dict, path: pathlib.Path) -> None:
    plt = pyplot()
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(12, 4))
    names = [s["env_id"].split("/")[-1] for s in r["soak"]]
    x = np.arange(len(names))
    for k, (key, label) in enumerate([("episodes", "episodes"), ("terminations", "terminations"),
                                      ("divergences_reported", "divergences reported"), ("nonfinite_observations", "non-finite observations")]):  # fmt: skip
        a0.bar(x + 0.2 * k, [max(s[key], 0.5) for s in r["soak"]], 0.2, label=label)
    a0.set_yscale("log")
    a0.set_xticks(x + 0.3, names, fontsize=8)
    a0.set_title("random-action episodes (bars at 0.5 mean zero)")
    a0.legend(fontsize=7)
    outcomes = ["ValueError", "ValueError at assembly", "stable", "diverged (reported)"]
    counts = [sum(e["outcome"] == o for e in r["edges"]) for o in outcomes]
    a1.bar(range(len(outcomes)), counts, tick_label=[o.replace(" ", "\n", 1) for o in outcomes])
    a1.set_title(f"parameters at the edges ({len(r['edges'])} cases)")
    save(fig, path)
