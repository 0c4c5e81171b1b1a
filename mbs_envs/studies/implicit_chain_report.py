"""The O(N) implicit joint step on long chains beside RK4 and SDIRK2: runs, tables and plot (the logic of ``scripts/implicit_chain.py``, whose help says what is run and how to read it)."""

from __future__ import annotations

import csv
import json
import pathlib
import time
import numpy as np
from tqdm import tqdm
from .scene_cases import drive_chain
from . import stiff_cases as sc
from .plotting import pyplot, save


#: (integrator, compiled path) timed per N
TIMED = (("joint_implicit_euler", False), ("rk4", False), ("rk4", True), ("sdirk2", False))


def run(out: pathlib.Path, ns: list[int] | None = None, quick: bool = False, repeats: int | None = None) -> dict:
    t_start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    ns = ns or ([20, 50] if quick else [50, 100, 200, 500])
    repeats = repeats or (3 if quick else 5)
    dts = [0.02 * 2.0**-k for k in range(8)]
    times, stability = [], []
    with tqdm(total=len(ns) * (len(TIMED) + 2), desc="implicit chain", unit="run") as bar:
        for n in ns:
            model = drive_chain(n)
            for method, compiled in TIMED:
                bar.set_postfix_str(f"N={n} {method}{' compiled' if compiled else ''}", refresh=True)
                steps = 3 if method == "sdirk2" and n > 100 else 20
                t = sc.step_time(model, method, compiled, steps=steps, repeats=repeats)
                times.append(
                    {"n_links": n, "integrator": method, "path": "compiled" if compiled else "numpy", "step_s": t}
                )
                bar.update()
            for method in ("joint_implicit_euler", "rk4"):
                bar.set_postfix_str(f"N={n} {method} stability", refresh=True)
                stability.append(sc.largest_settling_step(n, method, dts))
                bar.update()
    write_csv(times, out / "implicit_chain.csv")
    write_csv(stability, out / "implicit_chain_stability.csv")
    text = report(times, stability)
    (out / "implicit_chain.md").write_text(text)
    plot(times, out / "implicit_chain.png")
    result = {
        "step_times": times,
        "stability": stability,
        "repeats": repeats,
        "run_time_s": time.perf_counter() - t_start,
    }
    (out / "implicit_chain.json").write_text(json.dumps(result, indent=2))
    print(text)
    print(
        f"run time {result['run_time_s']:.0f} s; written to {out}/implicit_chain.csv, _stability.csv, .json, .md, .png"
    )
    return result


def write_csv(rows: list[dict], path: pathlib.Path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def report(times: list[dict], stability: list[dict]) -> str:
    ns = sorted({r["n_links"] for r in times})
    t = {(r["n_links"], r["integrator"], r["path"]): r["step_s"] for r in times}
    lines = ["# The O(N) implicit joint step on long chains", "",
             "Step of 10 ms, held zero torque, median wall time [ms]; ratio to RK4 on the same (numpy) path.", "",
             "| N | joint_implicit_euler | rk4 (numpy) | rk4 (compiled) | sdirk2 | implicit / rk4 numpy | implicit / rk4 compiled |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for n in ns:
        ji, rn, rc, sd = (
            t[n, "joint_implicit_euler", "numpy"],
            t[n, "rk4", "numpy"],
            t[n, "rk4", "compiled"],
            t[n, "sdirk2", "numpy"],
        )
        lines.append(
            f"| {n} | {1e3 * ji:.3f} | {1e3 * rn:.3f} | {1e3 * rc:.3f} | {1e3 * sd:.2f} | {ji / rn:.2f} | {ji / rc:.2f} |"
        )
    lines += ["", "Stiff case (joint PD, 1000 rad/s per joint): largest step that neither diverges nor misses the target by 1e-3 rad.", "",
              "| N | integrator | largest stable dt [s] | final error [rad] | runs flagged as diverged above it |", "|---|---|---|---|---|"]  # fmt: skip
    for r in stability:
        dt = "none down to 1.6e-4" if r["largest_stable_dt"] is None else f"{r['largest_stable_dt']:.3g}"
        err = "-" if r["final_error"] is None else f"{r['final_error']:.1e}"
        lines.append(f"| {r['n_links']} | {r['integrator']} | {dt} | {err} | {r['flagged_above']} |")
    return "\n".join(lines) + "\n"


def plot(times: list[dict], path: pathlib.Path) -> None:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for method, compiled in TIMED:
        label = f"{method} ({'compiled' if compiled else 'numpy'})"
        pts = sorted(
            (r["n_links"], r["step_s"])
            for r in times
            if r["integrator"] == method and r["path"] == ("compiled" if compiled else "numpy")
        )
        x, y = zip(*pts)
        ax.loglog(x, np.array(y) * 1e3, marker="o", label=label)
    ax.set_xlabel("links N")
    ax.set_ylabel("one 10 ms step [ms]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Step cost against chain length")
    save(fig, path)
