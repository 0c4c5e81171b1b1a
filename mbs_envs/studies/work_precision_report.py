"""The work-precision report: every scene's free and forced problems under every integrator, error against run time and evaluations, the CSV, the figures and the summary (``scripts/work_precision.py`` is its command line; :mod:`mbs_envs.studies.work_precision` holds the measurements)."""

from __future__ import annotations

import csv
import json
import pathlib
import time

import numpy as np
from tqdm import tqdm

from . import work_precision as wp
from .plotting import pyplot, save


TARGETS = (1e-3, 1e-6, 1e-9)


def run(
    out: pathlib.Path,
    quick: bool = False,
    problems: list[str] | None = None,
    methods: list[str] | None = None,
    repeats: int | None = None,
    n_fixed: int | None = None,
    n_adaptive: int | None = None,
    add: bool = False,
) -> list[dict]:
    """Measure the chosen problems and write the results to ``out``; with ``add``, into the results
    already there (rows of the same problems replaced, the others kept)."""
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
    jobs = [
        (p, m, s) for p in chosen for m in methods if wp.applies(p, m) for s in wp.settings(p, m, n_fixed, n_adaptive)
    ]
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
    for p in chosen:
        plot_problem([r for r in rows if r["problem"] == p.name], p, refs[p.name], out / f"work_precision_{p.name}.png")
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
    if add and (out / "work_precision.json").exists():
        old_rows, old_meta = load(out)
        if (old_meta["quick"], old_meta["horizon_s"], old_meta["repeats"]) != (quick, horizon, repeats):
            raise ValueError(f"--add: the results in {out} were made with quick={old_meta['quick']}, repeats={old_meta['repeats']}; "
                             "add runs of the same configuration")  # fmt: skip
        names = {p.name for p in chosen}
        rows = [r for r in old_rows if r["problem"] not in names] + rows
        added = {k: meta[k] for k in ("problems", "run_time_s", "timing_spread_max_over_min")}
        meta = {**old_meta, "problems": {**old_meta["problems"], **meta["problems"]},
                "added_runs": old_meta.get("added_runs", []) + [added]}  # fmt: skip
    write_csv(rows, out / "work_precision.csv")
    summary = summarize(rows, {name: info["reference_floor"] for name, info in meta["problems"].items()})
    (out / "work_precision.md").write_text(summary)
    (out / "work_precision.json").write_text(json.dumps(meta, indent=2))
    print(summary)
    print(
        f"run time {time.perf_counter() - t_start:.0f} s; written to {out}/work_precision.csv, .md, .json and one PNG per problem"
    )
    return rows


def write_csv(rows: list[dict], path: pathlib.Path) -> None:
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)


def plot_problem(
    rows: list[dict], p: wp.Problem | None, ref: wp.Reference | float, path: pathlib.Path, title: str | None = None
) -> None:
    """Three panels: trajectory error against median time and against evaluations (the floor drawn),
    and energy drift (free), constraint residual (constrained) or final error against time.
    One colour per integrator; solid numpy path, dotted compiled path, dashed adaptive."""
    plt = pyplot()
    floor = ref if isinstance(ref, float) else ref.floor
    kinds = {r["kind_of_problem"] for r in rows}
    has_residual = any(np.isfinite(r["constraint_residual"]) for r in rows)
    third = (
        "energy_drift"
        if kinds == {"free"} and not has_residual
        else ("constraint_residual" if has_residual else "final_error")
    )
    panels = [("time_median_s", "trajectory_error"), ("rhs_evaluations", "trajectory_error"), ("time_median_s", third)]
    fig, axes = plt.subplots(1, 3, figsize=(17, 4.8))
    colors = plt.get_cmap("tab20").colors
    order = list(wp.FIXED + wp.ADAPTIVE)
    lines = list(dict.fromkeys((r["integrator"], r["path"]) for r in rows))
    for ax, (xk, yk) in zip(axes, panels):
        for method, path_ in lines:
            pts = sorted((r[xk], r[yk]) for r in rows if r["integrator"] == method and r["path"] == path_
                         and r["finished"] and r[yk] > 0 and np.isfinite(r[yk]))  # fmt: skip
            if not pts:
                continue
            x, y = zip(*pts)
            style = "--" if method in wp.ADAPTIVE else (":" if path_ == "compiled" else "-")
            label = f"{method} (compiled)" if path_ == "compiled" else method
            ax.loglog(x, y, style, marker="o", ms=3, label=label, color=colors[order.index(method) % 20])
        if yk == "trajectory_error":
            ax.axhline(floor, color="k", lw=1.2, alpha=0.7, label="reference floor")
        ax.set_xlabel({"time_median_s": "median run time [s]", "rhs_evaluations": "right-hand-side evaluations"}[xk])
        ax.set_ylabel(yk.replace("_", " "))
        ax.tick_params(axis="x", which="minor", labelbottom=False)
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=7)
    if title is None:
        what = "free motion" if p.u is None else f"torque held per {p.interval:g} s control step, default friction"
        title = f"{p.name}: {p.t_final:g} s, {what}"
    fig.suptitle(f"{title} (dotted: compiled path; dashed: adaptive)")
    save(fig, path, rect=(0, 0, 0.86, 1))


