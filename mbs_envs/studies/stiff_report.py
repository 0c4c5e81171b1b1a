"""The stiff and extreme cases' report (the logic of ``scripts/stiff_cases.py``, whose help says what is run):
the scans over the cases of :mod:`mbs_envs.studies.stiff_cases`, their tables, CSV files and plot."""

from __future__ import annotations

import csv
import json
import pathlib

import numpy as np
from tqdm import tqdm

from ..dynamics import integrators
from . import numerics
from . import stiff_cases as sc
from .plotting import pyplot, save

RK4_BETA = 2.785  # RK4's real stability interval [-2.785, 0]
QUICK_CASES = ("viscous b=400", "PD kp=1e5, kd=2e3", "mass ratio 1e-3", "four-bar change point (parallelogram)")


def run(
    out: pathlib.Path, quick: bool = False, cases: list[str] | None = None, methods: list[str] | None = None
) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    if quick and cases is None:
        cases = list(QUICK_CASES)
    chosen = [c for c in sc.stiff_cases(quick) if cases is None or c.scene in cases]
    picked = methods  # None: every method; else also restricts the singular and long-run tables
    methods = list(methods or numerics.FIXED + ("joint_implicit_euler",))
    adaptive = [] if quick else ["dop853", "radau", "bdf"]
    dts = numerics.fixed_steps(0.05, 7 if quick else 11)
    runs, summary, adaptive_rows, meta = [], [], [], {}
    bar = tqdm(total=len(chosen) * (len(methods) + len(adaptive)), desc="stiff cases", unit="scan")
    for case in chosen:
        ref = numerics.reference(case)
        rho = sc.spectral_radius(case)
        meta[case.scene] = {"model": repr(case.model), "t_final": case.t_final, "spectral_radius": rho,
                            "rk4_limit_predicted": RK4_BETA / rho, "reference": ref.method,
                            "reference_error_estimate": ref.error_estimate}  # fmt: skip
        for method in methods:
            if not integrators.applies(method, case.model):  # the joint-implicit step: unconstrained models
                bar.update()
                continue
            bar.set_postfix_str(f"{case.scene} {method}")
            rows = sc.scan(case, ref, method, dts)
            runs += rows
            summary.append({**sc.summarize_scan(rows), "rk4_limit_predicted": RK4_BETA / rho})
            bar.update()
        for method in adaptive:
            if (
                method in ("radau", "bdf") and case.model.nv >= 200
            ):  # O(N^3) per Jacobian: 631 s for Radau on the bare 200-link chain once
                bar.update()
                continue
            bar.set_postfix_str(f"{case.scene} {method}")
            adaptive_rows.append(numerics.score(case, ref, method, 1e-6))
            bar.update()
    bar.close()

    def among_picked(names: tuple[str, ...]) -> list[str]:
        return [m for m in names if picked is None or m in picked]

    singular = [
        sc.singular_case_row(c, m, 0.01) for c in sc.singular_cases() for m in among_picked(("rk4", "sdirk2", "dop853"))
    ]
    long_methods = {
        "2R free swing": ("rk4", "semi_implicit_euler", "sdirk2"),
        "four-bar free, projection": ("rk4", "sdirk2"),
    }
    long_rows = [
        sc.long_run_row(r, m)
        for r in tqdm(sc.long_runs(quick), desc="long runs")
        for m in among_picked(long_methods[r.scene])
    ]
    write_csv(runs, out / "stiff_cases.csv")
    write_csv(summary, out / "stiff_summary.csv")
    result = {
        "cases": meta,
        "summary": summary,
        "adaptive": adaptive_rows,
        "singular": singular,
        "long_runs": long_rows,
        "dts": dts,
    }
    (out / "stiff_cases.json").write_text(json.dumps(result, indent=2, default=float))
    text = report(result)
    (out / "stiff_cases.md").write_text(text)
    plot(summary, meta, out / "stiff_cases.png")
    print(text)
    print(f"written to {out}/stiff_cases.md, .csv, .json, .png")
    return result


def write_csv(rows: list[dict], path: pathlib.Path) -> None:
    if not rows:
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def fmt(x, spec=".2g") -> str:
    return "-" if x is None or (isinstance(x, float) and np.isnan(x)) else format(x, spec)


