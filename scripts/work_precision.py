#!/usr/bin/env python
"""Work-precision: error against CPU time for every scene and integrator.

For each scene (2R; four-bar with projection, Baumgarte and no
stabilization; rolling disk; chains) and each integrator (fixed-step ones over
a range of ``dt``, adaptive ones over a range of ``rtol``) the final-state
error against an independent high-accuracy reference (DOP853 at rtol 1e-12 on
the unstabilized equations), the energy error and the constraint error over
the run, and the CPU time. See :mod:`mbs_envs.studies.numerics` for the definitions.

Writes to ``--out``: ``work_precision.csv`` (one row per scene x integrator x
setting), ``work_precision_<scene>.png`` (log-log error against CPU time) and
``work_precision.md`` (the cheapest run per scene and accuracy target).

    python scripts/work_precision.py --out results/numerics           # ~10 min
    python scripts/work_precision.py --out results/numerics --quick   # ~1 min
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys

import numpy as np
from tqdm import tqdm

from mbs_envs import numerics
from mbs_envs.studies.plotting import pyplot, save

TARGETS = (1e-2, 1e-5, 1e-8)


def settings_function(quick: bool, n_fixed: int | None, n_adaptive: int | None):
    n_fixed = n_fixed or (4 if quick else 7)
    n_adaptive = n_adaptive or (3 if quick else 5)
    coarsest = 0.02 if quick else 0.04
    rtols = list(np.logspace(-4 if quick else -3, -10 if quick else -11, n_adaptive))

    def settings(case, method):
        if method in numerics.ADAPTIVE:
            return rtols
        return numerics.fixed_steps(coarsest, n_fixed)

    return settings


def run(
    out: pathlib.Path,
    quick: bool = False,
    scenes: list[str] | None = None,
    methods: list[str] | None = None,
    n_fixed: int | None = None,
    n_adaptive: int | None = None,
) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    cases = [c for c in numerics.work_precision_cases(quick) if scenes is None or c.scene in scenes]
    if not cases:
        raise ValueError(f"no scene matches {scenes}")
    methods = list(methods or numerics.FIXED + numerics.ADAPTIVE)
    settings = settings_function(quick, n_fixed, n_adaptive)
    total = sum(len(settings(c, m)) for c in cases for m in methods)
    with tqdm(total=total, desc="work-precision", unit="run") as bar:

        def progress(label):
            bar.set_postfix_str(label, refresh=False)
            bar.update()

        rows, refs = numerics.run_grid(cases, settings, methods, progress)
    write_csv(rows, out / "work_precision.csv")
    for case in cases:
        plot_scene([r for r in rows if r["scene"] == case.scene], case, out / f"work_precision_{case.scene}.png")
    summary = summarize(rows, cases, refs)
    (out / "work_precision.md").write_text(summary)
    meta = {
        "quick": quick,
        "methods": methods,
        "references": {k: {"method": r.method, "rtol": r.rtol, "error_estimate": r.error_estimate} for k, r in refs.items()},
        "cases": {c.scene: {"model": repr(c.model), "t_final": c.t_final, "stabilization": c.stabilization} for c in cases},
    }
    (out / "work_precision.json").write_text(json.dumps(meta, indent=2))
    print(summary)
    print(f"written to {out}/work_precision.csv, .md, .json and one PNG per scene")
    return rows


def write_csv(rows: list[dict], path: pathlib.Path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def plot_scene(rows: list[dict], case: numerics.Case, path: pathlib.Path) -> None:
    plt = pyplot()
    keys = ["state_error", "energy_error"] + (["constraint_error"] if case.model.nc else [])
    fig, axes = plt.subplots(1, len(keys), figsize=(5.2 * len(keys), 4.2), squeeze=False)
    colors = plt.get_cmap("tab20").colors
    for ax, key in zip(axes[0], keys):
        for k, method in enumerate(dict.fromkeys(r["integrator"] for r in rows)):
            pts = [(r["cpu_s"], r[key]) for r in rows if r["integrator"] == method and not r["diverged"] and r[key] > 0]
            if not pts:
                continue
            x, y = zip(*sorted(pts))
            style = "--" if method in numerics.ADAPTIVE else "-"
            ax.loglog(x, y, style, marker="o", ms=3, label=method, color=colors[2 * k % 20 + (k >= 10)])
        ax.set_xlabel("CPU time [s]")
        ax.set_ylabel(key.replace("_", " "))
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"{case.scene}: {case.t_final:g} s of free motion (dashed: adaptive, per rtol)")
    save(fig, path)


def summarize(rows: list[dict], cases: list[numerics.Case], refs: dict) -> str:
    lines = ["# Work-precision summary", ""]
    lines.append("Cheapest run (CPU time) reaching each final-state error target; `-` if none did.")
    lines.append("")
    header = "| scene | reference error | " + " | ".join(f"error <= {t:g}" for t in TARGETS) + " | diverged runs |"
    lines += [header, "|" + "---|" * (len(TARGETS) + 3)]
    for case in cases:
        sub = [r for r in rows if r["scene"] == case.scene]
        cells = []
        for target in TARGETS:
            best = numerics.cheapest(sub, target)
            cells.append("-" if best is None else f"{best['integrator']} {best['setting_name']}={best['setting']:.2g} ({1e3 * best['cpu_s']:.1f} ms)")
        diverged = sorted({f"{r['integrator']}@{r['setting']:.2g}" for r in sub if r["diverged"]})
        lines.append(
            f"| {case.scene} | {refs[case.scene].error_estimate:.1e} | " + " | ".join(cells) + f" | {', '.join(diverged) or 'none'} |"
        )
    lines.append("")
    lines.append("Recommended (least CPU time over the targets 1e-2 and 1e-5 among fixed-step methods, usable in environments):")
    lines.append("")
    for case in cases:
        fixed = [r for r in rows if r["scene"] == case.scene and r["kind"] == "fixed"]
        picks = [numerics.cheapest(fixed, t) for t in TARGETS[:2]]
        text = ", ".join(
            f"{p['integrator']} at dt={p['setting']:.3g} s for error <= {t:g}" for p, t in zip(picks, TARGETS) if p is not None
        )
        lines.append(f"- **{case.scene}**: {text or 'no fixed-step run reached 1e-2'}")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--quick", action="store_true", help="shorter horizons, fewer settings (~1 min)")
    p.add_argument("--scenes", nargs="+", help="subset of scenes (default all)")
    p.add_argument("--methods", nargs="+", help="subset of integrators (default all)")
    p.add_argument("--n-fixed", type=int, help="number of dt values (halving from the coarsest)")
    p.add_argument("--n-adaptive", type=int, help="number of rtol values")
    a = p.parse_args(argv)
    run(a.out, a.quick, a.scenes, a.methods, a.n_fixed, a.n_adaptive)
    return 0


if __name__ == "__main__":
    sys.exit(main())
