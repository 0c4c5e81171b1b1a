"""Tuning every model-based controller's gains with the procedure of :mod:`mbs_envs.studies.tuning` and writing ``controllers/tuned.json`` (the logic of ``scripts/tune.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import argparse
import csv
import json
import multiprocessing
import pathlib
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
import numpy as np
from tqdm import tqdm
import mbs_envs  # noqa: F401
from ..controllers import tuned
from . import tuning
from .comparison import SCENES
from .plotting import pyplot, save
from .provenance import command_line


ROOT = pathlib.Path(__file__).resolve().parents[2]


def first_stage_of(stored: dict, env_id: str, controller: str) -> tuple[str, str]:
    """``(env id, controller)`` of the stored first-stage pick ``controller``'s second stage on ``env_id`` starts
    from: its own, or that of the controller whose laws it shares (:data:`controllers.tuned.SAME_LAWS`), on
    ``env_id`` or on the version whose plant it shares (:data:`controllers.tuned.SAME_PLANT`)."""
    for env in (env_id, tuned.SAME_PLANT.get(env_id)):
        for name in (controller, tuned.SAME_LAWS.get(controller)):
            if name in stored["gains"].get(env, {}):
                return env, name
    raise SystemExit(f"tune.py: --refine-only: no stored first stage for {controller!r} on {env_id}")


def tune_one(task: dict) -> dict:
    """Tune one controller of one scene; also score its pre-tuning default."""
    import torch

    torch.set_num_threads(1)
    tic = time.perf_counter()
    best, rows = tuning.tune(task["scene"], task["controller"], n_seeds=task["seeds"], start=task.get("start"))
    old = tuning.score(
        task["scene"], task["controller"], tuned.FALLBACK[task["controller"]], tuning.tuning_seeds(task["seeds"])
    )
    return {**task, "best": best, "rows": rows, "wall_s": time.perf_counter() - tic,
            "pre_tuning": {"entry": tuned.FALLBACK[task["controller"]], "failure_rate": old.failure_rate, "error": old.error}}  # fmt: skip


def run(args: argparse.Namespace) -> dict:
    scenes = args.scene or list(SCENES)
    tasks = [{"scene": s, "controller": c, "seeds": args.seeds} for s in scenes for c in SCENES[s][2]
             if c in tuning.GRIDS and (not args.controller or c in args.controller)]  # fmt: skip
    if not tasks:
        raise SystemExit(f"tune.py: no tunable controller {args.controller} in {scenes}")
    stored = json.loads(tuned.PATH.read_text()) if tuned.PATH.exists() else {"gains": {}, "scores": {}}
    if args.refine_only:  # the stored first stage's pick is where the second stage starts (for a controller without
        # an entry of its own, the pick of the controller whose laws it shares: controllers.tuned.SAME_LAWS)
        tasks = [dict(t, start=stored["gains"][env][name]) for t in tasks if t["controller"] in tuning.REFINE
                 for env, name in [first_stage_of(stored, SCENES[t["scene"]][0], t["controller"])]]  # fmt: skip
        if not tasks:
            raise SystemExit("tune.py: --refine-only: none of these controllers has a second stage")
    args.out.mkdir(parents=True, exist_ok=True)
    results = []
    with ProcessPoolExecutor(args.workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(tune_one, t) for t in tasks]
        for f in tqdm(as_completed(futures), total=len(futures), desc="controllers tuned"):
            results.append(f.result())
    results.sort(key=lambda r: (scenes.index(r["scene"]), r["controller"]))
    rows = [dict(r, entry=json.dumps(r["entry"])) for res in results for r in res["rows"]]
    with open(args.out / "tuning.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=sorted({k for r in rows for k in r}))
        w.writeheader()
        w.writerows(rows)
    record = {
        "procedure": tuning.__doc__,
        "tuning_seeds": [tuning.tuning_seeds(args.seeds)[0], tuning.tuning_seeds(args.seeds)[-1]],
        "conditions": [c.name for c in tuning.TUNING_CONDITIONS],
        "gains": {},
        "scores": {},
    }
    command = command_line("tune.py")
    for r in results:
        env_id = SCENES[r["scene"]][0]
        record["gains"].setdefault(env_id, {})[r["controller"]] = r["best"]
        chosen = next(x for x in r["rows"] if x["entry"] == r["best"])
        grid = tuning.GRIDS[r["controller"]]() + (
            tuning.REFINE[r["controller"]](r["best"]) if r["controller"] in tuning.REFINE else []
        )
        edge = tuning.at_grid_edge(r["best"], grid)
        score = {"tuned": {"failure_rate": chosen["failure_rate"], "error": chosen["error"]},
                 "pre_tuning": r["pre_tuning"], "at_grid_edge": edge, "wall_s": r["wall_s"], "command": command,
                 "tuning_seeds": record["tuning_seeds"]}  # fmt: skip
        if r.get("start") is not None:  # the first stage is the stored one
            env, source = first_stage_of(stored, env_id, r["controller"])
            first = stored["scores"][env][source]
            score.update(first_stage={"entry": r["start"], "env": env, "controller": source, "command": first["command"],
                                      "wall_s": first["wall_s"], "tuned": first["tuned"]}, wall_s=first["wall_s"] + r["wall_s"])  # fmt: skip
        record["scores"].setdefault(env_id, {})[r["controller"]] = score
        print(f"{r['scene']:12s} {r['controller']:16s} tuned {r['best']}: failures {chosen['failure_rate']:.0%}, "
              f"error {chosen['error']:.3g} (pre-tuning: {r['pre_tuning']['failure_rate']:.0%}, {r['pre_tuning']['error']:.3g})"
              + (f"; at the grid's edge in {', '.join(edge)}" if edge else ""))  # fmt: skip
    (args.out / "tuning.json").write_text(json.dumps(record, indent=2))
    plot(results, args.out / "tuning.png")
    if args.write:  # scenes and controllers not tuned in this run keep their stored entries
        if tuned.PATH.exists():
            for key in ("gains", "scores"):
                old = stored.get(key, {})
                record[key] = {env: {**old.get(env, {}), **record[key].get(env, {})} for env in {**old, **record[key]}}
            if stored.get(
                "tuning_seeds"
            ):  # the range covering every stored entry's seeds (each new entry states its own)
                record["tuning_seeds"] = [
                    min(stored["tuning_seeds"][0], record["tuning_seeds"][0]),
                    max(stored["tuning_seeds"][1], record["tuning_seeds"][1]),
                ]
        tuned.PATH.write_text(json.dumps(record, indent=2) + "\n")
        tuned.clear_cache()
        print(f"written {tuned.PATH}")
    return record


def plot(results: list[dict], path: pathlib.Path) -> None:
    """Error against bandwidth for the joint controllers (one panel per scene); failures marked."""
    plt = pyplot()
    joint = [r for r in results if "omega" in r["best"]]
    scenes = list(dict.fromkeys(r["scene"] for r in joint))
    if not scenes:
        return
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.5 * len(scenes), 4), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        for r in (x for x in joint if x["scene"] == scene):
            for zeta, style in ((0.7, "--"), (1.0, "-")):
                pts = [
                    (x["entry"]["omega"], x["error"], x["failure_rate"])
                    for x in r["rows"]
                    if x["entry"]["zeta"] == zeta
                ]
                w, e, fr = (np.array(v, float) for v in zip(*pts))
                line = ax.plot(w, e, style + "o", ms=3, label=f"{r['controller']}, zeta {zeta}")[0]
                bad = fr > 0
                ax.plot(w[bad], np.where(np.isfinite(e[bad]), e[bad], np.nanmax(e)), "x", color=line.get_color(), ms=8)
            ax.plot(r["best"]["omega"], next(x["error"] for x in r["rows"] if x["entry"] == r["best"]), "k*", ms=10)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("closed-loop bandwidth omega [rad/s]")
        ax.set_ylabel("mean settled RMS error, nominal and +-20 % [rad]")
        ax.set_title(f"{scene} (x: failures, *: chosen)", fontsize=9)
        ax.legend(fontsize=6)
    save(fig, path)
