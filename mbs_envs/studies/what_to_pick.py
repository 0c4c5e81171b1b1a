"""What to pick, per scene and regime, at the environments' control step: the table from the work-precision results (the logic of ``scripts/what_to_pick.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import csv
import json
import pathlib
import time
from tqdm import tqdm
from .. import integrators
from . import numerics
from . import stiff_cases as sc
from .work_precision import FIXED


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
