#!/usr/bin/env python
"""What to pick, per scene and regime, at the environments' control step (10 ms).

For each regime case (:func:`mbs_envs.studies.stiff_cases.regimes`: every scene's environment
model under a held torque, the disk at 100x its critical spin, stiff viscous, Coulomb and Stribeck
friction, a 200-link chain under a 1000 rad/s joint PD) and each fixed-step method, the control step
is split into 1, 2, 4, 8, 16 physics steps (the environments' ``substeps``) until the trajectory
error over 1 s (0.05 s grid, against the stiff set's reference) is at most 1e-6. Picked per case:
the cheapest run (median wall time, on the path an environment takes) reaching 1e-6, and the
cheapest merely *usable* one (not flagged, trajectory error at most 1e-2).

Writes ``what_to_pick.csv`` (every run), ``what_to_pick.json`` and ``what_to_pick.md`` to ``--out``.

    python scripts/what_to_pick.py --out results/what_to_pick    # about 20 min here
    python scripts/what_to_pick.py --out docs/figures/what_to_pick --add --cases "Acrobot (environment model, 0.3 u_max held)"
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys
import time

from tqdm import tqdm

from mbs_envs import integrators
from mbs_envs.studies import numerics
from mbs_envs.studies import stiff_cases as sc
from mbs_envs.studies.work_precision import FIXED

#: the fixed-step methods compared (the work-precision study's set)
METHODS = FIXED


def run(
    out: pathlib.Path,
    cases: list[str] | None = None,
    methods: list[str] | None = None,
    accurate: float = 1e-6,
    repeats: int = 3,
    add: bool = False,
) -> dict:
    t_start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    known = sc.regimes()
    unknown = sorted(set(cases or []) - {c.scene for _, c in known})
    if unknown:
        raise SystemExit(f"what_to_pick.py: no case {unknown}; the cases: {[c.scene for _, c in known]}")
    chosen = [(regime, c) for regime, c in known if cases is None or c.scene in cases]
    methods = list(methods or METHODS)
    rows, picks = [], []
    with tqdm(total=len(chosen) * (len(methods) + 1), desc="what to pick", unit="method") as bar:
        for regime, case in chosen:
            bar.set_postfix_str(f"{case.scene} reference", refresh=True)
            ref = numerics.reference(case)
            bar.update()
            case_rows = []
            for method in methods:
                bar.set_postfix_str(f"{case.scene} {method}", refresh=True)
                if integrators.applies(method, case.model):
                    case_rows += sc.pick_rows(case, ref, method, accurate=accurate, repeats=repeats)
                bar.update()
            rows += case_rows
            picks.append(
                {
                    "regime": regime,
                    "case": case.scene,
                    "reference_error_estimate": ref.error_estimate,
                    **pick(case_rows),
                }
            )
    run_time = time.perf_counter() - t_start
    if add:  # the other cases' runs and picks as they were; these cases' replaced
        meta = json.loads((out / "what_to_pick.json").read_text())
        names = {c.scene for _, c in chosen}
        rows = [r for r in read_rows(out) if r["case"] not in names] + rows
        order = {c.scene: k for k, (_, c) in enumerate(known)}
        picks = sorted(
            [p for p in meta["picks"] if p["case"] not in names] + picks, key=lambda p: order.get(p["case"], len(order))
        )
        run_time += meta["run_time_s"]
    with open(out / "what_to_pick.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    result = {"picks": picks, "accurate": accurate, "repeats": repeats, "run_time_s": run_time}
    (out / "what_to_pick.json").write_text(json.dumps(result, indent=2, default=float))
    text = report(picks, accurate)
    (out / "what_to_pick.md").write_text(text)
    print(text)
    print(f"run time {result['run_time_s']:.0f} s; written to {out}/what_to_pick.csv, .json, .md")
    return result


def pick(rows: list[dict]) -> dict:
    """The cheapest (median time) of ``rows`` that is accurate, usable, and merely stable (not flagged)."""
    stable = [dict(r, stable=not r["flagged"]) for r in rows]
    best = lambda key: min((r for r in stable if r[key]), key=lambda r: r["seconds"], default=None)  # noqa: E731
    return {"accurate": best("accurate"), "usable": best("usable"), "stable": best("stable")}


def read_rows(out: pathlib.Path) -> list[dict]:
    """The runs of ``out/what_to_pick.csv`` with their types."""
    with open(out / "what_to_pick.csv") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r.update(substeps=int(r["substeps"]), trajectory_error=float(r["trajectory_error"]), seconds=float(r["seconds"]),
                 flagged=r["flagged"] == "True", usable=r["usable"] == "True", accurate=r["accurate"] == "True")  # fmt: skip
    return rows


def from_csv(out: pathlib.Path) -> None:
    """``what_to_pick.md`` again from ``what_to_pick.csv`` and ``.json`` in ``out`` (no runs)."""
    meta = json.loads((out / "what_to_pick.json").read_text())
    rows = read_rows(out)
    picks = [{**p, **pick([r for r in rows if r["case"] == p["case"]])} for p in meta["picks"]]
    meta["picks"] = picks
    (out / "what_to_pick.json").write_text(json.dumps(meta, indent=2, default=float))
    (out / "what_to_pick.md").write_text(report(picks, meta.get("accurate", 1e-6)))


def cell(r: dict | None) -> str:
    if r is None:
        return "none with up to 16 substeps"
    return f"`{r['integrator']}`, {r['substeps']} substep{'s' if r['substeps'] > 1 else ''} ({r['trajectory_error']:.1e}; {1e3 * r['seconds']:.1f} ms)"


def report(picks: list[dict], accurate: float = 1e-6) -> str:
    lines = ["# What to pick at the 10 ms control step", "",
             "Per case: the cheapest run (median wall time for 1 s, the path an environment takes) whose trajectory error "
             f"is at most {accurate:g}, the cheapest usable one (not flagged, error at most 1e-2) and the cheapest merely "
             "stable one (not flagged as diverged, whatever its error); in brackets its trajectory error and time.", "",
             f"| regime | case | cheapest to {accurate:g} | cheapest usable | cheapest stable |", "|---|---|---|---|---|"]  # fmt: skip
    for p in picks:
        lines.append(
            f"| {p['regime']} | {p['case']} | {cell(p['accurate'])} | {cell(p['usable'])} | {cell(p['stable'])} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=pathlib.Path)
    p.add_argument("--cases", nargs="+", help="subset of case names")
    p.add_argument("--methods", nargs="+", help="subset of integrators")
    p.add_argument("--accurate", type=float, default=1e-6, help="trajectory error target (default 1e-6)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs after the warm-up (default 3)")
    p.add_argument(
        "--from-csv", action="store_true", help="rewrite the picks and the table from the CSV in --out, no runs"
    )
    p.add_argument(
        "--add", action="store_true", help="run only --cases and merge them into the results already in --out"
    )
    a = p.parse_args(argv)
    if a.from_csv:
        from_csv(a.out)
        return 0
    if a.add and not (a.cases and (a.out / "what_to_pick.json").exists()):
        p.error("--add needs --cases and earlier results in --out")
    run(a.out, a.cases, a.methods, a.accurate, a.repeats, a.add)
    return 0


if __name__ == "__main__":
    sys.exit(main())