def load(out: pathlib.Path) -> tuple[list[dict], dict]:
    """The rows of ``work_precision.csv`` (numbers parsed) and ``work_precision.json`` in ``out``."""
    meta = json.loads((out / "work_precision.json").read_text())
    with open(out / "work_precision.csv") as f:
        rows = list(csv.DictReader(f))
    numeric = ("setting", "rhs_evaluations", "final_error", "trajectory_error", "energy_drift", "constraint_residual",
               "time_median_s", "time_min_s", "time_max_s", "reference_floor")  # fmt: skip
    for r in rows:
        for k in numeric:
            r[k] = float(r[k]) if r.get(k) not in (None, "") else float("nan")
        if float(r["rhs_evaluations"]).is_integer():  # written as an integer count
            r["rhs_evaluations"] = int(r["rhs_evaluations"])
        r["finished"] = r["finished"] == "True"
    return rows, meta


def replot(out: pathlib.Path) -> None:
    """The plots again from ``work_precision.csv`` and ``.json`` in ``out`` (no runs)."""
    rows, meta = load(out)
    for name, info in meta["problems"].items():
        sub = [r for r in rows if r["problem"] == name]
        what = (
            f"torque held per {info['interval_s']:g} s control step, default friction"
            if info["forced"]
            else "free motion"
        )
        plot_problem(
            sub,
            None,
            float(info["reference_floor"]),
            out / f"work_precision_{name}.png",
            f"{name}: {info['interval_s'] * info['steps']:g} s, {what}",
        )


def summarize(rows: list[dict], floors: dict[str, float]) -> str:
    """The markdown table of the cheapest run per error target, one row per problem of ``floors``
    (problem name -> the reference's floor)."""
    lines = ["# Work-precision summary", "",
             "Cheapest run (median time) whose trajectory error reaches each target; `-` if none did. "
             "Floor: DOP853 against Radau at 1e-13.", ""]  # fmt: skip
    lines += ["| problem | floor | " + " | ".join(f"error <= {t:g}" for t in TARGETS) + " | unfinished runs |",
              "|" + "---|" * (len(TARGETS) + 3)]  # fmt: skip
    for name, floor in floors.items():
        sub = [r for r in rows if r["problem"] == name]
        cells = []
        for target in TARGETS:
            best = wp.cheapest(sub, target)
            cells.append("-" if best is None else
                         f"{best['integrator']} ({best['path']}) {best['setting_name']}={best['setting']:.3g}: {1e3 * best['time_median_s']:.2f} ms")  # fmt: skip
        failed = sorted({f"{r['integrator']}@{r['setting']:.2g}" for r in sub if not r["finished"]})
        lines.append(f"| {name} | {float(floor):.1e} | " + " | ".join(cells) + f" | {', '.join(failed) or 'none'} |")
    return "\n".join(lines) + "\n"
