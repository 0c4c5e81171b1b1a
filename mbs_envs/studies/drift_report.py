"""Constraint drift of the four-bar under each stabilization (the logic of
``scripts/constraint_drift.py``, whose help says what is measured): the runs, the table and the plot.
"""

from __future__ import annotations
import csv
import json
import pathlib
import time
import numpy as np
from tqdm import tqdm
from .. import simulate
from .plotting import pyplot, save
from ..models import FourBar


KINDS = ("none", "baumgarte", "projection")


def run(out: pathlib.Path, steps: int, dt: float, chunk: int = 1000) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    model = FourBar()
    q0, v0 = model.consistent_state(0.2, 4.0)
    E0 = float(model.energy(q0, v0))
    n_chunks = int(np.ceil(steps / chunk))
    series, result = {}, {}
    bar = tqdm(total=n_chunks * len(KINDS), desc="chunks", unit="chunk")
    for kind in KINDS:
        q, v = q0, v0
        t, res, dE = [0.0], [float(np.max(np.abs(model.constraint_residual(q0))))], [0.0]
        tic = time.perf_counter()
        done = 0
        diverged = False
        while done < steps:  # fixed-step RK4: chunking the run changes nothing
            n = min(chunk, steps - done)
            tr = simulate(model, q, v, n * dt, dt=dt, integrator="rk4", stabilization=kind)
            q, v = tr.q[-1], tr.v[-1]
            done += n
            diverged |= bool(tr.diverged)
            t.append(done * dt)
            res.append(float(np.max(np.abs(model.constraint_residual(tr.q)))))
            dE.append(float(np.max(np.abs(model.energy(tr.q, tr.v) - E0)) / abs(E0)))
            bar.update()
        series[kind] = {"t": t, "residual": res, "energy_drift": dE}
        result[kind] = {
            "final_residual": res[-1],
            "max_residual": max(res),
            "final_energy_drift": abs(float(model.energy(q, v)) - E0) / abs(E0),
            "max_energy_drift": max(dE),
            "run_time_s": time.perf_counter() - tic,
            "diverged": diverged,
        }
    bar.close()
    meta = {"model": repr(model), "steps": steps, "dt": dt, "integrator": "rk4", "q0": q0.tolist(), "v0": v0.tolist()}
    (out / "constraint_drift.json").write_text(json.dumps({"config": meta, "result": result}, indent=2))
    with open(out / "constraint_drift.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["stabilization", "t", "max_residual_in_chunk", "max_rel_energy_drift_in_chunk"])
        for kind, s in series.items():
            for row in zip(s["t"], s["residual"], s["energy_drift"]):
                w.writerow([kind, *row])
    plot(series, out / "constraint_drift.png", steps, dt)
    print(
        f"{'stabilization':14s} {'final |phi| [m]':>16s} {'max |phi| [m]':>14s} {'rel. energy drift':>18s} {'time [s]':>9s}"
    )
    for kind, r in result.items():
        print(
            f"{kind:14s} {r['final_residual']:16.2e} {r['max_residual']:14.2e} "
            f"{r['final_energy_drift']:18.2e} {r['run_time_s']:9.1f}"
        )
    print(f"written to {out}/constraint_drift.json, .csv, .png")
    return result


def plot(series: dict, path: pathlib.Path, steps: int, dt: float) -> None:
    plt = pyplot()
    fig, (a0, a1) = plt.subplots(1, 2, figsize=(11, 4))
    for kind, s in series.items():
        a0.semilogy(s["t"][1:], np.maximum(s["residual"][1:], 1e-17), label=kind)
        a1.semilogy(s["t"][1:], np.maximum(s["energy_drift"][1:], 1e-17), label=kind)
    a0.set_ylabel("max |phi| in each 1000 steps [m]")
    a1.set_ylabel("max |E - E0| / |E0|")
    for a in (a0, a1):
        a.set_xlabel("t [s]")
        a.legend()
    fig.suptitle(f"FourBar, RK4, dt = {dt:g} s, {steps} steps, no input")
    save(fig, path)
