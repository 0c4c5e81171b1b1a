#!/usr/bin/env python
"""Work-precision: error against run time (and right-hand-side evaluations) for every scene and integrator.

Protocol and definitions: :mod:`mbs_envs.studies.work_precision`. In short: per
scene a free (frictionless, energy-conserving) and a forced problem (the scene as
its environment runs it: default friction, a smooth torque held per control
step); fixed-step methods swept over ``dt``, adaptive ones over ``rtol`` (one
whole-trajectory solve of free problems; restarted per control step on forced
ones, as environments do, and labelled so); each run warmed up, then the median
and minimum of ``--repeats`` timed runs of the stepping loop, on the numpy path
and on the compiled path where the environment takes it; errors against DOP853
at 1e-13, whose difference from Radau IIA at 1e-13 is the drawn floor.

Writes to ``--out``: ``work_precision.csv`` (one row per problem x integrator x
setting x path), ``work_precision.json`` (references, floors, protocol, run
time), ``work_precision.md`` (the cheapest run per problem and target) and
``work_precision_<problem>.png`` (trajectory error against median time and
against evaluations, with the floor; energy drift or constraint residual).

    python scripts/work_precision.py --out results/numerics            # about 25 min here
    python scripts/work_precision.py --out results/numerics --quick    # about 2 min
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys
import time

import numpy as np
from tqdm import tqdm

from mbs_envs.studies import work_precision as wp
from mbs_envs.studies.plotting import pyplot, save

TARGETS = (1e-3, 1e-6, 1e-9)


def run(
    out: pathlib.Path,
    quick: bool = False,
    problems: list[str] | None = None,
    methods: list[str] | None = None,
    repeats: int | None = None,
    n_fixed: int | None = None,
    n_adaptive: int | None = None,
) -> list[dict]:
    t_start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    horizon = 0.4 if quick else 1.0
    repeats = repeats or (3 if quick else 5)
    n_fixed = n_fixed or (4 if quick else 6)
    n_adaptive = n_adaptive or (3 if quick else 5)
    every = wp.free_problems(horizon) + wp.forced_problems(horizon)
    chosen = [p for p in every if problems is None or p.name in problems]
    if not chosen:
        raise ValueError(f"no problem matches {problems}; known: {[p.name for p in every]}")
    methods = list(methods or wp.FIXED + wp.ADAPTIVE)
    unknown = sorted(set(methods) - set(wp.FIXED + wp.ADAPTIVE))
    if unknown:
        raise ValueError(f"unknown methods {unknown}; known: {list(wp.FIXED + wp.ADAPTIVE)}")
    jobs = [(p, m, s) for p in chosen for m in methods if wp.applies(p, m) for s in wp.settings(p, m, n_fixed, n_adaptive)]
    rows, refs = [], {}
    with tqdm(total=len(jobs) + len(chosen), desc="work-precision", unit="run") as bar:
        for p in chosen:
            bar.set_postfix_str(f"{p.name} reference", refresh=True)
            refs[p.name] = wp.reference(p)
            bar.update()
            for q, m, s in jobs:
                if q is not p:
                    continue
                bar.set_postfix_str(f"{p.name} {m} {s:.3g}", refresh=False)
                rows.extend(wp.measure(p, refs[p.name], m, s, repeats))
                bar.update()
    write_csv(rows, out / "work_precision.csv")
    for p in chosen:
        plot_problem([r for r in rows if r["problem"] == p.name], p, refs[p.name], out / f"work_precision_{p.name}.png")
    summary = summarize(rows, chosen, refs)
    (out / "work_precision.md").write_text(summary)
    spreads = [r["time_max_s"] / r["time_min_s"] for r in rows if r["finished"] and r["time_min_s"] > 0]
    meta = {
        "quick": quick, "horizon_s": horizon, "repeats": repeats, "methods": methods,
        "reference": {"methods": ["dop853", "radau"], "rtol": wp.REFERENCE_TOL, "atol": wp.REFERENCE_TOL},
        "problems": {p.name: {"model": repr(p.model), "interval_s": p.interval, "steps": p.steps, "forced": p.u is not None,
                              "stabilization": p.stabilization, "reference_floor": refs[p.name].floor,
                              "reference_seconds": refs[p.name].seconds} for p in chosen},
        "timing_spread_max_over_min": {"median": float(np.median(spreads)), "p90": float(np.percentile(spreads, 90))} if spreads else None,
        "run_time_s": time.perf_counter() - t_start,
    }  # fmt: skip
    (out / "work_precision.json").write_text(json.dumps(meta, indent=2))
    print(summary)
    print(f"run time {meta['run_time_s']:.0f} s; written to {out}/work_precision.csv, .md, .json and one PNG per problem")
    return rows


def write_csv(rows: list[dict], path: pathlib.Path) -> None:
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)


def plot_problem(rows: list[dict], p: wp.Problem, ref: wp.Reference, path: pathlib.Path) -> None:
    plt = pyplot()
    third = "energy_drift" if p.conservative else ("constraint_residual" if p.model.nc else "final_error")
    panels = [("time_median_s", "trajectory_error"), ("rhs_evaluations", "trajectory_error"), ("time_median_s", third)]
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6))
    colors = plt.get_cmap("tab20").colors
    lines = list(dict.fromkeys((r["integrator"], r["path"]) for r in rows))
    for ax, (xk, yk) in zip(axes, panels):
        for k, (method, path_) in enumerate(lines):
            pts = sorted((r[xk], r[yk]) for r in rows if r["integrator"] == method and r["path"] == path_
                         and r["finished"] and r[yk] > 0 and np.isfinite(r[yk]))  # fmt: skip
            if not pts:
                continue
            x, y = zip(*pts)
            style = "--" if method in wp.ADAPTIVE else (":" if path_ == "compiled" else "-")
            label = f"{method} ({path_})" if path_ == "compiled" else method
            ax.loglog(x, y, style, marker="o", ms=3, label=label, color=colors[(2 * k) % 20])
        if yk == "trajectory_error":
            ax.axhline(ref.floor, color="k", lw=1, alpha=0.6)
            ax.text(ax.get_xlim()[0], ref.floor, " reference floor", va="bottom", fontsize=7)
        ax.set_xlabel({"time_median_s": "median run time [s]", "rhs_evaluations": "right-hand-side evaluations"}[xk])
        ax.set_ylabel(yk.replace("_", " "))
        ax.tick_params(axis="x", which="minor", labelbottom=False)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=6, ncol=2)
    what = "free motion" if p.u is None else f"torque held per {p.interval:g} s control step, default friction"
    fig.suptitle(f"{p.name}: {p.t_final:g} s, {what} (dotted: compiled path; dashed: adaptive)")
    save(fig, path)


def summarize(rows: list[dict], chosen: list[wp.Problem], refs: dict) -> str:
    lines = ["# Work-precision summary", "",
             "Cheapest run (median time) whose trajectory error reaches each target; `-` if none did. "
             "Floor: DOP853 against Radau at 1e-13.", ""]  # fmt: skip
    lines += ["| problem | floor | " + " | ".join(f"error <= {t:g}" for t in TARGETS) + " | unfinished runs |",
              "|" + "---|" * (len(TARGETS) + 3)]  # fmt: skip
    for p in chosen:
        sub = [r for r in rows if r["problem"] == p.name]
        cells = []
        for target in TARGETS:
            best = wp.cheapest(sub, target)
            cells.append("-" if best is None else
                         f"{best['integrator']} ({best['path']}) {best['setting_name']}={best['setting']:.3g}: {1e3 * best['time_median_s']:.2f} ms")  # fmt: skip
        failed = sorted({f"{r['integrator']}@{r['setting']:.2g}" for r in sub if not r["finished"]})
        lines.append(f"| {p.name} | {refs[p.name].floor:.1e} | " + " | ".join(cells) + f" | {', '.join(failed) or 'none'} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--quick", action="store_true", help="0.4 s horizons, fewer settings, 3 repeats")
    p.add_argument("--problems", nargs="+", help="subset, e.g. planar2r-free fourbar-forced (default all)")
    p.add_argument("--methods", nargs="+", help="subset of integrators (default all)")
    p.add_argument("--repeats", type=int, help="timed runs per setting after the warm-up (default 5, quick 3)")
    p.add_argument("--n-fixed", type=int, help="number of dt values (halving from the interval)")
    p.add_argument("--n-adaptive", type=int, help="number of rtol values")
    a = p.parse_args(argv)
    run(a.out, a.quick, a.problems, a.methods, a.repeats, a.n_fixed, a.n_adaptive)
    return 0


if __name__ == "__main__":
    sys.exit(main())