def report(result: dict) -> str:
    L = ["# Stiff and extreme cases", ""]
    L.append("Largest usable fixed step (halving from 0.05 s: not flagged as diverged and trajectory within "
             "1e-2 of the reference on a 0.05 s grid; on an ill-posed reference, energy within 1e-2 J and constraints within 1e-6), "
             "its errors and CPU time; failures above it, flagged (reported in `diverged`) or silent (bounded but wrong). "
             "A scan stops once its runs used 60 s of CPU (column: finest step tried).")  # fmt: skip
    L.append("")
    L.append(
        "| case | stiffness rho [1/s] | RK4 limit 2.785/rho [s] | integrator | largest usable dt [s] | trajectory error | final error | energy error [J] | constraint error | CPU [s] | failures above: flagged / silent | step halvings (all runs) | finest dt tried |"
    )
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in result["summary"]:
        m = result["cases"][r["scene"]]
        L.append(
            f"| {r['scene']} | {m['spectral_radius']:.3g} | {m['rk4_limit_predicted']:.2g} | {r['integrator']} | "
            f"{fmt(r['largest_stable_dt'])} | {fmt(r['trajectory_error'])} | {fmt(r['state_error'])} | {fmt(r['energy_error'])} | "
            f"{fmt(r['constraint_error'])} | {fmt(r['cpu_s'], '.3f')} | {r['unstable_flagged']} / {r['silent_failures']} | {r['halvings']} | {r['finest_dt_tried']:.2g} |"
        )
    if result["adaptive"]:
        L += ["", "Adaptive methods at rtol = atol = 1e-6:", "",
              "| case | integrator | trajectory error | final error | accepted steps | evaluations | CPU [s] | diverged |",
              "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in result["adaptive"]:
            L.append(f"| {r['scene']} | {r['integrator']} | {fmt(r['trajectory_error'])} | {fmt(r['state_error'])} | "
                     f"{r['steps']} | {r['evaluations']} | {r['cpu_s']:.3f} | {r['diverged']} |")  # fmt: skip
    L += [
        "",
        "Reference of each case (its error estimate: largest difference over the 0.05 s grid to the same method at a 100x looser tolerance):",
        "",
    ]
    L += [
        f"- {k}: {m['reference']} rtol 1e-12, estimate {m['reference_error_estimate']:.1e}"
        for k, m in result["cases"].items()
    ]
    L += ["", "A motion that ends in a singularity (the disk falling flat, where the Euler angles fail):", "",
          "| case | integrator | dt | flagged | all outputs finite | flagged at t [s] | largest lean returned [rad] |",
          "|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in result["singular"]:
        L.append(f"| {r['scene']} | {r['integrator']} | {r['dt']:g} | {r['flagged']} | {r['all_outputs_finite']} | "
                 f"{fmt(r['t_flagged'], '.3f')} | {r['max_lean_reported']:.3f} |")  # fmt: skip
    L += ["", "Long horizons (free, conservative motion):", "",
          "| case | integrator | steps | dt [s] | max energy drift [J] | relative | constraint error | CPU [s] | diverged |",
          "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in result["long_runs"]:
        L.append(f"| {r['scene']} | {r['integrator']} | {r['steps']} | {r['dt']:g} | {r['energy_drift']:.2e} | "
                 f"{r['energy_drift_relative']:.2e} | {fmt(r['constraint_error'], '.1e')} | {r['cpu_s']:.1f} | {r['diverged']} |")  # fmt: skip
    return "\n".join(L) + "\n"


def plot(summary: list[dict], meta: dict, path: pathlib.Path) -> None:
    plt = pyplot()
    scenes = list(dict.fromkeys(r["scene"] for r in summary))
    methods = list(dict.fromkeys(r["integrator"] for r in summary))
    fig, ax = plt.subplots(figsize=(12, 0.45 * len(scenes) + 2))
    colors = plt.get_cmap("tab10").colors
    for k, method in enumerate(methods):
        for i, scene in enumerate(scenes):
            r = next((x for x in summary if x["scene"] == scene and x["integrator"] == method), None)
            y = i + (k - len(methods) / 2) * 0.1
            if r is None:  # the method does not apply to the case (joint-implicit on a constrained model)
                continue
            if r["largest_stable_dt"] is None:
                ax.plot([1e-5], [y], "x", color=colors[k % 10])
            else:
                ax.plot([r["largest_stable_dt"]], [y], "o", color=colors[k % 10], label=method if i == 0 else None)
    for i, scene in enumerate(scenes):
        ax.plot([meta[scene]["rk4_limit_predicted"]] * 2, [i - 0.45, i + 0.45], "k:", lw=1)
    ax.set_xscale("log")
    ax.set_yticks(range(len(scenes)), scenes)
    ax.set_xlabel("largest usable dt [s] (x at left: none down to the finest step; dotted: RK4 limit 2.785/rho)")
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(True, axis="x", which="both", alpha=0.3)
    save(fig, path)
